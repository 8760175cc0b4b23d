"""Showing recordings in a Rerun viewer: a run streamed live (``legsim run --spawn`` or
``--connect ADDRESS``) and a recording file opened (``legsim replay --spawn``).

The checks run before any work: ``--spawn`` needs a display, and ``--connect`` an address that
accepts a connection and answers now, since Rerun's own client only logs, and drops the data,
when nothing listens there, and waits without a deadline for a peer that accepts and never
answers. Every wait of ``--connect`` has a deadline, ``timeout`` (``--connect-timeout``,
default ``CONNECT_TIMEOUT``): the TCP connection (a closed port is refused at once), the
viewer's first answer (the HTTP/2 settings a gRPC server sends on a new connection; for
``rerun+https``, the TLS handshake), and, after the run, the viewer taking the recording: the
recording is written to a temporary file and sent by a child process (``send``), which is
killed when the deadline passes or the run is interrupted (Ctrl-C and SIGTERM end it within a
fraction of a second).

Rerun's viewer collects usage analytics unless they are turned off, and a viewer's first run on
a machine writes a setting that turns them on for every later one. legsim never decides that
for its user: before it starts a viewer on a machine where Rerun has no analytics setting yet,
it runs Rerun's documented opt-out, ``rerun analytics disable`` (``viewer_analytics_off``); a
setting the user made (``rerun analytics enable`` or ``disable``) or ``FORCE_RERUN_ANALYTICS``
is left alone. Sending to a viewer the user started (``--connect``) starts none.
"""

from __future__ import annotations

import contextlib
import os
import socket
import ssl
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from ...builders import Model
from ...errors import LegsimError
from ...execution import Execution
from ...hybrid import HybridSystem
from ..files import temporary_folder
from ..untrusted import printable
from .send import layout_json
from .write import check_complete, prepare, record, recording_stream

#: Rerun's default port for a viewer or proxy; ``--connect`` without a port uses it.
DEFAULT_PORT = 9876
#: Seconds each step of ``--connect`` may take (module docstring), unless told otherwise.
CONNECT_TIMEOUT = 10.0
#: An HTTP/2 client's opening: the connection preface and an empty SETTINGS frame. A gRPC
#: server answers it with its own SETTINGS frame (type 4).
HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
#: Seconds between two looks at the sending process (how soon a signal is handled).
POLL_SECONDS = 0.05
#: Rerun's environment variable that turns its analytics on whatever the setting: the user's
#: to set; legsim reads it and never sets it.
FORCE_ANALYTICS = "FORCE_RERUN_ANALYTICS"
#: Seconds ``rerun analytics disable`` may take.
ANALYTICS_TIMEOUT = 60.0


def has_display() -> bool:
    """True when a graphical viewer can open a window here."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_display(flag: str, instead: str) -> None:
    """LegsimError naming ``flag`` when no window can open here; ``instead`` says what to do."""
    if not has_display():
        raise LegsimError(
            f"{flag} needs a display, and there is none here (DISPLAY and WAYLAND_DISPLAY are unset); {instead}"
        )


def rerun_analytics_setting() -> Path:
    """The file holding Rerun's analytics setting (what ``rerun analytics config`` shows): its
    ``analytics.json`` in Rerun's configuration folder, found as Rerun finds it (the
    ``directories`` crate's project folder ``rerun``: XDG on Linux)."""
    if sys.platform == "darwin":
        folder = Path.home() / "Library" / "Application Support" / "rerun"
    elif sys.platform == "win32":
        folder = Path(os.environ.get("APPDATA") or Path.home() / "AppData" / "Roaming") / "rerun" / "config"
    else:
        xdg = os.environ.get("XDG_CONFIG_HOME", "")
        folder = (Path(xdg) if os.path.isabs(xdg) else Path.home() / ".config") / "rerun"
    return folder / "analytics.json"


