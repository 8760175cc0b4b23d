"""Optional: legsim's compiled walkers against Drake's own (pydrake), interleaved in one process.

Drake is never installed into the project's venv. Set it up once in its own environment and
point this script at its site-packages (appended to sys.path, after the project's packages):

    python3 -m venv /work/drake-venv && /work/drake-venv/bin/pip install drake
    .venv/bin/python benchmarks/drake_compare.py --drake-site /work/drake-venv/lib/python3.11/site-packages

Both simulators run Drake's compass gait and rimless wheel with Drake's default parameters,
started on their limit cycles (each from Drake's example start walked for 30 s, the state right
after the last impact). Each run's error is that of its impacts against its own simulator's
reference run (rtol/accuracy 1e-12): the largest difference of impact times (s) and post-impact
states. Drake's configurations are its fastest: RK3 with error control (``set_target_accuracy``
on the integrator as well as ``SetAccuracy`` on the context; largest step 0.1 s, and 0.2 s at
accuracies down to 1e-6) and fixed-step RK3 and RK5 with a coarse witness window (context
accuracy 0.1). legsim's: the compiled relaxed runs of ``legsim bench robots`` (rk4 with aimed
landing, dopri5 and dop853 with dense landing). The two are timed alternately, config by config,
for ``--rounds`` rounds; for
each error level the best time of each side is taken per round, and the median ratio printed
(Drake / legsim: > 1 means legsim is faster). Print ``uptime`` next to the numbers.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np

LEVELS = (1e-4, 1e-6, 1e-8)
EXAMPLE_START = {"compass-gait": [0.0, 0.0, 0.4, -2.0], "rimless-wheel": [0.0, 5.0]}


def drake_plant(name: str):
    from pydrake.examples import CompassGait, RimlessWheel

    return CompassGait() if name == "compass-gait" else RimlessWheel()


def drake_run(name: str, x0, t_final: float, config: tuple, record: bool):
    """(wall s, impacts [(t, state before)]) of one Drake run; config = (scheme, step, accuracy, fixed)."""
    from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator

    plant = drake_plant(name)
    sim = Simulator(plant)
    ctx = sim.get_mutable_context()
    ctx.SetContinuousState(np.asarray(x0, dtype=float))
    scheme, step, accuracy, fixed = config
    integrator = ResetIntegratorFromFlags(sim, scheme, step)
    integrator.set_fixed_step_mode(fixed)
    if not fixed:
        integrator.set_target_accuracy(accuracy)
    ctx.SetAccuracy(accuracy)
    impacts = []
    if record:
        # Drake applies an impact at the start of the step after the one whose end its witness
        # isolated, so the impact shows in the monitor one step late: keep the state at the end
        # of the step before (the isolated impact time and the pre-impact state).
        last = [float(ctx.get_discrete_state_vector()[0]), 0.0, None]

        def monitor(context):
            toe = float(context.get_discrete_state_vector()[0])
            if toe != last[0]:
                last[0] = toe
                impacts.append((last[1], last[2]))
            last[1], last[2] = context.get_time(), context.get_continuous_state_vector().CopyToVector()
            from pydrake.systems.framework import EventStatus

            return EventStatus.Succeeded()

        sim.set_monitor(monitor)
    sim.Initialize()
    start = time.perf_counter()
    sim.AdvanceTo(t_final)
    return time.perf_counter() - start, impacts


def _after_last_impact(name: str) -> np.ndarray:
    """The state just after the last impact within 30 s from Drake's example start: on the cycle."""
    from pydrake.systems.analysis import Simulator

    plant = drake_plant(name)
    sim = Simulator(plant)
    ctx = sim.get_mutable_context()
    ctx.SetContinuousState(np.asarray(EXAMPLE_START[name], dtype=float))
    sim.get_mutable_integrator().set_target_accuracy(1e-12)
    ctx.SetAccuracy(1e-12)
    seen = {"toe": float(ctx.get_discrete_state_vector()[0]), "state": None}

    def monitor(context):
        from pydrake.systems.framework import EventStatus

        toe = float(context.get_discrete_state_vector()[0])
        if toe != seen["toe"]:
            seen["toe"] = toe
            seen["state"] = context.get_continuous_state_vector().CopyToVector()
        return EventStatus.Succeeded()

    sim.set_monitor(monitor)
    sim.AdvanceTo(30.0)
    return seen["state"]


