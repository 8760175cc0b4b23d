"""``legsim orbit SCENE``: find a periodic orbit (a gait) of a scene, or follow a family of them.

The problem is the scene's ``[orbit]`` section (``legsim.scene.orbit.ORBIT_KEYS``): the Poincare
section, fixed and cyclic coordinates, free parameters, tolerances; the initial guess is the
scene's ``[initial]`` state. ``--continue PARAM FROM TO`` follows the family of orbits as the
real parameter PARAM (a robot parameter, or EFFECT.PARAM) goes from FROM to TO, prints a table
with the stability changes and, with ``--plot FILE``, draws it.

Exit codes: 0 when the orbit (every orbit of the family) was found; 3 when the search stopped
without an orbit (the message says why: no return, singular Jacobian, divergence, ...); 2 for
errors in the scene or the arguments. Long simulations draw a progress bar on a terminal's
stderr (not with --quiet).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import LegsimError, OutputError

if TYPE_CHECKING:
    from ..orbits import Family, FamilyPoint, OrbitProblem

#: Most parameter steps of ``--continue`` (one orbit search each) and bisections of ``--locate``
#: (beyond ~50 the parameter interval is below double precision).
MAX_CONTINUATION_STEPS = 10_000
MAX_LOCATE = 50

NAME = "orbit"
HELP = "find a periodic orbit (gait) of a scene from its [orbit] section, or follow a family (--continue)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "scene", metavar="SCENE", help="scene file (.toml) or bundled scene name with an [orbit] section"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a scene field, e.g. --set robot.parameters.slope=4 --set orbit.tol=1e-8",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--continue",
        dest="continuation",
        nargs=3,
        metavar=("PARAM", "FROM", "TO"),
        help="follow the family of orbits as PARAM goes from FROM to TO",
    )
    parser.add_argument(
        "--steps", type=int, metavar="N", help="number of equal parameter steps of --continue (default 10)"
    )
    parser.add_argument(
        "--locate",
        type=int,
        metavar="K",
        help="with --continue: narrow each stability change by K bisections of the parameter "
        "(default 8; 0 interpolates between the family's orbits)",
    )
    parser.add_argument("--plot", metavar="FILE", help="with --continue: plot the family (png, pdf, svg)")
    parser.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors; no progress bar")


def run(args: argparse.Namespace) -> int:
    from ..progress import progress_for
    from ..scene import load_scene

    _check_family_options(args)
    scene = load_scene(args.scene, overrides=args.overrides)
    plot_path = _check_plot_path(args.plot) if args.plot else None
    bar = progress_for(sys.stderr, enabled=not args.quiet, label=scene.name)
    try:
        return _run(args, scene, plot_path, bar)
    finally:
        if bar is not None:
            bar.close()


#: The options that shape a family (``--continue``), each with what it does; without
#: ``--continue`` each is refused rather than ignored. Their defaults apply with ``--continue``.
FAMILY_OPTIONS: dict[str, tuple[str, str, int | None]] = {
    "plot": ("--plot", "draws a family", None),
    "steps": ("--steps", "sets the family's parameter steps", 10),
    "locate": ("--locate", "narrows the family's stability changes", 8),
}


def _check_family_options(args: argparse.Namespace) -> None:
    """Refuse a family option without ``--continue``; with it, fill in the defaults and check
    the ranges (before the scene loads: a bad value should not wait for it)."""
    for dest, (flag, what, default) in FAMILY_OPTIONS.items():
        if getattr(args, dest) is None:
            setattr(args, dest, default)
        elif not args.continuation:
            raise LegsimError(f"{flag} {what}: use it with --continue PARAM FROM TO")
    if not args.continuation:
        return
    if not 1 <= args.steps <= MAX_CONTINUATION_STEPS:
        raise LegsimError(f"--steps must be in [1, {MAX_CONTINUATION_STEPS}], got {args.steps}")
    if not 0 <= args.locate <= MAX_LOCATE:
        raise LegsimError(f"--locate must be in [0, {MAX_LOCATE}], got {args.locate}")


def _run(args: argparse.Namespace, scene, plot_path: Path | None, bar) -> int:
    if args.continuation:
        return _run_family(args, scene, plot_path, bar)
    return _run_orbit(args, scene, bar)


def _run_orbit(args: argparse.Namespace, scene, bar) -> int:
    """One orbit search: its report, and exit code 3 when no orbit was found."""
    from ..orbits import find_orbit
    from ..scene.orbit import problem_from_scene, shadowed_integrator_keys

    settings = problem_from_scene(scene)
    _say_shadowed(shadowed_integrator_keys(scene, args.overrides or []))
    settings.problem.progress = bar
    result = find_orbit(settings.problem, settings.guess, **settings.solver)
    if bar is not None:
        bar.close()
    payload = result.to_json()
    payload["scene"] = scene.name
    payload["integrator"] = settings.problem.integrator_settings
    if args.json:
        print(json.dumps(payload, allow_nan=False))
    elif not args.quiet:
        print(format_orbit(payload, scene.name))
    if not result.converged:
        print(f"legsim: no orbit ({result.status}): {result.message}", file=sys.stderr)
        return 3
    return 0


def _say_shadowed(shadowed: dict[str, Any]) -> None:
    """A note on stderr for each ``--set integrator.KEY`` the scene's ``[orbit.integrator]``
    overrides for the search ({KEY: the search's value}): it sets the runs, not the search."""
    for key, value in shadowed.items():
        print(
            f"legsim: note: --set integrator.{key} sets the scene's runs, not this search: its "
            f"[orbit.integrator] gives {key} = {value!r}; use --set orbit.integrator.{key}=... to change it",
            file=sys.stderr,
        )


def _run_family(args: argparse.Namespace, scene, plot_path: Path | None, bar) -> int:
    """``--continue``: the family's table (or JSON), its plot, exit code 3 when incomplete."""
    from ..orbits import continue_family

    param = args.continuation[0]
    settings, start, stop = _continuation_settings(scene, args.continuation)
    settings.problem.progress = bar

    def progress(point: FamilyPoint) -> None:
        if bar is not None:
            bar.close()
        if not (args.json or args.quiet):
            print(format_row(param, point.value, point.result.to_json(), widths), flush=True)

    widths = None
    if not (args.json or args.quiet):
        header, widths = format_header(param, settings.problem)
        print(f"{scene.name}: family of orbits over {param} from {start:g} to {stop:g} ({args.steps} steps)")
        print(f"integrator: {settings.problem.integrator_label}")
        print(header)
    family = continue_family(
        settings.problem,
        param,
        start,
        stop,
        args.steps,
        settings.guess,
        progress=progress,
        locate=args.locate,
        **settings.solver,
    )
    if bar is not None:
        bar.close()
    payload = family.to_json()
    payload["scene"] = scene.name
    payload["integrator"] = settings.problem.integrator_settings
    plotted = plot_path is not None and bool(family.points)
    if plot_path is not None and plotted:
        write_family_plot(family, scene.name, plot_path)
        payload["plot"] = str(plot_path)
    if args.json:
        print(json.dumps(payload, allow_nan=False))
    elif not args.quiet:
        print(format_family_end(family, param, plot_path if plotted else None))
    if not family.complete:
        print(f"legsim: the family is incomplete: {family.message}", file=sys.stderr)
        return 3
    return 0


def _continuation_settings(scene, continuation: list[str]):
    """(the scene's orbit settings with the continued parameter, FROM, TO), both ends checked
    as values of the parameter before any orbit is searched for."""
    from ..scene.orbit import problem_from_scene

    param, start_text, stop_text = continuation
    start, stop = _number("--continue FROM", start_text), _number("--continue TO", stop_text)
    if start == stop:
        raise LegsimError("--continue needs FROM != TO")
    settings = problem_from_scene(scene, extra_parameters=[param])
    if param in settings.problem.free:
        raise LegsimError(
            f"--continue {param}: '{param}' is a free parameter of the scene's [orbit] section "
            f"(solved for at each orbit); continue another parameter or drop it from orbit.free"
        )
    for label, value in (("FROM", start), ("TO", stop)):
        try:
            settings.problem.instantiate({param: value})
        except LegsimError as exc:
            raise LegsimError(f"--continue {label} = {value:g}: {exc}") from None
    return settings, start, stop


def format_family_end(family: Family, param: str, plot_path: Path | None) -> str:
    """The lines after the ``--continue`` table: stability changes, completeness, the plot."""
    lines = ["stability change: " + change.describe(param) for change in family.stability_changes]
    if not family.stability_changes:
        lines.append("stability change: none in this range")
    lines.append(("complete: " if family.complete else "incomplete: ") + family.message)
    if plot_path is not None:
        lines.append(f"wrote {plot_path} (plot)")
    return "\n".join(lines)


def _number(label: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise LegsimError(f"{label}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise LegsimError(f"{label}: must be finite, got {text!r}")
    return value


def _check_plot_path(path_text: str) -> Path:
    """The plot's path, checked before any orbit is computed: its suffix, and a folder that
    exists (or can be made) and can be written to."""
    path = Path(path_text)
    if path.suffix.lower().lstrip(".") not in ("png", "pdf", "svg"):
        raise LegsimError(f"--plot {path}: the file must end in .png, .pdf or .svg")
    if path.is_dir():
        raise LegsimError(f"--plot {path}: is a directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LegsimError(f"--plot {path}: cannot create the folder {path.parent}: {exc.strerror or exc}") from None
    try:
        # Probe with an unnamed file: permission bits say yes to root where writes still fail (/proc).
        with tempfile.TemporaryFile(dir=path.parent):
            pass
    except OSError as exc:
        raise LegsimError(f"--plot {path}: cannot write in the folder {path.parent}: {exc.strerror or exc}") from None
    return path


def _fmt(value: Any, width: int = 12) -> str:
    if value is None:
        return "-".rjust(width)
    return f"{value:.{width - 6}g}".rjust(width)


def format_orbit(payload: dict[str, Any], name: str) -> str:
    """The human-readable report of one orbit search (a ``OrbitResult.to_json()`` dict, with
    the problem's ``integrator_settings`` under ``integrator`` when known)."""
    from ..orbits.problem import describe_integrator

    lines = []
    if payload["status"] == "converged":
        lines.append(
            f"{name}: periodic orbit found in {payload['iterations']} iteration(s), residual "
            f"{payload['residual']:.3g} ({payload['jacobian']} Jacobian, "
            f"{payload['evaluations']} simulations)"
        )
    else:
        lines.append(f"{name}: no orbit ({payload['status']}): {payload['message']}")
        lines.append("last iterate:")
    if "integrator" in payload:
        lines.append(f"integrator: {describe_integrator(payload['integrator'])}")
    if payload.get("map_accuracy"):
        lines.append(_accuracy_text(payload["map_accuracy"]))
    lines.append(f"section: {payload['section']} (mode {payload['mode']})")
    memory = payload.get("memory", {})
    width = max(len(n) for n in list(payload["state_names"]) + list(payload["free"]) + list(memory))
    for n, v in zip(payload["state_names"], payload["fixed_point"], strict=False):
        lines.append(f"  {n.ljust(width)} = {v: .10g}")
    for n in payload["free"]:
        lines.append(f"  {n.ljust(width)} = {payload['parameters'][n]: .10g}  (free parameter)")
    for n, v in memory.items():
        lines.append(f"  {n.ljust(width)} = {v: .10g} {payload['memory_units'][n]}  (controller memory)")
    if payload["status"] != "converged":
        return "\n".join(lines)
    period = f"period {payload['period']:.10g} s (relaxed return time {payload['return_time']:.10g} s)"
    if payload["step_length"] is not None:
        period += f", step length {payload['step_length']:.10g} m"
    lines.append(period)
    lines.append("Floquet multipliers: " + _multipliers_text(payload["multipliers"]))
    trivial = (
        f", {payload['trivial_multipliers']} trivial multiplier(s) 1 left out" if payload["trivial_multipliers"] else ""
    )
    radius = f"spectral radius {payload['spectral_radius']:.6g}{trivial}"
    if payload.get("differentiable") is False:
        radius = f"by the piecewise-linear derivative (central differences' {radius})"
    lines.append(f"{_verdict(payload['stable'])}: {radius}")
    if payload.get("differentiable") is False:
        for side in ("forward", "backward"):
            lines.append(f"  {side}-difference multipliers: " + _multipliers_text(payload[f"multipliers_{side}"]))
    if payload.get("piecewise"):
        piecewise = payload["piecewise"]
        lines.append(f"piecewise-linear derivative: {piecewise['verdict']}: {piecewise['reason']}")
    lines.extend(f"warning: {text}" for text in payload.get("warnings", []))
    lines.append("transitions per period: " + ", ".join(payload["transitions"]))
    return "\n".join(lines)


def _accuracy_text(acc: dict[str, Any]) -> str:
    """The map accuracy line: noise, resolved residual, change at refined settings."""
    noise = "unknown" if acc["noise"] is None else f"{acc['noise']:.3g}"
    where = f" (row {acc['noisiest']})" if acc.get("noisiest") else ""
    text = (
        f"return map resolves: {acc['resolved']:.3g} (noise {noise}{where})"
        if acc["resolved"] is not None
        else (f"return map resolves: unknown (noise {noise})")
    )
    if acc["refinement"] is not None:
        text += f"; at {acc['refined']} the equations change by {acc['refinement']:.3g}"
    return text + (f"; {acc['note']}" if acc.get("note") else "")


def _multipliers_text(pairs: list[list[float]] | None) -> str:
    """Multipliers given as [re, im] pairs, each with its modulus."""
    mus = []
    for re, im in pairs or []:
        text = f"{re:.6g}" if im == 0 else f"{re:.6g}{im:+.6g}j"
        mus.append(f"{text} (|mu| {math.hypot(re, im):.6g})")
    return ", ".join(mus) if mus else "none"


def _verdict(stable: bool | None) -> str:
    """The stability verdict's word: "unresolved" when the multipliers cannot decide it."""
    return "unresolved" if stable is None else "stable" if stable else "unstable"


def format_header(param: str, problem: OrbitProblem) -> tuple[str, tuple[list[str], list[int]]]:
    """The table header of ``--continue`` and its columns: the parameter, the unknown
    coordinates, the controller's memory, the free parameters, period, step length, largest
    |multiplier|, verdict."""
    cols = (
        [param]
        + [problem.names[i] for i in problem.unknown_idx]
        + list(problem.memory_names)
        + list(problem.free)
        + ["period", "step", "max|mu|", "stable"]
    )
    widths = [max(12, len(c) + 2) for c in cols]
    return "".join(c.rjust(w) for c, w in zip(cols, widths, strict=True)), (cols, widths)


def format_row(param: str, value: float, payload: dict[str, Any], layout: tuple[list[str], list[int]] | None) -> str:
    """One row of the ``--continue`` table."""
    if layout is None:
        return ""
    cols, widths = layout
    state = dict(zip(payload["state_names"], payload["fixed_point"], strict=False))
    cells = []
    for col, width in zip(cols, widths, strict=True):
        if col == param:
            v: Any = value
        elif col in state:
            v = state[col]
        elif col in payload.get("memory", {}):
            v = payload["memory"][col]
        elif col in payload["parameters"] and col not in ("period", "step", "max|mu|", "stable"):
            v = payload["parameters"][col]
        elif col == "period":
            v = payload["period"]
        elif col == "step":
            v = payload["step_length"]
        elif col == "max|mu|":
            v = payload["spectral_radius"]
        else:
            cells.append({True: "yes", False: "no", None: "unresolved"}[payload["stable"]].rjust(width))
            continue
        cells.append(_fmt(v, width))
    return "".join(cells)


def write_family_plot(family: Family, title: str, path: Path) -> None:
    """Fixed-point coordinates, period and multiplier moduli against the parameter, written to
    ``path`` (png, pdf or svg by its suffix) so that it appears complete or not at all."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..output.files import write_atomic

    values = np.array([p.value for p in family.points])
    first = family.points[0].result
    names = list(first.state_names)
    states = np.array([p.result.fixed_point for p in family.points])
    varying = [i for i in range(len(names)) if np.ptp(states[:, i]) > 0]
    fig = Figure(figsize=(8.0, 8.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    for i in varying:
        ax1.plot(values, states[:, i], marker=".", label=names[i])
    for name in first.free:
        ax1.plot(values, [p.result.parameters[name] for p in family.points], marker=".", ls="--", label=name)
    ax1.set_ylabel("fixed point")
    ax1.legend(loc="best", fontsize="small")
    ax1.set_title(f"{title}: orbits over {family.parameter}")
    ax2.plot(values, [p.result.period for p in family.points], marker=".", label="period (s)")
    steps = [p.result.step_length for p in family.points]
    if all(s is not None for s in steps):
        ax2.plot(values, steps, marker=".", label="step length (m)")
    ax2.legend(loc="best", fontsize="small")
    moduli = [np.abs(p.result.multipliers) if p.result.multipliers is not None else np.empty(0) for p in family.points]
    for k in range(max(len(m) for m in moduli)):
        ax3.plot(values, [m[k] if k < len(m) else np.nan for m in moduli], marker=".", label=f"|mu_{k + 1}|")
    ax3.axhline(1.0, color="k", lw=0.8)
    for change in family.stability_changes:
        for ax in (ax1, ax2, ax3):
            ax.axvline(change.at, color="r", ls=":", lw=1.0)
    ax3.set_ylabel("|multiplier|")
    ax3.set_xlabel(family.parameter)
    ax3.legend(loc="best", fontsize="small")
    try:
        write_atomic(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lower().lstrip(".")), what="--plot")
    except LegsimError:
        raise
    except Exception as exc:
        raise OutputError(f"--plot {path}: writing failed: {type(exc).__name__}: {exc}") from exc