def viewer_analytics_off() -> None:
    """Before legsim starts a Rerun viewer: when Rerun has no analytics setting here yet (its
    first run would write one that turns them on) and ``FORCE_RERUN_ANALYTICS`` is not set, run
    Rerun's opt-out ``rerun analytics disable`` and say so on stderr. LegsimError when that
    fails: the viewer is then not started."""
    # The values Rerun reads as true (re_log::env_var_flag); any other leaves its setting in charge.
    forced = os.environ.get(FORCE_ANALYTICS, "").strip().lower() in ("1", "true", "yes", "on")
    setting = rerun_analytics_setting()
    if forced or setting.exists():
        return
    command = [sys.executable, "-m", "rerun_cli", "analytics", "disable"]
    try:
        done = subprocess.run(
            command, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=ANALYTICS_TIMEOUT, check=False
        )
        reason = f"exit code {done.returncode}: {done.stderr.strip()[-300:]}"
    except (OSError, subprocess.SubprocessError) as exc:
        done, reason = None, f"{type(exc).__name__}: {exc}"
    if done is None or done.returncode != 0 or not setting.exists():
        raise LegsimError(
            f"Rerun has no analytics setting here ({setting}), and `rerun analytics disable` failed "
            f"({reason}); run `rerun analytics disable` (or `rerun analytics enable`) yourself before "
            f"starting a viewer from legsim"
        )
    print(
        f"legsim: Rerun had no analytics setting here; turned its usage analytics off with "
        f"`rerun analytics disable` before starting its viewer (setting in {setting}; "
        f"`rerun analytics enable` turns them on)",
        file=sys.stderr,
    )


def viewer_url(address: str) -> str:
    """The gRPC URL of a Rerun viewer or proxy at ``address``: a port (``9876``), ``HOST:PORT``
    or a full ``rerun+http://HOST:PORT/proxy`` URL; LegsimError naming it otherwise."""
    text = address.strip()
    if text.isdigit():
        text = f"127.0.0.1:{text}"
    if "://" not in text:
        text = f"rerun+http://{text}/proxy"
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError:
        parts, port = None, None
    if (
        parts is None
        or parts.scheme not in ("rerun", "rerun+http", "rerun+https")
        or not parts.hostname
        or parts.path.rstrip("/") != "/proxy"
        or (port is not None and not 0 < port < 65536)
    ):
        raise LegsimError(
            f"--connect {address!r}: not a Rerun viewer address; give a port (9876), HOST:PORT "
            f"or rerun+http://HOST:PORT/proxy"
        )
    return text


