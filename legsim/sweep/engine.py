"""Where the batches run: Dask, on an embedded local cluster or a running scheduler, or this
process.

* default: an embedded ``distributed.LocalCluster`` of worker processes (one per core, or
  ``workers``), one thread each (the runs are pure Python holding the GIL, so threads would
  not run in parallel), started for the sweep and stopped after it;
* ``scheduler=ADDRESS`` (or the ``DASK_SCHEDULER_ADDRESS`` environment variable): a Dask
  cluster already running (``dask scheduler`` and ``dask worker`` processes on one machine or
  many); the workers must have the same version of legsim installed;
* ``in_process=True``: no Dask at all, the batches run one after another here (the reference
  the engine's overhead is measured against).

Deadlines. Reaching a running scheduler waits at most ``connect_timeout`` seconds (default
``CONNECT_TIMEOUT``, ``--connect-timeout``) at each step: the TCP connection (a closed port is
refused at once, not after Dask's retries), the scheduler's first answer (Dask's own handshake
waits for it without a deadline: a peer that accepts and never answers would hang the sweep),
the client's registration, the first worker and the workers' version check. Each ends in an
``EngineError`` naming the address and the step. During the sweep, when no batch has finished
or come back for ``connect_timeout`` seconds, the scheduler is asked for its identity: one that does not
answer within ``connect_timeout`` more (a host gone, a stopped process: the client would wait
for its futures forever) ends the sweep the same way, the rows finished so far kept.

Interrupts. The embedded cluster's worker processes ignore SIGINT and SIGTERM (``worker_setup``,
preloaded): Ctrl-C at a terminal reaches every process of its group, and the workers would each
print a KeyboardInterrupt traceback. The client alone stops the sweep: it cancels what is
queued and closes the cluster's nannies, which give each worker ``STOP_SECONDS`` to stop before
they kill it (a busy worker would otherwise finish its batch first).

Batches. A task is a batch of items, so the engine's cost per task (scheduling, pickling, a
round trip: about a millisecond) is paid once per batch: ``BatchSizer`` sizes each batch to
``target_seconds`` of work from the cost per item measured so far, smaller towards the end so
that the last batches finish together. The engine keeps two batches per worker in flight, so
a worker never waits for the client, and hands each finished batch to ``on_done`` as it
arrives. A batch whose task fails (a worker died, a result could not be unpickled) is handed
over with the exception, and the sweep goes on.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from ..errors import LegsimError
from ..interrupts import raise_if_stopped

if TYPE_CHECKING:
    from dask.typing import Key
    from distributed import Client, LocalCluster

SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"

#: Seconds to wait at each step of reaching a scheduler (module docstring), unless told otherwise.
CONNECT_TIMEOUT = 20.0
#: The address schemes of a scheduler legsim reaches (Dask's default for a bare HOST:PORT is tcp).
SCHEMES = ("tcp", "tls")
#: Seconds an interrupted sweep gives its workers to stop before their nannies end them.
STOP_SECONDS = 0.5
#: The module the embedded cluster's workers preload (they ignore SIGINT: module docstring).
WORKER_SETUP = "legsim.sweep.worker_setup"

BatchFn = Callable[[Any, list], list]
OnDone = Callable[[list, "list | BaseException"], None]


class EngineError(LegsimError):
    """The engine cannot start or reach its cluster; the message says which and why."""


def default_workers() -> int:
    """One worker per core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def timed(fn: BatchFn, common: Any, batch: list) -> tuple[float, list]:
    """``fn(common, batch)`` with its wall time (s) on the worker."""
    start = time.perf_counter()
    results = fn(common, batch)
    return time.perf_counter() - start, results


class BatchSizer:
    """Batch sizes: ``first`` items until costs are known, then ``target_seconds`` of work at
    the mean cost per item so far, at most ``max_size`` and at most an even share of what is
    left over ``2 * workers`` batches (so that the sweep's tail is balanced)."""

    def __init__(
        self, workers: int, target_seconds: float = 2.0, first: int = 1, max_size: int = 1000, fixed: int | None = None
    ) -> None:
        self.workers, self.target, self.first = workers, target_seconds, first
        self.max_size, self.fixed = max_size, fixed
        self.seconds = 0.0
        self.items = 0

    def record(self, seconds: float, items: int) -> None:
        self.seconds += seconds
        self.items += items

    def size(self, remaining: int) -> int:
        if self.fixed is not None:
            return max(1, min(self.fixed, remaining))
        if self.items == 0:
            return max(1, min(self.first, remaining))
        per_item = max(self.seconds / self.items, 1e-6)
        share = math.ceil(remaining / (2 * self.workers))
        return max(1, min(int(self.target / per_item), self.max_size, share, remaining))


