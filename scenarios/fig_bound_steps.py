"""The planar quadruped bounding over steps: fell / ran per step height (scene ``quadruped_bound_steps``).

A ``legsim sweep`` over ``terrain.rise`` (each of the 5 treads this much above the one before;
negative: steps down) runs the bound commanded 0.5 m/s for the scene's 10 s and writes per cell
the run's status: ``finished`` (ran), ``fell`` (a fall: |pitch| reaching 1 rad, the scene's
``[fall]``, or the body meeting a riser or a tread, its ``below_ground = "fall"``) or another
status where the simulation itself could not go on (the cell says which). A finished run that
carries warnings (a chatter against a riser the method reports as an accumulation: past it the
result is not the hybrid system's) is drawn hollow. Each cell is drawn at its rise, coloured by
its status, with the time the run reached; the achieved mean speed over [4 s, t_end]
(``--measure mean_rate:x:4``) is plotted above. The table stays in
``<out>/bound_steps/results.parquet`` (a second call resumes it). Writes
``<out>/fig_bound_steps.png``.
Run: ``.venv/bin/python scenarios/fig_bound_steps.py [out]``
"""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
from legsim.viz._figures import finish, new_figure, parse_out

import legsim

RISES = [round(float(v), 3) for v in np.linspace(-0.1, 0.1, 21)]  # m
SETTLE = 4.0  # s
COLOURS = {"finished": "tab:green", "fell": "tab:red"}
OTHER = "0.3"  # any other status: the run could not go on


def sweep(out):
    folder = out / "bound_steps"
    legsim.sweep(
        "quadruped_bound_steps",
        grid={"terrain.rise": RISES},
        measures=[f"mean_rate:x:{SETTLE}"],
        out=folder,
        resume=(folder / "sweep.json").exists(),
        workers=2,
    )
    return pq.read_table(folder / "results.parquet").to_pylist()


def main(argv=None) -> int:
    out = parse_out(__doc__.splitlines()[0], argv)
    rows = sweep(out)
    fig = new_figure(10.0, 4.8)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[1.0, 1.2])
    statuses = sorted({r["status"] for r in rows}, key=lambda s: (s not in COLOURS, s))
    others = [s for s in statuses if s not in COLOURS]
    markers = dict(zip(others, "sXD^v", strict=False))  # filled shapes: a hollow one must show its edge
    for r in rows:
        rise, status = r["terrain.rise"], r["status"]
        colour = COLOURS.get(status, OTHER)
        warned = bool(r.get("warnings"))
        face = "none" if warned else colour
        marker = markers.get(status, "o")
        bottom.scatter([rise], [r["t_end"]], edgecolors=colour, facecolors=face, marker=marker, s=50, zorder=3)
        if r["mean_rate_x"] is not None:
            top.scatter([rise], [r["mean_rate_x"]], edgecolors=colour, facecolors=face, marker=marker, s=30)
        print(
            f"rise {rise:+.3f} m: {status}{' (warnings)' if warned else ''}, t_end {r['t_end']:.3f} s, "
            f"fell {r['fell']}, mean speed over [{SETTLE:g} s, t_end] {r['mean_rate_x']}; {(r['message'] or '')[:60]}"
        )
    for status in statuses:
        bottom.scatter([], [], color=COLOURS.get(status, OTHER), marker=markers.get(status, "o"), label=status)
    bottom.scatter([], [], edgecolors="0.3", facecolors="none", marker="o", label="with warnings")
    top.axhline(0.5, color="0.5", ls=":", lw=1.0)
    top.set_ylabel("mean speed (m/s)")
    top.set_title("quadruped_bound_steps: bound at 0.5 m/s over 5 steps of equal rise", fontsize=10)
    bottom.set_ylabel("time reached (s)")
    bottom.set_xlabel("terrain.rise: step height (m; < 0 steps down)")
    bottom.set_ylim(0.0, 10.5)
    bottom.legend(loc="lower left", fontsize="small", ncol=len(statuses) + 1)
    finish(fig, out / "fig_bound_steps.png", [])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