def impact_error(run, ref) -> float:
    if len(run) != len(ref):
        return math.inf
    return max(
        [0.0]
        + [
            max(abs(a[0] - b[0]), float(np.max(np.abs(a[1] - b[1]))))
            for a, b in zip(run, ref, strict=True)
            if a[1] is not None and b[1] is not None
        ]
    )


def drake_configs(quick: bool) -> list[tuple]:
    accs = (1e-4, 1e-6, 1e-8) if quick else (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    configs = [("runge_kutta3", 0.1, a, False) for a in accs]
    # The same largest step as legsim's longest (``robots.LARGEST_STEPS``) where it may bind.
    configs += [("runge_kutta3", 0.2, a, False) for a in accs if a >= 1e-6]
    configs += [("runge_kutta3", h, 0.1, True) for h in (0.03, 0.015, 0.0075, 0.004)]
    configs += [("runge_kutta5", h, 0.1, True) for h in (0.08, 0.04, 0.02, 0.01)]
    return configs


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--drake-site", required=True, help="site-packages of the venv where drake is installed")
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (default 2)")
    parser.add_argument("--quick", action="store_true", help="fewer configurations, 10 s instead of 40 s")
    args = parser.parse_args()
    sys.path.append(args.drake_site)
    from legsim.bench import robots

    for name in ("compass-gait", "rimless-wheel"):
        t_final = 10.0 if args.quick else 40.0
        # The state at the end of the first step after the last impact of 30 s from the example's start.
        x0 = _after_last_impact(name)
        _, ref = drake_run(name, x0, t_final, ("runge_kutta3", 0.01, 1e-12, False), True)
        case = robots.make_robot_case(name, quick=args.quick)
        t_final = case.t_final
        specs = [s for s in robots.sweep(args.quick) if s.kind == "relaxed"]
        configs = drake_configs(args.quick)
        d_err = [impact_error(drake_run(name, x0, t_final, c, True)[1], ref) for c in configs]
        ratios: dict[float, list[float]] = {lv: [] for lv in LEVELS}
        for rnd in range(args.rounds):
            d_time, l_rows = [], []
            for i in range(max(len(configs), len(specs))):  # alternate: one Drake config, one legsim run
                if i < len(configs):
                    d_time.append(min(drake_run(name, x0, t_final, configs[i], False)[0] for _ in range(3)))
                if i < len(specs):
                    l_rows.append(robots.run_one(case, specs[i], 3))
            for lv in LEVELS:
                d_best = min([t for t, e in zip(d_time, d_err, strict=True) if e <= lv], default=math.inf)
                l_best = min([r.wall_s for r in l_rows if r.error <= lv], default=math.inf)
                ratios[lv].append(d_best / l_best if math.isfinite(l_best) else math.nan)
                cfg = next((c for c, t, e in zip(configs, d_time, d_err, strict=True) if t == d_best and e <= lv), None)
                row = next((r for r in l_rows if r.wall_s == l_best), None)
                print(
                    f"{name} round {rnd + 1} error <= {lv:g}: Drake {cfg} {1e3 * d_best:.3g} ms; legsim "
                    f"{row.method if row else None} tol={row.tol if row else None} h={row.h if row else None} "
                    f"{1e3 * l_best:.3g} ms"
                )
        for lv in LEVELS:
            print(
                f"{name} error <= {lv:g}: Drake / legsim median {statistics.median(ratios[lv]):.3g} "
                f"(rounds {', '.join(f'{r:.3g}' for r in ratios[lv])})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