class Engine:
    """Runs ``fn(common, batch)`` over batches of items (see the module docstring).

    ``with Engine(workers=2) as engine: engine.run(fn, common, items, on_done)``.
    """

    def __init__(
        self,
        workers: int | None = None,
        scheduler: str | None = None,
        in_process: bool = False,
        batch_size: int | None = None,
        target_seconds: float = 2.0,
        connect_timeout: float | None = None,
    ) -> None:
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise EngineError(f"--workers must be an integer >= 1, got {workers!r}")
        if batch_size is not None and (
            isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1
        ):
            raise EngineError(f"--batch must be an integer >= 1, got {batch_size!r}")
        if in_process and scheduler:
            raise EngineError("--in-process and --scheduler exclude each other")
        if connect_timeout is None:
            connect_timeout = CONNECT_TIMEOUT
        if isinstance(connect_timeout, bool) or not (
            isinstance(connect_timeout, (int, float)) and math.isfinite(connect_timeout) and connect_timeout > 0
        ):
            raise EngineError(f"--connect-timeout must be a number of seconds > 0, got {connect_timeout!r}")
        self.connect_timeout = float(connect_timeout)
        self.scheduler = None if in_process else (scheduler or os.environ.get(SCHEDULER_ENV) or None)
        if self.scheduler:
            # Named where the user gave it: an address from the environment is no option typed.
            scheduler_endpoint(self.scheduler, "--scheduler" if scheduler else f"${SCHEDULER_ENV}")
        if self.scheduler and workers is not None:
            raise EngineError(
                f"--workers sets the size of the embedded cluster; with a scheduler "
                f"({self.scheduler}) the cluster's own workers run the sweep"
            )
        self.in_process = in_process
        self.requested = workers
        self.batch_size, self.target_seconds = batch_size, target_seconds
        self.client: Client | None = None
        self.cluster: LocalCluster | None = None
        self.workers = 1

    @property
    def where(self) -> str:
        """Where the batches run, for messages."""
        if self.in_process:
            return "this process"
        if self.scheduler:
            return f"the Dask scheduler at {self.scheduler} ({self.workers} worker(s))"
        return f"an embedded Dask cluster of {self.workers} worker process(es)"

    def __enter__(self) -> Engine:
        if not self.in_process:
            client, self.cluster = _connect(self.scheduler, self.requested, self.connect_timeout)
            self.client = client
            self.workers = max(1, len(client.scheduler_info().get("workers", {})))
        return self

    def __exit__(self, *exc: Any) -> None:
        if exc[0] is not None and self.cluster is not None:
            # Interrupted: a busy worker would finish its batch before closing (seconds); its
            # nanny, told to close first, stops it after STOP_SECONDS and starts no other.
            with contextlib.suppress(Exception):
                self.cluster.sync(_stop_workers, self.cluster)
        if self.client is not None:
            # Bounded: Dask waits twice its connection timeout for a scheduler that went silent.
            with contextlib.suppress(Exception):
                self.client.close(timeout=min(self.connect_timeout, STOP_SECONDS) if exc[0] else self.connect_timeout)
        if self.cluster is not None:
            # Closing a cluster that is already going away may raise anything.
            with contextlib.suppress(Exception):
                self.cluster.close()
        self.client = self.cluster = None

    def run(self, fn: BatchFn, common: Any, items: Sequence[Any], on_done: OnDone) -> None:
        """Run ``fn(common, batch)`` over ``items`` in batches; ``on_done(batch, results)`` (or
        ``(batch, exception)``) for each batch as it finishes."""
        sizer = BatchSizer(self.workers, self.target_seconds, first=1, fixed=self.batch_size)
        batches = _batches(list(items), sizer)
        if self.in_process:
            for batch in batches:
                raise_if_stopped()
                try:
                    seconds, results = timed(fn, common, batch)
                except Exception as exc:
                    on_done(batch, exc)
                    continue
                sizer.record(seconds, len(batch))
                on_done(batch, results)
            return
        self._run_on_dask(fn, common, batches, sizer, on_done)

    def _run_on_dask(
        self, fn: BatchFn, common: Any, batches: Iterator[list], sizer: BatchSizer, on_done: OnDone
    ) -> None:
        from distributed import wait

        client = self.client
        if client is None:
            raise EngineError("the Dask engine runs batches only inside its `with` block (not connected)")
        window = 2 * self.workers
        in_flight: dict[Key, tuple[Any, list[Any]]] = {}

        def submit() -> None:
            batch = next(batches, None)
            if batch is not None:
                future = client.submit(timed, fn, common, batch, pure=False)
                in_flight[future.key] = (future, batch)

        for _ in range(window):
            submit()
        try:
            while in_flight:
                # Dask's futures release themselves in finalizers, where Python swallows the
                # exception of a signal that lands there.
                raise_if_stopped()
                try:
                    # Waiting on the futures is local: a scheduler that stops answering (a host
                    # gone, a stopped process) leaves them pending forever without an error.
                    done = wait([f for f, _ in in_flight.values()], self.connect_timeout, "FIRST_COMPLETED").done
                except TimeoutError:
                    if self.scheduler:
                        self._check_answers(client)
                    continue
                for future in sorted(done, key=lambda f: str(f.key)):
                    _, batch = in_flight.pop(future.key)
                    try:
                        seconds, results = self._result(client, future)
                    except EngineError:  # the scheduler is gone: no row of this batch is known
                        raise
                    except Exception as exc:
                        on_done(batch, exc)
                    else:
                        sizer.record(seconds, len(batch))
                        on_done(batch, results)
                    future.release()
                    submit()
        except BaseException:  # Ctrl-C, a failing on_done, a silent scheduler: stop what is queued
            client.cancel([future for future, _ in in_flight.values()])  # a message, not waited on
            raise

    def _result(self, client: Any, future: Any) -> Any:
        """A finished future's result, fetched from its worker through the scheduler: each wait
        bounded by ``connect_timeout`` seconds, the scheduler asked whether it still answers
        after each that passes. A failed task's exception is held here, raised at once."""
        if future.status == "error":
            return future.result()
        while True:
            try:
                return future.result(timeout=self.connect_timeout)
            except TimeoutError:
                if self.scheduler:
                    self._check_answers(client)

    def _check_answers(self, client: Any) -> None:
        """EngineError unless the running scheduler answers within ``connect_timeout`` seconds
        (asked when no batch has finished for that long: batches may take long, a scheduler
        that stopped answering would keep the sweep waiting forever)."""
        try:
            client.sync(client.scheduler.identity, callback_timeout=self.connect_timeout)
        except Exception as exc:  # a timeout, a closed connection: the scheduler is gone either way
            raise EngineError(
                f"the Dask scheduler at {self.scheduler} stopped answering during the sweep (no batch came back "
                f"and no answer within {self.connect_timeout:g} s each, --connect-timeout; "
                f"{type(exc).__name__}); the rows finished so far are kept: continue with --resume"
            ) from None


