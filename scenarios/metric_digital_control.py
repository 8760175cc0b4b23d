"""Paper 000 Section V-A: the quotient metric against a trajectory-space metric, digital control.

For each delta, y_delta and z_delta start at the nominal state (-1, -1) shifted by (-delta, 0)
and (0, -delta); they cross the two thresholds in opposite orders (modes 0 -> 2 -> 3 and
0 -> 1 -> 3). The script computes, over t in [0, 2] s,

* rho (eps = 0) between the exact executions, and rho^eps between relaxed simulations
  (RK4, h = eps = 1e-4): both fall linearly with delta;
* the trajectory-space distance sup_t |y - z| + [mode_y != mode_z], which stays >= 1,

prints a table, and writes a log-log figure to ``<out>/metric_digital_control.png``.

With ``--oscillator`` it also prints the convergence of rho^eps for the forced oscillator with a
stop (paper 000 Table I) against its exact reference, in eps and in h (the numbers of
docs/metric.md).

Run: ``.venv/bin/python scenarios/metric_digital_control.py [--out out] [--deltas 7] [--oscillator]``
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

import numpy as np

from legsim import simulate
from legsim.metric import distances, trajectory_space_distance
from legsim.output.files import cannot_create_in, write_atomic
from legsim.systems import digital_control as dc

T_END = 2.0
EPS = H = 1e-4


def sweep(deltas: np.ndarray) -> dict[str, np.ndarray]:
    """rho (exact), rho^eps (simulated) and the trajectory-space distance for each delta."""
    system = dc.make_system()
    x0 = dc.nominal_initial_state()
    out = {"delta": deltas, "rho": [], "rho_window": [], "rho_eps": [], "trajectory": []}
    for delta in deltas:
        y = dc.make_reference(x0 + np.array([-delta, 0.0]))
        z = dc.make_reference(x0 + np.array([0.0, -delta]))
        events = np.array(y.transition_times + z.transition_times)
        times = np.union1d(np.linspace(0.0, T_END, 401), np.linspace(events.min() - delta, events.max() + delta, 201))
        d = distances(system, y, z, times, 0.0)
        mismatch = np.array(y.modes(times)) != np.array(z.modes(times))
        out["rho"].append(d.max())
        out["rho_window"].append(d[mismatch].max())
        out["trajectory"].append(trajectory_space_distance(y, z, times))
        ys = simulate(system, x0 + np.array([-delta, 0.0]), "0", T_END, H, EPS)
        zs = simulate(system, x0 + np.array([0.0, -delta]), "0", T_END, H, EPS)
        out["rho_eps"].append(distances(system, ys, zs, times, EPS).max())
    return {k: np.asarray(v) for k, v in out.items()}


def plot(result: dict[str, np.ndarray], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    d = result["delta"]
    ax.loglog(d, result["trajectory"], "s-", label="trajectory space: sup |y - z| + [modes differ]")
    ax.loglog(d, result["rho"], "o-", label=r"$\rho$ (quotient metric, exact executions)")
    ax.loglog(d, result["rho_window"], "^--", label=r"sup over the mode-mismatch window")
    ax.loglog(d, result["rho_eps"], "x:", label=rf"$\rho^\varepsilon$ (relaxed sims, h = $\varepsilon$ = {EPS:g})")
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_xlabel(r"offset $\delta$")
    ax.set_ylabel("distance between $y_\\delta$ and $z_\\delta$")
    ax.set_title("Digital control (paper 000, Sec. V-A)")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120), what="figure")
    finally:
        plt.close(fig)


def oscillator_table() -> None:
    """rho^eps and eq. (30) for Table I against the exact reference: in eps (RK4, mean over three
    step sizes, i.e. three landing phases) and in h (the paper's midpoint method, rk2)."""
    import math

    from legsim.metric import position_error, rho
    from legsim.systems import oscillator as osc

    for name, t_end in (("ex1", 10.0), ("ex2", 4 * math.pi)):
        ex = osc.EXAMPLES[name]
        system = osc.make_system(omega=ex["omega"], a=ex["a"], x_max=ex["x_max"], c=ex["c"], mass=ex["mass"])
        ref = osc.OscillatorReference.example(name)
        control = osc.forcing(ex["amplitude"], ex["frequency"])
        times = np.linspace(0.0, t_end, 2001)

        # run(h, eps, method): the paper's relaxed execution (no Zeno continuation), whose modes
        # are the reference's, so that rho compares like with like
        run = partial(
            simulate,
            system,
            [ex["x0"], ex["xd0"]],
            "free",
            t_end,
            control=control,
            max_transitions=10**6,
            continuation=False,
        )

        print(f"{name} (t in [0, {t_end:.4g}] s, 2001 samples)")
        epsilons, means = [1e-2, 1e-3, 1e-4, 1e-5], []
        for eps in epsilons:
            means.append(np.mean([rho(system, run(h, eps, "rk4"), ref, times, eps) for h in (1e-2, 7.7e-3, 6.1e-3)]))
            print(
                f"  rk4 eps={eps:.0e}: mean rho^eps over h = 1e-2, 7.7e-3, 6.1e-3: {means[-1]:.3g} "
                f"(rho/eps {means[-1] / eps:.0f})"
            )
        print(f"  slope in eps: {np.polyfit(np.log(epsilons), np.log(means), 1)[0]:.3f}")
        steps, values, positions = [1e-2, 5e-3, 2.5e-3], [], []
        for h in steps:
            sim = run(h, 1e-8, "rk2")
            values.append(rho(system, sim, ref, times, 1e-8))
            positions.append(position_error(sim, ref, times))
            print(f"  rk2 h={h:g} eps=1e-8: rho^eps {values[-1]:.3g}, position error (30) {positions[-1]:.3g}")
        print(
            f"  slope in h: rho {np.polyfit(np.log(steps), np.log(values), 1)[0]:.3f}, "
            f"position error {np.polyfit(np.log(steps), np.log(positions), 1)[0]:.3f}"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out", help="output folder (default: out)")
    parser.add_argument("--deltas", type=int, default=7, help="number of offsets in [1e-4, 1e-1] (default: 7)")
    parser.add_argument(
        "--oscillator", action="store_true", help="also print rho^eps against eps and h for the oscillator of Table I"
    )
    args = parser.parse_args(argv)
    if not 2 <= args.deltas <= 50:
        parser.error("--deltas must be between 2 (a slope needs two points) and 50")
    out = Path(args.out)
    # Check the output folder before the sweep (seconds of work), not after it.
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        parser.error(f"--out {out}: cannot create the folder: {exc.strerror or exc}")
    reason = cannot_create_in(out)
    if reason is not None:
        parser.error(f"--out {out}: cannot write in the folder: {reason}")
    result = sweep(np.logspace(-1, -4, args.deltas))
    print(f"{'delta':>10} {'rho':>12} {'rho window':>12} {'rho^eps':>12} {'trajectory':>11}")
    for i, delta in enumerate(result["delta"]):
        print(
            f"{delta:10.3g} {result['rho'][i]:12.5g} {result['rho_window'][i]:12.5g} "
            f"{result['rho_eps'][i]:12.5g} {result['trajectory'][i]:11.5g}"
        )
    log_d = np.log(result["delta"])
    print(
        f"slope of log rho vs log delta: {np.polyfit(log_d, np.log(result['rho']), 1)[0]:.4f}; "
        f"in the mismatch window: {np.polyfit(log_d, np.log(result['rho_window']), 1)[0]:.4f}"
    )
    print(f"min trajectory-space distance: {result['trajectory'].min():.6f}")
    path = plot(result, out / "metric_digital_control.png")
    print(f"wrote {path}")
    if args.oscillator:
        oscillator_table()
    return 0


if __name__ == "__main__":
    sys.exit(main())
