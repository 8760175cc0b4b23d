"""``legsim run SCENE``: simulate a scene, print its summary, write its outputs.

The output writers are looked up only when asked for: ``--rrd`` uses
``legsim.record.write_rrd``, ``--html`` and ``--plot`` the ``html`` and ``plot`` writers of the
``legsim.writers`` entry-point group; each is called as ``writer(execution, scene, path)``.
The outputs are planned before the run (``legsim.output.files.OutputPlan``): an output may not
overwrite the scene file, share its file with another output, replace a device, FIFO or
folder, or have the wrong suffix for its kind. A scene's own ``[output]`` paths are relative
to its folder (or ``--out-dir``); paths given with ``--rrd/--html/--plot`` are the user's.
Every file is written under a temporary name in its directory and renamed into place only
when its writer returned (``legsim.output.files.write_atomic``), so an output is complete or
absent. A run that stops before t_final (status other than ``finished``) still writes its
outputs (they record the status and show where it stopped) and exits with code 3, also when
one of them cannot be made: that output's error is printed on one line (``legsim: error:
--plot FILE: writing failed: ...``), no file is left for it, the others are still written,
and the exit code stays 3 (the run's status is the result; a writer failing on a diverged
state is no bad input). After a finished run a failed output is an error (exit code 2).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from itertools import groupby
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import LegsimError
from ..output.writers import Writer, find_writer

if TYPE_CHECKING:
    from ..output.files import OutputPlan, Staging

NAME = "run"
HELP = "run a scene (a TOML file or a bundled scene name) and print its summary"

OUTPUT_KINDS = ("rrd", "html", "plot")
#: The file types of each kind of output, unless its writer declares its own (``suffixes``).
KIND_SUFFIXES = {"rrd": (".rrd",), "html": (".html", ".htm")}


def add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``--rrd/--html/--plot FILE`` options (shared with commands that write executions)."""
    parser.add_argument("--rrd", metavar="FILE", help="write a Rerun recording of the execution")
    parser.add_argument("--html", metavar="FILE", help="write a self-contained meshcat animation")
    parser.add_argument(
        "--html-camera",
        choices=("fixed", "follow"),
        help="the animation's camera: fixed on the whole run (default; planted feet stand "
        "still) or following a travelling robot",
    )
    parser.add_argument("--plot", metavar="FILE", help="write a plot of the state against time")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene file (.toml) or bundled scene name (see `legsim scenes`)")
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a scene field, e.g. --set integrator.h=1e-4 "
        "--set effects.floor.restitution=0.8 (value read as TOML, else as a string)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    parser.add_argument("--quiet", "-q", action="store_true", help="print nothing but errors; no progress bar")
    parser.add_argument(
        "--check-accuracy",
        action="store_true",
        help="run again with eps/10 and h/2 (tolerances/10 with error control) and report the "
        "estimated error of the final state, transition times and trajectory",
    )
    add_output_arguments(parser)
    parser.add_argument(
        "--out-dir", metavar="DIR", help="where the scene's own [output] files go (default: the scene's folder)"
    )
    add_live_arguments(parser)


def add_live_arguments(parser: argparse.ArgumentParser) -> None:
    """``--spawn``/``--connect`` (stream the recording to a Rerun viewer) and ``--rrd-rate``."""
    live = parser.add_mutually_exclusive_group()
    live.add_argument(
        "--spawn", action="store_true", help="stream the recording to a new Rerun viewer (needs a display)"
    )
    live.add_argument(
        "--connect",
        metavar="ADDRESS",
        help="stream the recording to the Rerun viewer at ADDRESS (a port, HOST:PORT or rerun+http://HOST:PORT/proxy)",
    )
    parser.add_argument(
        "--connect-timeout",
        metavar="S",
        type=float,
        help="seconds --connect waits at each step: the viewer's connection, its first answer, and its "
        "taking the recording after the run (default 10)",
    )
    parser.add_argument(
        "--rrd-rate",
        metavar="HZ",
        type=float,
        help="record at most HZ samples per second of simulated time (--rrd, --spawn, --connect); "
        "every transition's states before and after its reset are kept",
    )


