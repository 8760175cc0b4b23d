"""Cost of one field and one guards evaluation per robot and mode, against a bare ABA on the same
model, and each robot scene's run time.

    .venv/bin/python benchmarks/field_cost.py [--calls 20000] [--scene NAME ...]

Part 1 runs each scene, keeps up to 64 states of each mode, and times the mode's compiled model
functions (``Mode.functions``: the field, every guard at once) called from a compiled loop over
those states (cycled, so the native library's one-solve cache never serves them), against a
bare C++ ABA on the robot's model (``legsim.robots._native.time_aba``, no numba, no wrapper), the floor
a field can go to. A field with constraints adds the KKT solve (M^-1, the contact Jacobians);
the quadruped's runner law adds the generalised gravity in flight.

Part 2 gives each scene's run: wall time, steps, field evaluations and the share of the wall time
not spent in as many bare ABA calls.

Times are the best of 3 batches; the machine may be shared, so compare ratios, not absolutes.
This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from legsim.robots import _native

from legsim.scene import load_scene

SCENES = ("double_pendulum_plastic", "pronk", "slip", "compass_gait", "rimless_wheel", "rod", "quadruped_pronk")
#: Shorter runs of the long scenes (s).
T_FINAL = {"quadruped_pronk": 2.0}


@numba.njit
def _loop(fn, calls, states, u, p, out):
    for i in range(calls):
        fn(0.0, states[i % states.shape[0]], u, p, out)


def best_of(call, repeats: int = 3) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best


def states_by_mode(execution, dim_of, limit: int = 64) -> dict[str, np.ndarray]:
    """Up to ``limit`` stored plant states per mode (the controller's memory cut off)."""
    out: dict[str, list[np.ndarray]] = {}
    for seg in execution.segments:
        bucket = out.setdefault(seg.mode, [])
        step = max(1, len(seg.x) // limit)
        bucket.extend(np.ascontiguousarray(x[: dim_of(seg.mode)]) for x in seg.x[::step][: limit - len(bucket)])
    return {mode: np.array(xs) for mode, xs in out.items() if len(xs) > 1}


def mode_costs(scene, calls: int) -> list[tuple[str, int, float, float, float]]:
    """(mode, guards, field us, guards us, bare aba us) of each mode the scene's run visits."""
    system = scene.model.system
    execution = scene.simulate()
    law = scene.control
    rows = []
    for mode, states in states_by_mode(execution, lambda m: system.mode(m).dim).items():
        functions = system.mode(mode).functions
        p, guards = np.array(functions.params), len(system.outgoing(mode))
        u = np.zeros(functions.inputs)
        if law is not None:
            u = law.input_at(mode, 0.0, states[0])
        out = np.empty(max(states.shape[1], guards, 1))
        timed = []
        for fn in (functions.field, functions.guards):
            if fn is None:
                timed.append(np.nan)
                continue
            _loop(fn, 2, states, u, p, out)
            timed.append(best_of(lambda fn=fn, s=states, u=u, p=p, o=out: _loop(fn, calls, s, u, p, o)) / calls * 1e6)
        nv = (states.shape[1] - 1) // 2 if scene.model.system.name in ("compass_gait", "rimless_wheel") else None
        handle, n = int(p[0]), nv if nv is not None else int(p[1])
        x = states[0]
        aba = _native.time_aba(handle, x[:n], x[n : 2 * n], np.zeros(n), calls) * 1e6
        rows.append((mode, guards, timed[0], timed[1], aba))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=20000)
    parser.add_argument("--scene", action="append")
    args = parser.parse_args()
    scenes = args.scene or SCENES
    print("Part 1: cost per call (us), compiled loop over a mode's states, against bare C++ ABA")
    print(f"{'scene':24} {'mode':16} {'guards':>6} {'field':>8} {'guards':>8} {'aba':>7} {'field/aba':>9}")
    for name in scenes:
        overrides = [f"integrator.t_final={T_FINAL[name]}"] if name in T_FINAL else []
        for mode, guards, field, guard, aba in mode_costs(load_scene(name, overrides), args.calls):
            print(f"{name:24} {mode:16} {guards:6d} {field:8.3g} {guard:8.3g} {aba:7.3g} {field / aba:9.2f}")
    print()
    print("Part 2: scene runs (wall time of the second run; the first compiles or loads the kernel)")
    print(f"{'scene':24} {'wall s':>8} {'steps':>8} {'fields':>8} {'us/field':>9}")
    for name in scenes:
        scene = load_scene(name)
        scene.simulate()
        start = time.perf_counter()
        ex = scene.simulate()
        wall = time.perf_counter() - start
        c = ex.counters
        print(f"{name:24} {wall:8.3f} {c['steps']:8d} {c['field_evals']:8d} {1e6 * wall / c['field_evals']:9.2f}")


if __name__ == "__main__":
    main()
