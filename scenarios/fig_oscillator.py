"""Paper 000 Fig. 14b and 14c: the forced linear oscillator with a stop, Table I Examples 1, 2.

Each panel shows the position of the analytical solution (solid; ``model.reference``, the
closed form of eq. (28) with impacts, sticking and releases), the position of the stop
(dotted), and the relaxed simulation of the scene (dashed; the scene's method, h and eps), with
the largest position error over the simulated points, rho-hat of eq. (30).

(b) Example 1 (scene ``oscillator_ex1``): a = 0.05, c = 0.9, u = 20 cos(2.5 t), x0 = 11.36,
xd0 = 31.4, x_max = 14, omega = 2.5, t_max = 40 pi. (c) Example 2 (``oscillator_ex2``):
a = 0.95, c = 0.5, u = cos t, x0 = -0.8, xd0 = 0, x_max = -0.8, omega = 1, t_max = 4 pi.

Writes ``<out>/fig_oscillator.png``, ``<out>/oscillator_ex1.rrd`` and ``<out>/oscillator_ex2.rrd``.
Run: ``.venv/bin/python scenarios/fig_oscillator.py [out]``
"""

from __future__ import annotations

import numpy as np
from legsim.viz._figures import finish, new_figure, parse_out, run_scene

SCENES = [("oscillator_ex1", "(b) Example 1"), ("oscillator_ex2", "(c) Example 2")]


def main(argv=None) -> int:
    out = parse_out(__doc__.splitlines()[0], argv)
    fig = new_figure(12.0, 4.6)
    axes = fig.subplots(1, len(SCENES))
    rrds = []
    for ax, (name, caption) in zip(axes, SCENES, strict=True):
        scene, ex, rrd = run_scene(name, out)
        rrds.append(rrd)
        reference = scene.model.reference
        x_max = scene.effects["stop"]["position"]
        t_fine = np.linspace(ex.t0, ex.t_end, 6000)
        if reference is not None:
            ax.plot(t_fine, reference.position(t_fine), color="k", lw=1.0, label="analytical solution")
        ax.axhline(x_max, color="0.3", ls=":", lw=1.2, label="stop")
        # The computed points (not the held strip points): the samples of rho-hat, eq. (30).
        t_sim = np.concatenate([s.t for s in ex.segments])
        x_sim = np.concatenate([s.x[:, 0] for s in ex.segments])
        s = scene.integrator
        ax.plot(t_sim, x_sim, "--", color="tab:orange", lw=0.9, label=f"relaxed {s['method'].upper()}, h = {s['h']:g}")
        note = ""
        if reference is not None:
            rho_hat = float(np.max(np.abs(x_sim - reference.position(t_sim))))
            note = f", rho-hat = {rho_hat:.2e} m"
            print(
                f"{name}: {len(ex.transitions)} transitions, rho-hat (max |x_sim - x_exact| over "
                f"{len(t_sim)} points) = {rho_hat:.3e} m"
            )
        ax.set_xlim(ex.t0, ex.t_end)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("x (m)")
        ax.set_title(f"{caption}: {len(ex.transitions)} impacts{note}", fontsize=10)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, fontsize="small", frameon=False)
    finish(fig, out / "fig_oscillator.png", rrds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