def run(args: argparse.Namespace) -> int:
    from ..output.summary import finite_or_none, run_summary
    from ..output.untrusted import printable
    from ..scene import load_scene

    scene = load_scene(args.scene, overrides=args.overrides)
    scene_outputs = scene.output_paths(args.out_dir)
    if args.out_dir is not None and not scene_outputs:
        raise LegsimError(
            f"--out-dir {args.out_dir}: places the scene's own [output] files, and {scene.path} has no [output] "
            f"section; give --rrd, --html or --plot paths instead"
        )
    outputs = requested_outputs(args, scene_outputs, scene.path)
    plan, writers = plan_outputs(outputs, inputs=scene.input_files(), scene=scene)
    options = {**html_options(args, outputs), "rrd": _check_live(args, "rrd" in outputs)}
    execution, estimate = _simulate(scene, show_progress=not (args.quiet or args.json), check=args.check_accuracy)
    written, failures = _write_all(execution, scene, plan, writers, options)
    failures += _stream_live(args, execution, scene, options["rrd"])
    summary = run_summary(execution, scene, outputs=written)
    if estimate is not None:
        summary["error_estimate"] = finite_or_none(estimate.as_dict())
    if args.json:
        print(json.dumps(summary, allow_nan=False))
    elif not args.quiet:
        print(printable(format_summary(summary)))
        if estimate is not None:
            print(printable(format_estimate(estimate)))
        for kind, path in written.items():
            print(printable(f"wrote {path} ({kind})"))
    if args.quiet:  # the summary prints them otherwise: a result it cannot vouch for says so, even quiet
        for warning in summary["warnings"]:
            print(printable(f"legsim: warning: {warning['message']}"), file=sys.stderr)
    for exc in failures:
        print(printable(f"legsim: error: {exc}"), file=sys.stderr)
    if summary["status"] != "finished":
        print(printable(f"legsim: run stopped early ({summary['status']}): {summary['message']}"), file=sys.stderr)
        return 3
    return 0


def html_options(args: argparse.Namespace, outputs: Mapping[str, object]) -> dict[str, dict[str, Any]]:
    """kind -> keyword arguments for its writer: the html camera, only when asked for (a
    writer is called as ``writer(execution, scene, path)`` otherwise). A camera without an
    animation among ``outputs`` (kind -> target) is an error, not a flag left unused."""
    camera = getattr(args, "html_camera", None)
    if camera and "html" not in outputs:
        raise LegsimError("--html-camera sets the animation's camera: give --html OUT.html with it")
    return {"html": {"camera": camera}} if camera else {}


def plan_outputs(
    outputs: dict[str, tuple[Path, str]], inputs: list[Path], scene: Any = None
) -> tuple[OutputPlan, dict[str, Writer]]:
    """The output plan and kind -> writer of each output (kind -> (path, how messages name
    it)), checked before any work is done: writer found, file type, target (no input, no
    device, no second output on one file), folder writable, and, with a scene, the geometry
    present when the writer draws the robot."""
    from ..output.files import OutputPlan

    plan = OutputPlan(inputs)
    writers = {kind: find_writer(kind, source) for kind, (_, source) in outputs.items()}
    for kind, (path, source) in outputs.items():
        writer = writers[kind]
        suffixes = getattr(writer, "suffixes", None) or KIND_SUFFIXES.get(kind, ())
        plan.add(kind, path, what=source, suffixes=suffixes)
        if scene is not None and getattr(writer, "needs_geometry", False) and scene.model.geometry is None:
            raise LegsimError(
                f"{source} {path}: this output draws the robot, and {scene.model.system.name} "
                f"defines no geometry (Model.geometry is None); use --plot or --rrd for it"
            )
    return plan, writers


