"""Cost of one vector-field evaluation per robot and mode, and the share of simulation time
spent outside Pinocchio.

    .venv/bin/python benchmarks/field_cost.py [--repeat 5] [--calls 4000]

Part 1 times ``field(t, x, None)`` over states recorded in each mode of each robot's scene run
(cycled, so the bridge's one-state cache never hits), and a bare ``pinocchio.aba`` call on the
same model as the floor no Python wrapper can go below.

Part 2 runs each robot scene twice: once plainly (wall time), once with every Pinocchio function
the bridge calls wrapped by a timer, and reports the share of the run spent outside those calls
(integrator, guards' Python, numpy glue). The timers add a fraction of a microsecond per call, charged to the
Pinocchio side, so the share outside is a slight underestimate.

Times are CPU time of this process (``time.process_time``), not wall time: the benchmark
machine is shared, and CPU time does not count the moments another process holds the core.

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import pkgutil
import statistics
import time
import types
from collections.abc import Iterator
from typing import Any

import legsim.robots.bridge as bridge_package
import numpy as np
import pinocchio

from legsim.scene import load_scene

SCENES = ("double_pendulum_plastic", "double_pendulum_zeno", "pronk", "pronk_pitched", "slip")


def states_by_mode(execution, limit: int = 64) -> dict[str, list[np.ndarray]]:
    """Up to ``limit`` distinct stored states per mode of an execution."""
    out: dict[str, list[np.ndarray]] = {}
    for seg in execution.segments:
        bucket = out.setdefault(seg.mode, [])
        step = max(1, len(seg.x) // limit)
        bucket.extend(np.array(x) for x in seg.x[::step][: limit - len(bucket)])
    return out


def time_calls(fn, args_list, calls: int, repeat: int) -> float:
    """Median over ``repeat`` runs of the mean time per call (us)."""
    n = len(args_list)
    per_call = []
    for _ in range(repeat):
        t0 = time.process_time()
        for i in range(calls):
            fn(*args_list[i % n])
        per_call.append((time.process_time() - t0) / calls * 1e6)
    return statistics.median(per_call)


def field_table(calls: int, repeat: int) -> list[tuple[str, str, int, float, float]]:
    rows = []
    seen = set()
    for name in SCENES:
        scene = load_scene(name)
        robot = scene.robot
        ex = scene.simulate()
        bridge = scene.model.info["bridge"]
        model, data = bridge.model, bridge.model.createData()
        for mode, xs in states_by_mode(ex).items():
            if (robot, mode, bridge.model.nv) in seen or len(xs) < 2:
                continue
            seen.add((robot, mode, bridge.model.nv))
            field = scene.model.system.mode(mode).field
            us = time_calls(field, [(0.0, x, None) for x in xs], calls, repeat)
            n = bridge.n
            tau = np.zeros(n)
            aba = time_calls(pinocchio.aba, [(model, data, x[:n], x[n : 2 * n], tau) for x in xs], calls, repeat)
            rows.append((robot, mode, len(xs[0]), us, aba))
    return rows


class _TimedPin(types.ModuleType):
    """Stand-in for the ``pinocchio`` module inside legsim.robots.bridge's modules: every function is timed."""

    def __init__(self) -> None:
        super().__init__("pinocchio_timed")
        self.seconds = 0.0
        self.calls = 0

    def __getattr__(self, name: str) -> Any:
        real = getattr(pinocchio, name)
        if not callable(real) or isinstance(real, type):
            return real
        clock = time.process_time

        def timed(*args, **kwargs):
            t0 = clock()
            try:
                return real(*args, **kwargs)
            finally:
                self.seconds += clock() - t0
                self.calls += 1

        setattr(self, name, timed)  # cache: later lookups skip __getattr__
        return timed


def bridge_modules_using_pinocchio() -> list[types.ModuleType]:
    """The modules of the bridge package that call Pinocchio through a module global ``pin``."""
    modules = [
        importlib.import_module(f"{bridge_package.__name__}.{info.name}")
        for info in pkgutil.iter_modules(bridge_package.__path__)
    ]
    return [m for m in modules if getattr(m, "pin", None) is pinocchio]


@contextlib.contextmanager
def pinocchio_replaced(stand_in: types.ModuleType) -> Iterator[None]:
    """Make every bridge module call ``stand_in`` instead of Pinocchio, for the duration."""
    modules = bridge_modules_using_pinocchio()
    for m in modules:
        m.pin = stand_in
    try:
        yield
    finally:
        for m in modules:
            m.pin = pinocchio


def share_table(repeat: int) -> list[tuple[str, float, float, int, float, int]]:
    rows = []
    bias = clock_bias()
    for name in SCENES:
        plain = []
        for _ in range(repeat):
            scene = load_scene(name)
            t0 = time.process_time()
            scene.simulate()
            plain.append(time.process_time() - t0)
        timed_pin = _TimedPin()
        with pinocchio_replaced(timed_pin):
            scene = load_scene(name)
            timed_pin.seconds, timed_pin.calls = 0.0, 0
            t0 = time.process_time()
            ex = scene.simulate()
            wall = time.process_time() - t0
        # The inner time of each timed call includes part of the clock reads: subtract that bias
        # (measured on a wrapped no-op) and compare with the plain run, which has no timers.
        pin_seconds = timed_pin.seconds - timed_pin.calls * bias
        rows.append(
            (
                name,
                statistics.median(plain),
                wall,
                timed_pin.calls,
                1.0 - pin_seconds / statistics.median(plain),
                int(ex.counters["field_evals"]),
            )
        )
    return rows


def clock_bias(samples: int = 200_000) -> float:
    """Seconds a timed wrapper charges to a call that does nothing (the clock reads' share)."""
    clock = time.process_time
    total = 0.0
    for _ in range(samples):
        t0 = clock()
        try:
            pass
        finally:
            total += clock() - t0
    return total / samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="repetitions (median reported)")
    parser.add_argument("--calls", type=int, default=4000, help="field evaluations per repetition")
    args = parser.parse_args()

    print(f"pinocchio {pinocchio.__version__}, numpy {np.__version__}")
    print()
    print("One vector-field evaluation (us per call; median of", args.repeat, "runs)")
    print(f"{'robot':16s} {'mode':14s} {'dim':>3s} {'field us':>9s} {'bare aba us':>12s} {'ratio':>6s}")
    for robot, mode, dim, us, aba in field_table(args.calls, args.repeat):
        print(f"{robot:16s} {mode:14s} {dim:3d} {us:9.2f} {aba:12.2f} {us / aba:6.1f}")
    print()
    print("Scene runs: CPU time and share outside Pinocchio")
    print(
        f"{'scene':24s} {'cpu s':>7s} {'timed cpu s':>12s} {'pin calls':>10s} {'field evals':>12s} {'outside pin':>12s}"
    )
    for name, plain, wall, calls, outside, fevals in share_table(args.repeat):
        print(f"{name:24s} {plain:7.3f} {wall:12.3f} {calls:10d} {fevals:12d} {100 * outside:11.1f}%")


if __name__ == "__main__":
    main()
