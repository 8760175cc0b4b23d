"""Print what the benchmark systems' references say and how far the relaxed integrator is from
them: ``python -m legsim.systems.report`` (a few seconds on one core).

The numbers of docs/systems.md come from this script.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..relaxed import simulate
from . import bouncing_ball as bb
from . import digital_control as dc
from . import oscillator as osc


def _slope(xs, ys) -> float:
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def _oscillator_run(
    name: str,
    h: float,
    eps: float,
    method: str = "rk4",
    landing: str = "halve",
    t_final: float | None = None,
    stop: bool = True,
):
    E = osc.EXAMPLES[name]
    system = osc.make_system(E["omega"], E["a"], E["x_max"] if stop else None, E["c"], E["mass"])
    return simulate(
        system,
        [E["x0"], E["xd0"]],
        "free",
        E["t_max"] if t_final is None else t_final,
        h,
        eps,
        method,
        osc.forcing(E["amplitude"], E["frequency"]),
        landing=landing,
    )


def references() -> None:
    print("== exact references")
    for name in ("ex1", "ex2"):
        E = osc.EXAMPLES[name]
        t = time.perf_counter()
        ref = osc.OscillatorReference.example(name)
        impacts = ref.impact_times(E["t_max"])
        wall = time.perf_counter() - t
        print(
            f"oscillator {name}: {len(impacts)} resolved impacts in [0, {E['t_max']:.6g}] s "
            f"(built in {wall:.3f} s); first {impacts[:3].round(6).tolist()}"
        )
        for s, e in ref.sticking_intervals(E["t_max"]):
            print(f"  sticks on [{s:.10f}, {e:.10f}] s")
        for s, e in ref.chatter_intervals(E["t_max"]):
            print(f"  Zeno accumulation: last resolved impact {s:.10f} s, accumulation time {e:.10f} s")
        x, xd = ref.state(E["t_max"])
        print(f"  state at t_max: x = {x:.10f} m, xd = {xd:.10f} m/s")
    ball = bb.BouncingBallReference()
    print(
        f"bouncing ball (g 9.81, c 0.5, z0 1): first impact {ball.first_impact:.10f} s, "
        f"Zeno time {ball.zeno_time:.10f} s"
    )
    d = dc.make_reference()
    print(
        f"digital control nominal: transitions at {[round(t, 12) for t in d.transition_times]} s "
        f"(ln 2 = {math.log(2):.12f}), modes {d.mode_sequence}, simultaneous={d.simultaneous}"
    )


def scenes() -> None:
    print("== relaxed integrator vs reference (the bundled scenes' settings)")
    for name, eps in (("ex1", 1e-6), ("ex2", 1e-5)):
        E = osc.EXAMPLES[name]
        ref = osc.OscillatorReference.example(name)
        ex = _oscillator_run(name, 1e-2, eps)
        ts = np.linspace(0, E["t_max"], 20001)
        pos = np.abs(np.array(ex.sample(ts).states)[:, 0] - ref.position(ts)).max()
        fin = np.abs(ex.final_state - ref.state(E["t_max"])).max()
        line = (
            f"oscillator {name} rk4 h=1e-2 eps={eps:g}: {len(ex.transitions)} transitions, "
            f"max |x - x_ref| {pos:.2e} m, final state error {fin:.2e}, wall {ex.counters['wall_time_s']:.2f} s"
        )
        if name == "ex1":
            sim = np.array([tr.time for tr in ex.transitions])
            line += f", max impact time error {np.abs(sim - ref.impact_times(E['t_max'])).max():.2e} s"
        print(line)
    ball = bb.BouncingBallReference()
    ex = simulate(bb.make_system(), [1.0, 0.0], "flight", 2.7, 1e-3, 1e-4)
    sim = np.array([tr.time for tr in ex.transitions[:10]])
    print(
        f"bouncing ball rk4 h=1e-3 eps=1e-4 to 2.7 s: {len(ex.transitions)} transitions, first 10 impact "
        f"times late by {(sim - ball.impact_time(np.arange(1, 11))).max():.2e} s at most, final state "
        f"{ex.final_state.tolist()}"
    )
    d = dc.make_reference()
    for eps in (1e-3, 1e-4, 1e-5):
        ex = simulate(dc.make_system(), dc.nominal_initial_state(), "0", 3.0, 1e-2, eps)
        print(
            f"digital control eps={eps:g}: modes {ex.mode_sequence}, final error "
            f"{np.abs(ex.final_state - d.state(3.0)).max():.2e}"
        )


def convergence() -> None:
    print("== convergence on Example 1 up to t = 6 s (3 impacts)")
    ref = osc.OscillatorReference.example("ex1")
    for method, hs in (
        ("euler", [1e-3, 5e-4, 2.5e-4, 1.25e-4]),
        ("rk2", [1e-2, 5e-3, 2.5e-3, 1.25e-3]),
        ("rk4", [1.25e-2, 6.25e-3, 3.125e-3]),
    ):
        errs = [
            np.abs(_oscillator_run("ex1", h, 1e-12, method, t_final=6.0).final_state - ref.state(6.0)).max() for h in hs
        ]
        print(f"{method:5s} eps=1e-12 h={hs}: errors {[f'{e:.2e}' for e in errs]}, slope {_slope(hs, errs):.2f}")
    eps = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7]
    for landing in ("aim", "halve"):
        errs = [
            np.abs(_oscillator_run("ex1", 5e-3, e, landing=landing, t_final=6.0).final_state - ref.state(6.0)).max()
            for e in eps
        ]
        ratios = np.array(errs) / np.array(eps)
        print(
            f"rk4 h=5e-3 landing={landing} eps={eps}: errors {[f'{e:.2e}' for e in errs]}, "
            f"slope {_slope(eps, errs):.2f}, error/eps from {ratios.min():.3g} to {ratios.max():.3g}"
        )


def main() -> None:
    references()
    scenes()
    convergence()


if __name__ == "__main__":
    main()