def _simulate(scene: Any, show_progress: bool, check: bool) -> tuple[Any, Any]:
    """``scene.simulate()`` with its progress on stderr when shown (a bar on a terminal, a line
    every 30 s elsewhere);
    with ``check``, ``scene.check_accuracy()``: (execution, error estimate or None)."""
    import numpy as np

    from ..output.untrusted import printable
    from ..progress import progress_for

    bar = progress_for(sys.stderr, enabled=show_progress, label=printable(scene.name, newlines=False))
    try:
        # The integrator checks every state for finiteness and ends a diverging run with status
        # non_finite naming mode, time and state; numpy's overflow warnings on the way there
        # would only bury that message.
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return scene.check_accuracy(progress=bar) if check else (scene.simulate(progress=bar), None)
    finally:
        if bar is not None:
            bar.close()


def _check_live(args: argparse.Namespace, records: bool) -> dict[str, Any]:
    """The recording's options (``rate``), after checking the live flags before the run: a
    display for ``--spawn``, a viewer answering at ``--connect``, a positive ``--rrd-rate``
    with something to record (``records``: a recording file is written)."""
    from ..arguments import positive
    from ..output.rrd.live import check_display, check_reachable, viewer_url

    if args.spawn:
        check_display("--spawn", "write the recording with --rrd FILE and open it with `rerun FILE` elsewhere")
    timeout = connect_timeout(args)
    if args.connect is not None:
        check_reachable(args.connect, viewer_url(args.connect), timeout)
    if args.rrd_rate is None:
        return {}
    if not (records or args.spawn or args.connect is not None):
        raise LegsimError("--rrd-rate thins a recording: give --rrd FILE, --spawn or --connect ADDRESS with it")
    return {"rate": positive("--rrd-rate", args.rrd_rate)}


def connect_timeout(args: argparse.Namespace) -> float:
    """The seconds each wait of ``--connect`` may take: ``--connect-timeout``, checked, or the default."""
    from ..arguments import positive
    from ..output.rrd.live import CONNECT_TIMEOUT

    if args.connect_timeout is None:
        return CONNECT_TIMEOUT
    if args.connect is None:
        raise LegsimError("--connect-timeout bounds the waits of --connect: give --connect ADDRESS with it")
    return positive("--connect-timeout", args.connect_timeout)


def _stream_live(args: argparse.Namespace, execution: Any, scene: Any, options: dict[str, Any]) -> list[LegsimError]:
    """Stream the recording to the viewer of ``--spawn``/``--connect``; its error, as
    ``_write_all`` returns them, after a run that stopped early."""
    if not (args.spawn or args.connect is not None):
        return []
    from ..output.rrd.live import stream_rrd

    try:
        if args.connect is not None:
            options = {**options, "timeout": connect_timeout(args)}
        stream_rrd(execution, scene, spawn=args.spawn, connect=args.connect, **options)
    except LegsimError as exc:
        if execution.status == "finished":
            raise
        return [exc]
    return []


def _write_all(
    execution: Any,
    scene: Any,
    plan: OutputPlan,
    writers: dict[str, Writer],
    options: dict[str, dict[str, Any]] | None = None,
) -> tuple[dict[str, Path], list[LegsimError]]:
    """Write every planned output (``options``: kind -> keyword arguments of its writer):
    (kind -> path written, the errors of those that failed).

    After a finished run a failed output is raised. After a run that stopped early the run's
    status is the result the exit code reports (3), not the output that could not be made: its
    error is returned to be printed, and the other outputs are still written.
    """
    import numpy as np

    from ..output.files import Staging

    written: dict[str, Path] = {}
    failures: list[LegsimError] = []
    # A diverged run hands the writers states near the float64 limit: interpolating them and
    # Rerun's float32 cast overflow on the way. The writers draw or store what is finite (the
    # plot leaves out, and says so, what matplotlib cannot draw); numpy's warnings would only
    # bury the status line, as during the run.
    # Staged: the outputs take their names together once all are written, so Ctrl-C or SIGTERM
    # while a later one is written leaves no earlier one replaced (a mixed set of old and new files).
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"), Staging() as staging:
        for kind in plan:
            try:
                written[kind] = write_output(
                    plan, kind, writers[kind], execution, scene, staging=staging, **(options or {}).get(kind, {})
                )
            except LegsimError as exc:
                if execution.status == "finished":
                    raise
                failures.append(exc)
    return written, failures