async def _stop_workers(cluster: Any) -> None:
    """Close the embedded cluster's nannies, each stopping its worker within ``STOP_SECONDS``."""
    nannies = [nanny for nanny in list(cluster.workers.values()) if hasattr(nanny, "close")]
    await asyncio.gather(*(nanny.close(timeout=STOP_SECONDS) for nanny in nannies), return_exceptions=True)


def _batches(items: list, sizer: BatchSizer) -> Iterator[list]:
    start = 0
    while start < len(items):
        size = sizer.size(len(items) - start)
        yield items[start : start + size]
        start += size


def scheduler_endpoint(address: str, source: str = "--scheduler") -> tuple[str, int]:
    """(host, port) of a Dask scheduler address (``tcp://HOST:PORT``, ``tls://HOST:PORT`` or
    ``HOST:PORT``); EngineError naming it and its ``source`` (the option or variable) otherwise."""
    text = address.strip() if isinstance(address, str) else ""
    try:
        parts = urlsplit(text if "://" in text else f"tcp://{text}")
        port = parts.port
    except ValueError:
        parts, port = None, None
    if parts is None or parts.scheme not in SCHEMES or not parts.hostname or port is None or not 0 < port < 65536:
        raise EngineError(
            f"{source} {address!r}: not a Dask scheduler address; give tcp://HOST:PORT (or tls://HOST:PORT, "
            f"or HOST:PORT), e.g. tcp://127.0.0.1:8786"
        )
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise EngineError(f"{source} {address!r}: a scheduler address has no path, e.g. tcp://127.0.0.1:8786")
    return parts.hostname, port


