"""Paper 003 Fig. 2b and 2c: the double pendulum with a mechanical stop, plastic and Zeno.

(b) plastic impact, c = 0 (scene ``double_pendulum_plastic_paper``): after an impact the
second link stays on the stop (mode ``constrained``) until the constraint force of eq. (31)
changes sign; (c) restitution c = 0.5 (scene ``double_pendulum_zeno_paper``, the paper's
relaxed execution without continuation): the impacts accumulate (Zeno) and the strips pile up.
Both start at (theta1, theta2, theta1d, theta2d) = (30 deg, 25 deg, 0, 0) and use the paper's
coarse setting, Euler with h = 0.001 s and eps = 0.2 (rad, N m for the release guard), which
shows the strips; the scenes without ``_paper`` are the converged runs. As in the paper,
vertical gray bars show when the simulation is inside a strip; the band below each column
shows the mode of each segment.

Writes ``<out>/fig_double_pendulum.png``, ``<out>/double_pendulum_plastic_paper.rrd`` and
``<out>/double_pendulum_zeno_paper.rrd``.
Run: ``.venv/bin/python scenarios/fig_double_pendulum.py [out]``
"""

from __future__ import annotations

from legsim.viz._figures import finish, new_figure, parse_out, run_scene, state_panels

# (scene, caption): Fig. 2c shows the paper's relaxed execution; its scene turns off the
# continuation legsim takes by default where the impacts accumulate.
SCENES = [
    ("double_pendulum_plastic_paper", "(b) plastic impact, c = 0"),
    ("double_pendulum_zeno_paper", "(c) Zeno, c = 0.5"),
]
COORDINATES = ["theta1", "theta2", "theta1d", "theta2d"]
UNITS = {"theta1": "rad", "theta2": "rad", "theta1d": "rad/s", "theta2d": "rad/s"}


def main(argv=None) -> int:
    out = parse_out(__doc__.splitlines()[0], argv)
    fig = new_figure(12.0, 8.0)
    grid = fig.add_gridspec(1, len(SCENES))
    rrds = []
    for column, (name, caption) in zip(grid, SCENES, strict=True):
        _scene, ex, rrd = run_scene(name, out)
        rrds.append(rrd)
        strip_time = sum(b - a for a, b in ex.strip_intervals())
        title = f"{caption}\n{len(ex.transitions)} transitions, {strip_time:.2f} s of {ex.t_end:g} s in strips"
        state_panels(fig, column, ex, COORDINATES, title, UNITS)
        print(
            f"{name}: {len(ex.transitions)} transitions, modes {' -> '.join(ex.mode_sequence[:8])}"
            f"{' ...' if len(ex.mode_sequence) > 8 else ''}; strip time {strip_time:.3f} s; "
            f"first impact at t = {ex.transitions[0].time:.4f} s"
            if ex.transitions
            else f"{name}: no transition"
        )
    finish(fig, out / "fig_double_pendulum.png", rrds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