def format_estimate(estimate: Any) -> str:
    """The error estimate as lines of the text summary."""
    final = ", ".join(f"{name} {value:.3g}" for name, value in estimate.final_state.items())
    relative = "" if estimate.final_state_relative is None else f" (relative {estimate.final_state_relative:.3g})"
    lines = [
        f"estimated error (against eps/10, {'tolerances/10' if estimate.refined.get('rtol') else 'h/2'}):",
        f"  final state: {final}{relative}",
    ]
    if estimate.transition_times is not None:
        differ = "; the transition sequences differ after those" if estimate.transitions_differ else ""
        lines.append(
            f"  transition times: {estimate.transition_times:.3g} s over {estimate.transitions_matched} "
            f"transitions{differ}"
        )
    trajectory = ", ".join(f"{name} {value:.3g}" for name, value in estimate.trajectory.items())
    lines.append(
        f"  trajectory (max over {100 * (1 - estimate.mode_mismatch):.0f}% of the run in the same mode): {trajectory}"
    )
    orbit = estimate.along_orbit
    if orbit is not None:
        largest = max(orbit.state, key=orbit.state.__getitem__, default=None)
        worst = "" if largest is None else f"; largest {largest} {orbit.state[largest]:.3g}"
        relative = "n/a" if orbit.relative is None else f"{orbit.relative:.3g}"
        quotient = "" if orbit.quotient is None else f"; quotient distance (paper 000) {orbit.quotient:.3g}"
        lines.append(
            f"  along the orbit (states at {orbit.crossings} {orbit.where}, phase-aligned): "
            f"relative {relative}{worst}{quotient}; their times {orbit.phase:.3g} s apart"
        )
    lines.append(format_quotient_distance(estimate))
    return "\n".join(lines)


def format_quotient_distance(estimate: Any) -> str:
    """The line of the error estimate on the relaxed quotient distance, or why there is none."""
    q = getattr(estimate, "quotient_distance", None)
    if q is None:
        return f"  quotient distance (paper 000): {estimate.quotient_distance_note or 'not computed'}"
    memory = ", ".join(f"{name} {value:.3g}" for name, value in q.memory.items())
    memory = f"; memory apart (in the same mode): {memory}" if memory else ""
    return (
        f"  quotient distance (paper 000, plant states in M^eps, eps = {q.eps:.3g}): {q.value:.3g} "
        f"at t = {q.time:.6g} s, max over {q.samples} times ({q.searched} across modes or in strips){memory}"
    )


def requested_outputs(
    args: argparse.Namespace, scene_outputs: dict[str, Path] | None = None, scene_path: Path | None = None
) -> dict[str, tuple[Path, str]]:
    """kind -> (path, where it was asked for): a flag wins over the scene's ``[output]``
    (``scene_outputs``: kind -> path, already resolved by ``Scene.output_paths``; ``scene_path``
    the scene file that names them)."""
    out: dict[str, tuple[Path, str]] = {}
    for kind in OUTPUT_KINDS:
        flag = getattr(args, kind, None)
        if flag:
            out[kind] = (Path(flag), f"--{kind}")
        elif scene_outputs and scene_outputs.get(kind):
            named_in = f"{scene_path}: " if scene_path is not None else ""
            out[kind] = (Path(scene_outputs[kind]), f"{named_in}output.{kind} =")
    return out


def write_output(
    plan: OutputPlan,
    kind: str,
    writer: Writer,
    execution: Any,
    scene: Any,
    staging: Staging | None = None,
    **extra: Any,
) -> Path:
    """``writer(execution, scene, tmp, **extra)`` through the plan (``write_atomic``): its
    temporary file is renamed over the planned target when it returns (with ``staging``, when
    the staging ends), removed when it fails; its errors are a LegsimError naming the output and
    the file."""
    label, path = plan.outputs[kind].what, plan.outputs[kind].path

    def write(tmp: Path) -> None:
        try:
            writer(execution, scene, tmp, **extra)
        except LegsimError as exc:
            # The writer only saw the temporary name: say which file was asked for.
            raise LegsimError(f"{label} {path}: writing failed: {str(exc).replace(str(tmp), str(path))}") from exc
        except Exception as exc:
            raise LegsimError(f"{label} {path}: writing failed: {type(exc).__name__}: {exc}") from exc

    return plan.write(kind, write, staging)


