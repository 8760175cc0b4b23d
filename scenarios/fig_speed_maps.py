"""Speed maps of the planar quadruped's gaits: commanded speed x foot-placement gain.

For each gait (scenes ``quadruped_pronk_forward``, ``quadruped_bound_forward`` (the bound with two
flights a stride), ``quadruped_bound_one_flight`` (one flight a stride) and ``quadruped_gallop``) a
``legsim sweep`` over ``controller.parameters.speed`` and ``controller.parameters.k_x`` runs every
cell for ``T_FINAL`` s and writes per cell the achieved mean speed over [``SETTLE``, t_end]
(``--measure mean_rate:x:SETTLE``), the largest |pitch| (``max_abs:pitch``), the run's status
(``fell`` when a condition of the scene's ``[fall]`` held) and an orbit search (``--orbit``): its
status, and the largest Floquet multiplier where it found an orbit. The bounds' and the gallop's
searches start from the last apex of each cell's run (``--orbit-guess run``); the pronk's from its
scene's guess, the one-hop orbit at 1.0 m/s (``--orbit-guess scene``): that orbit is a flip, and
the runs settle on a two-hop gait, whose apexes are no guess for it. A cell is drawn

* red: the run fell (status ``fell`` or ``model_breakdown``); black: the run failed otherwise;
* purple: it finished with warnings (an accumulation: past it the relaxed execution holds the
  state in the strip, so the run is not one the method vouches for as a gait);
* green / orange: it ran and the orbit search found a stable / unstable orbit;
* grey: it ran and the search found no orbit: no multiplier, the search's status written in it.

Each cell is annotated with its achieved speed (m/s) and the orbit's status or spectral radius.
The sweeps' tables stay in ``<out>/speed_map_<scene>/results.parquet`` (a second call resumes
them). Writes ``<out>/fig_speed_maps.png``.
Run: ``.venv/bin/python scenarios/fig_speed_maps.py [out]``
"""

from __future__ import annotations

import pyarrow.parquet as pq
from legsim.viz._figures import finish, new_figure, parse_out

import legsim

#: Each map's scene, by the gait it runs.
GAITS = {
    "pronk": "quadruped_pronk_forward",
    "bound, two flights": "quadruped_bound_forward",
    "bound, one flight": "quadruped_bound_one_flight",
    "gallop": "quadruped_gallop",
}
SPEEDS = [0.5, 0.75, 1.0]  # m/s (commanded)
GAINS = [0.03, 0.06, 0.12]  # s (k_x: foot placement per m/s of speed error)
T_FINAL = 8.0  # s
SETTLE = 4.0  # s: the achieved speed is the mean over [SETTLE, t_end]
#: The orbit problem of each gait is its scene's ``[orbit]`` section (a flight apex of the body,
#: x cyclic, the memory entries each gait keeps unchanged held fixed); the maps search it to a
#: looser tolerance, from each cell's own run.
ORBIT_SETTINGS = ["orbit.t_max=2.0", "orbit.tol=1e-6", "orbit.max_iterations=10"]
#: Wall time (s) a cell's run and search may take: past it the row says ``timeout`` (the
#: bound's cell at 0.5 m/s and k_x 0.12 s searched on for over 10 min).
TIMEOUT = 300.0
#: Where each gait's searches start (module docstring).
ORBIT_GUESS = {"pronk": "scene", "bound, two flights": "run", "bound, one flight": "run", "gallop": "run"}
COLOURS = {
    "stable": "tab:green",
    "unstable": "tab:orange",
    "no orbit": "0.75",
    "warnings": "tab:purple",
    "fell": "tab:red",
    "failed": "k",
}


def sweep_gait(gait: str, out):
    """The sweep of one gait (resumed when its folder holds it), as a pyarrow table."""
    scene = GAITS[gait]
    folder = out / f"speed_map_{scene}"
    legsim.sweep(
        scene,
        grid={"controller.parameters.speed": SPEEDS, "controller.parameters.k_x": GAINS},
        overrides=[f"integrator.t_final={T_FINAL}", *ORBIT_SETTINGS],
        measures=[f"mean_rate:x:{SETTLE}", f"max_abs:pitch:{SETTLE}"],
        orbit=True,
        orbit_guess=ORBIT_GUESS[gait],
        out=folder,
        resume=(folder / "sweep.json").exists(),
        workers=2,
        timeout=TIMEOUT,
        figures=False,
    )
    return pq.read_table(folder / "results.parquet")


def verdict(row: dict) -> str:
    """The cell's colour key: fell, failed, warnings, stable, unstable or no orbit."""
    if row["fell"]:
        return "fell"
    if row["task_status"] != "done" or row["status"] != "finished":
        return "failed"
    if row.get("warnings"):
        return "warnings"
    if row["orbit_status"] == "converged" and row["orbit_stable"] is not None:
        return "stable" if row["orbit_stable"] else "unstable"
    return "no orbit"


def draw(ax, gait: str, rows: list[dict]) -> None:
    for row in rows:
        i = SPEEDS.index(row["controller.parameters.speed"])
        j = GAINS.index(row["controller.parameters.k_x"])
        key = verdict(row)
        ax.add_patch(_cell(i, j, COLOURS[key]))
        speed = row["mean_rate_x"]
        orbit = (
            f"rho {row['orbit_spectral_radius']:.4g}"
            if row["orbit_spectral_radius"] is not None
            else str(row["orbit_status"] or row["status"])
        )
        text = f"{speed:.3f} m/s\n{orbit}" if speed is not None else f"{row['status']}\n{orbit}"
        if key == "warnings":
            text += "\nwarnings"
        light = key in ("failed", "fell", "warnings")
        ax.text(i, j, text, ha="center", va="center", fontsize=7, color="w" if light else "k")
        pitch = row["max_abs_pitch"]
        print(
            f"{gait}: speed {row['controller.parameters.speed']:g} k_x {row['controller.parameters.k_x']:g}: "
            f"{row['status']}, achieved {speed if speed is None else round(speed, 4)} m/s, "
            f"max |pitch| {pitch if pitch is None else round(pitch, 3)} rad, "
            f"orbit {row['orbit_status']}, spectral radius {row['orbit_spectral_radius']}"
            f"{', with warnings' if row.get('warnings') else ''}"
        )
    ax.set_xticks(range(len(SPEEDS)), [f"{v:g}" for v in SPEEDS])
    ax.set_yticks(range(len(GAINS)), [f"{v:g}" for v in GAINS])
    ax.set_xlim(-0.5, len(SPEEDS) - 0.5)
    ax.set_ylim(-0.5, len(GAINS) - 0.5)
    ax.set_xlabel("commanded speed (m/s)")
    ax.set_ylabel("foot placement gain k_x (s)")
    ax.set_title(f"{gait}: {GAITS[gait]}", fontsize=10)


def _cell(i: int, j: int, colour):
    from matplotlib.patches import Rectangle

    return Rectangle((i - 0.5, j - 0.5), 1.0, 1.0, facecolor=colour, edgecolor="w", lw=2.0)


def main(argv=None) -> int:
    out = parse_out(__doc__.splitlines()[0], argv)
    fig = new_figure(10.0, 8.8)
    axes = fig.subplots(2, 2).ravel()
    for ax, gait in zip(axes, GAITS, strict=True):
        table = sweep_gait(gait, out)
        draw(ax, gait, table.to_pylist())
    from matplotlib.patches import Patch

    handles = [Patch(facecolor=c, label=k) for k, c in COLOURS.items()]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(COLOURS), frameon=False, fontsize="small")
    finish(fig, out / "fig_speed_maps.png", [])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