def check_reachable(address: str, url: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """LegsimError naming ``address`` when nothing accepts a connection at ``url``, or what does
    does not answer as a gRPC server within ``timeout`` seconds (module docstring)."""
    parts = urlsplit(url)
    host, port = parts.hostname or "", parts.port or DEFAULT_PORT
    late = f"within {timeout:g} s (--connect-timeout)"
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as exc:
        reason = f"no answer {late}" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise LegsimError(
            f"--connect {address}: no Rerun viewer answers at {host}:{port} ({reason}); start one with `rerun` "
            f"(or `rerun --serve-grpc`) there first"
        ) from None
    try:
        with sock:
            sock.settimeout(timeout)
            answer = _first_answer(sock, host, parts.scheme == "rerun+https")
    except TimeoutError:
        raise LegsimError(
            f"--connect {address}: {host}:{port} accepted the connection but did not answer {late}; is a Rerun "
            f"viewer running there?"
        ) from None
    except (OSError, ssl.SSLError) as exc:
        raise LegsimError(f"--connect {address}: {host}:{port} broke the connection: {exc}") from None
    if answer is not None and (len(answer) < 4 or answer[3] != 4):
        raise LegsimError(
            f"--connect {address}: {host}:{port} answered {printable(answer[:24])!r}, not as a Rerun viewer "
            f"(a gRPC server) does"
        )


def _first_answer(sock: socket.socket, host: str, tls: bool) -> bytes | None:
    """The first bytes the server sends after an HTTP/2 client's opening (None for TLS, whose
    finished handshake is the answer)."""
    if tls:
        context = ssl.create_default_context()
        context.set_alpn_protocols(["h2"])
        with context.wrap_socket(sock, server_hostname=host):
            return None
    sock.sendall(HTTP2_PREFACE)
    answer = sock.recv(64)
    if not answer:
        raise ConnectionError("it closed the connection without answering")
    return answer


def stream_rrd(
    execution: Execution,
    scene: Any = None,
    *,
    spawn: bool = False,
    connect: str | None = None,
    model: Model | HybridSystem | None = None,
    rate: float | None = None,
    timeout: float = CONNECT_TIMEOUT,
) -> None:
    """Send the recording of ``execution`` (as ``write_rrd`` would write it, with the same
    ``scene``, ``model`` and ``rate``) to a new viewer (``spawn``) or to the viewer at
    ``connect`` (an address for ``viewer_url``), each wait of the latter bounded by ``timeout``
    seconds (module docstring)."""
    if spawn == (connect is not None):
        raise LegsimError("stream_rrd needs one of spawn=True or connect=ADDRESS")
    content = prepare(execution, scene, model, rate, f"--connect {connect}" if connect else "--spawn")
    if connect is None:
        viewer_analytics_off()
        with recording_stream() as rec:
            rec.spawn(connect=True)
            record(rec, content)
        return
    url = viewer_url(connect)
    # Python's first use of its temporary folder writes and removes a probe file there: done
    # before the first wait, a Ctrl-C or SIGTERM during the waits cannot land inside it.
    tempfile.gettempdir()
    check_reachable(connect, url, timeout)
    with temporary_folder("legsim-connect-") as folder:
        file = folder / "recording.rrd"
        with recording_stream() as rec:
            rec.save(file)
            layout = record(rec, content)
        check_complete(file, file)
        _send(connect, url, file, layout_json(layout), timeout)


def _send(address: str, url: str, file: Path, layout: str, timeout: float) -> None:
    """Run ``send`` on ``file``, waiting at most ``timeout`` seconds; LegsimError naming
    ``address`` when it fails or the deadline passes. On any exception (Ctrl-C, SIGTERM) the
    child is killed before it propagates."""
    with tempfile.TemporaryFile() as said:
        child = subprocess.Popen(
            [sys.executable, "-m", "legsim.output.rrd.send", url, str(file), layout],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=said,
            start_new_session=True,  # Ctrl-C at the terminal is the parent's to handle
            # Python's first use of its temporary folder writes a probe file there; a child
            # killed at that moment would leave it behind, so the child's folder is ours to remove.
            env={**os.environ, "TMPDIR": str(file.parent)},
        )
        try:
            deadline = time.monotonic() + timeout
            while child.poll() is None and time.monotonic() < deadline:
                time.sleep(POLL_SECONDS)
        finally:
            if child.poll() is None:
                child.kill()
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.wait(timeout=5)
        said.seek(0)
        lines = [line for line in said.read(65536).decode("utf-8", "replace").splitlines() if line.strip()]
    host = urlsplit(url).netloc
    if child.returncode in (-9, None):
        raise LegsimError(
            f"--connect {address}: the viewer at {host} did not take the recording within {timeout:g} s "
            f"(--connect-timeout); is it still running?"
        )
    if child.returncode != 0:
        raise LegsimError(
            f"--connect {address}: sending the recording to {host} failed: "
            f"{printable(lines[-1] if lines else f'exit {child.returncode}', newlines=False)}"
        )


def open_in_viewer(path: Path) -> None:
    """Open the recording file ``path`` in Rerun's bundled viewer, detached so that the viewer
    outlives this command."""
    viewer_analytics_off()
    # rerun-sdk runs its bundled viewer as `python -m rerun_cli FILE`.
    subprocess.Popen(
        [sys.executable, "-m", "rerun_cli", str(path)],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