def _compact_modes(sequence: list[str], limit: int = 6) -> str:
    """Runs of one mode written once with a count (``flight x13``); long sequences keep their ends."""
    runs = [(mode, len(list(repeats))) for mode, repeats in groupby(sequence)]
    parts = [m if n == 1 else f"{m} x{n}" for m, n in runs]
    if len(parts) > limit:
        parts = [*parts[: limit - 2], "...", *parts[-2:]]
    return " -> ".join(parts) + f" ({len(sequence)} visit{'' if len(sequence) == 1 else 's'})"


def _num(value: Any) -> str:
    # None is what the JSON summary holds for a number that is not finite (or could not be
    # computed on a diverged state): say so rather than print a made-up nan.
    return "n/a" if value is None else f"{value:.6g}"


CORE_KEYS = {
    "system",
    "status",
    "message",
    "t_final",
    "final_mode",
    "final_state",
    "state_names",
    "final_in_strip",
    "mode_sequence",
    "transitions",
    "steps",
    "halvings",
    "field_evals",
    "guard_evals",
    "reset_evals",
    "strip_time",
    "wall_time_s",
    "h",
    "eps",
    "method",
    "scene",
    "robot",
    "energy_initial",
    "energy_final",
    "scene_file",
    "outputs",
    "error_rejections",
    "longest_strip_hold",
    "warnings",
    "error_estimate",
}


def format_summary(summary: dict[str, Any]) -> str:
    """The human-readable run summary (a few lines) of a ``run_summary`` dict."""
    name = summary.get("scene") or summary.get("system") or "run"
    status = summary["status"]
    lines = [
        f"{name}: {status} at t = {_num(summary['t_final'])} s "
        f"({summary.get('method')}, h = {_num(summary.get('h'))} s, eps = {_num(summary.get('eps'))})"
    ]
    state = ", ".join(f"{n} = {_num(v)}" for n, v in zip(summary["state_names"], summary["final_state"], strict=False))
    strip = " (held in a strip)" if summary.get("final_in_strip") else ""
    lines.append(f"final mode {summary['final_mode']}{strip}: {state}")
    lines.append(f"transitions {summary['transitions']}: {_compact_modes(summary['mode_sequence'])}")
    rejections = summary.get("error_rejections") or 0
    rejected = f", error rejections {rejections}" if rejections else ""
    lines.append(
        f"steps {summary['steps']}, halvings {summary['halvings']}{rejected}; evaluations: field "
        f"{summary['field_evals']}, guard {summary['guard_evals']}, reset {summary['reset_evals']}"
    )
    if summary.get("strip_time"):
        lines.append(
            f"held in strips {_num(summary['strip_time'])} s in all, the longest hold "
            f"{_num(summary.get('longest_strip_hold'))} s"
        )
    extra = {k: v for k, v in summary.items() if k not in CORE_KEYS and isinstance(v, (int, float))}
    # The time each actuated joint spent at its effort limit (robots' saturated_<joint>_s counters).
    saturated = {k: extra.pop(k) for k in list(extra) if k.startswith("saturated_") and k.endswith("_s")}
    if saturated:
        lines.append(
            "time at the effort limit: "
            + ", ".join(f"{k[len('saturated_') : -2]} {_num(v)} s" for k, v in saturated.items())
        )
    if extra:
        lines.append("other counters: " + ", ".join(f"{k} {v}" for k, v in extra.items()))
    if "energy_initial" in summary:
        lines.append(f"energy {_num(summary['energy_initial'])} J -> {_num(summary.get('energy_final'))} J")
    lines.append(f"wall time {summary['wall_time_s']:.3g} s")
    lines += [f"warning: {w['message']}" for w in summary.get("warnings", [])]
    if status != "finished" and summary.get("message"):
        lines.append(f"stopped: {summary['message']}")
    return "\n".join(lines)