def _connect(scheduler: str | None, workers: int | None, timeout: float) -> tuple[Client, LocalCluster | None]:
    """(client, cluster): a client of the scheduler, or of a new embedded cluster (its cluster)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise EngineError(
            f"the sweep engine needs Dask's distributed scheduler ({exc}); "
            f"pip install 'dask[distributed]', or run with --in-process"
        ) from exc
    if scheduler:
        return _client_of(scheduler, timeout), None
    n = workers or default_workers()
    # The dashboard on a free port: the default 8787 may be another cluster's on a shared machine.
    # Logs only at CRITICAL: a worker whose scheduler went first (an interrupted sweep) logs its
    # lost heartbeat as an error with a traceback; what fails in a batch is that batch's rows.
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        silence_logs=logging.CRITICAL,
        preload=[WORKER_SETUP],
    )
    return Client(cluster), cluster


def _client_of(scheduler: str, timeout: float) -> Client:
    """A client of the running scheduler at ``scheduler``, each step of reaching it bounded by
    ``timeout`` seconds (module docstring)."""
    from distributed import Client

    host, port = scheduler_endpoint(scheduler)
    late = f"(--connect-timeout {timeout:g} s)"
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise EngineError(f"cannot reach the Dask scheduler at {scheduler}: {host}:{port}: {reason} {late}") from None
    _handshake(scheduler, timeout)
    try:
        client = Client(scheduler, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        raise EngineError(f"cannot reach the Dask scheduler at {scheduler}: {exc} {late}") from exc
    except Exception as exc:  # Dask's own errors for a peer that is no scheduler
        raise EngineError(f"the Dask scheduler at {scheduler} could not be used: {type(exc).__name__}: {exc}") from exc
    try:
        client.wait_for_workers(1, timeout=timeout)
        _check_workers(client, scheduler, timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise EngineError(
            f"the Dask scheduler at {scheduler} has no worker (none joined within "
            f"{timeout:g} s, --connect-timeout): start one with `dask worker {scheduler}`"
        ) from exc
    except BaseException:
        client.close()
        raise
    return client


def _handshake(scheduler: str, timeout: float) -> None:
    """EngineError unless the scheduler answers Dask's handshake within ``timeout`` seconds.
    Dask waits for that answer without a deadline; here it runs on its own thread and event
    loop (the caller's thread may run one already), waited for in short slices so that Ctrl-C
    and SIGTERM are handled at once."""
    from distributed.comm import connect

    failure: list[BaseException] = []

    async def probe() -> None:
        comm = await asyncio.wait_for(connect(scheduler, timeout=timeout), timeout)
        await comm.close()

    def run() -> None:
        try:
            asyncio.run(probe())
        except BaseException as exc:  # handed to the waiting thread
            failure.append(exc)

    thread = threading.Thread(target=run, name="legsim-scheduler-probe", daemon=True)
    thread.start()
    deadline = time.monotonic() + timeout + 1.0
    while thread.is_alive() and time.monotonic() < deadline:
        thread.join(0.1)
    if thread.is_alive() or (failure and isinstance(failure[0], (TimeoutError, asyncio.TimeoutError))):
        raise EngineError(
            f"the Dask scheduler at {scheduler} accepted the connection but did not answer within {timeout:g} s "
            f"(--connect-timeout): is it a Dask scheduler, and is it running?"
        )
    if failure:
        exc = failure[0]
        raise EngineError(
            f"the Dask scheduler at {scheduler} could not be reached: {type(exc).__name__}: {exc}"
        ) from exc


def _check_workers(client: Any, scheduler: str, timeout: float) -> None:
    """The scheduler's workers must run this version of legsim (their answer bounded by
    ``timeout`` seconds)."""
    from ..version import __version__

    try:
        versions = client.run(_legsim_version, callback_timeout=timeout)
    except (OSError, TimeoutError):
        raise
    except Exception as exc:
        raise EngineError(
            f"the workers of the Dask scheduler at {scheduler} cannot run legsim "
            f"({type(exc).__name__}: {exc}); install legsim {__version__} where they run"
        ) from exc
    wrong = {worker: version for worker, version in versions.items() if version != __version__}
    if wrong:
        raise EngineError(
            f"the workers of the Dask scheduler at {scheduler} run another legsim: {wrong}; "
            f"this is legsim {__version__}"
        )


def _legsim_version() -> str:
    from ..version import __version__

    return __version__
