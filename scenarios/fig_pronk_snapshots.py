"""Paper 000 Fig. 17: snapshots of the pronking runner at its discrete transition times.

Top: the pronk from (x, z, theta, xd, zd, thetad) = (0, 1.1, 0, 3.4, 0, 0), where both legs
touch down and lift off together (scene ``pronk_paper``). Bottom: the same with theta0 = -0.4
(scene ``pronk_pitched_paper``), where the legs touch down one after the other. Parameters
(m, I, k, l, d, g, psi) = (1, 1, 30, 1, 1, 9.81, pi/5), RK4 with h = 1e-3 and the paper's
coarse eps = 1e-2 (whose strip holds delay the runs; ``pronk`` and ``pronk_pitched`` are the
converged runs).

Each snapshot draws the robot at the guard point q of a transition (the strip entry), in the
mode it leaves, coloured by time; transitions less than 30 ms apart (a simultaneous
touchdown crosses its second guard within the first one's strip) share one label. The dashed
line is the centre of mass.

Writes ``<out>/fig_pronk_snapshots.png``, ``<out>/pronk_paper.rrd`` and ``<out>/pronk_pitched_paper.rrd``.
Run: ``.venv/bin/python scenarios/fig_pronk_snapshots.py [out]``
"""

from __future__ import annotations

import numpy as np
from legsim.viz._figures import (
    draw_parts,
    draw_scenery,
    finish,
    group_shots,
    new_figure,
    parse_out,
    run_scene,
    snapshot_times,
)

SCENES = [
    ("pronk_paper", r"$\theta_0 = 0$: both legs touch down and lift off together"),
    ("pronk_pitched_paper", r"$\theta_0 = -0.4$: the left leg touches down first"),
]
GROUP_WITHIN = 0.03  # s


def main(argv=None) -> int:
    from matplotlib import colormaps

    out = parse_out(__doc__.splitlines()[0], argv)
    fig = new_figure(11.0, 7.5)
    axes = fig.subplots(len(SCENES), 1)
    cmap = colormaps["viridis"]
    rrds = []
    for ax, (name, caption) in zip(axes, SCENES, strict=True):
        scene, ex, rrd = run_scene(name, out)
        rrds.append(rrd)
        model = scene.model
        span = max(ex.t_end - ex.t0, 1e-12)
        xs = []
        for k, group in enumerate(group_shots(snapshot_times(ex), GROUP_WITHIN)):
            for t, mode, state, _ in group:
                colour = cmap(0.9 * (t - ex.t0) / span)
                parts = model.geometry(mode, np.asarray(state, dtype=float))
                draw_parts(ax, parts, colour, lw=2.2, point_size=25)
            pts = np.concatenate([np.asarray(p).reshape(-1, 2) for p in parts.values()])
            xs.extend([pts[:, 0].min(), pts[:, 0].max()])
            transitions = (
                [group[0][3].split(" → ")[0]] + [g[3].split(" → ")[-1] for g in group]
                if group[0][3].find("→") >= 0
                else [group[0][3]]
            )
            label = f"{group[0][0]:.3f} s\n" + " → ".join(dict.fromkeys(transitions))
            # Alternate label heights so that neighbouring snapshots do not overwrite each other.
            ax.annotate(
                label,
                (float(pts[:, 0].mean()), float(pts[:, 1].max())),
                textcoords="offset points",
                xytext=(0, 6 + 22 * (k % 2)),
                ha="center",
                fontsize=7,
                color=colour,
            )
        samples = ex.sample(np.linspace(ex.t0, ex.t_end, 400))
        com = np.array(
            [
                model.geometry(m, s).get("com", np.full((1, 2), np.nan))[0]
                for m, s in zip(samples.modes, samples.states, strict=True)
            ]
        )
        ax.plot(com[:, 0], com[:, 1], "--", color="0.5", lw=0.8, zorder=0)
        draw_scenery(ax, model.scenery)
        ax.set_xlim(min(xs) - 0.3, max(xs) + 0.3)
        ax.set_ylim(-0.1, 1.85)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
        ax.set_title(f"{caption}   ({len(ex.transitions)} transitions in {ex.t_end:g} s)", fontsize=10)
        print(
            f"{name}: {len(ex.transitions)} transitions at t = "
            + ", ".join(f"{tr.time:.4f} ({tr.source}->{tr.target})" for tr in ex.transitions)
        )
    finish(fig, out / "fig_pronk_snapshots.png", rrds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
