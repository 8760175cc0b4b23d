"""What one step costs around the model, for the relaxed integrator's Python loop and for
scipy's ``solve_ivp`` with events, with the same method and the same cheap field.

    .venv/bin/python benchmarks/loop_overhead.py [--repeat 7]

A six-dimensional linear decay with two guards that never fire, integrated over 200 s with a
largest step of 0.2 s (1001 steps, no transitions): what remains of a run's time after the
field is the step routine, the error norm, the guard checks and the loop's bookkeeping. The
field costs about 1 us here; on the robots it is 6-11 us (benchmarks/field_cost.py), so the
difference per step matters in proportion. Both sides take the same steps (the step counts
are printed); the ratio is time of solve_ivp / time of relaxed, from CPU times of this process
measured in the same run (least disturbed of the repeats).

This is a benchmark, not a test: it prints numbers and asserts nothing.
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import numpy as np

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.baselines import simulate_events

RATES = np.array([1.0, 0.7, 0.5, 0.3, 0.2, 0.1])


def decay(t: float, x: np.ndarray, u: object) -> np.ndarray:
    return -RATES * x


def system() -> HybridSystem:
    far = [
        Transition("a", "a", guard=lambda x, i=i: x[i] + 10.0, reset=lambda x: x.copy(), name=f"far{i}") for i in (0, 1)
    ]
    return HybridSystem({"a": Mode(6, decay)}, far)


def best_cpu_time(run, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    hs = system()
    x0 = np.ones(6)
    print("per-step cost, field included (about 1 us per evaluation), 6 states, 2 guards")
    print(
        f"{'method':8s} {'tol':>6s} {'relaxed steps':>13s} {'us/step':>8s} {'solve_ivp steps':>15s} "
        f"{'us/step':>8s} {'ratio':>6s}"
    )
    for ivp_method, tableau in (("DOP853", "dop853"), ("RK45", "dopri5")):
        for tol in (1e-6, 1e-9):
            relaxed = partial(simulate, hs, x0, "a", 200.0, 0.2, 1e-9, tableau, rtol=tol, atol=tol, landing="dense")
            ivp = partial(simulate_events, hs, x0, "a", 200.0, method=ivp_method, rtol=tol, atol=tol, max_step=0.2)

            r, i = relaxed(), ivp()  # warm up, and the step counts
            t_relaxed, t_ivp = best_cpu_time(relaxed, args.repeat), best_cpu_time(ivp, args.repeat)
            per_r = t_relaxed / r.counters["steps"] * 1e6
            per_i = t_ivp / i.counters["steps"] * 1e6
            print(
                f"{ivp_method:8s} {tol:6.0e} {r.counters['steps']:13d} {per_r:8.1f} {i.counters['steps']:15d} "
                f"{per_i:8.1f} {per_i / per_r:5.2f}x"
            )


if __name__ == "__main__":
    main()
