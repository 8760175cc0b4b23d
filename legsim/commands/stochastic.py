"""``legsim stochastic SCENE``: sample the stochastic approximation of a scene (paper 004 Sec. IV).

Settings come from the scene's ``[stochastic]`` section
(``legsim.scene.stochastic.section_schema``: samples, seed, h, method, pair, floor, intensity,
t_final, max_transitions, carry, hazard_cap), with h, method and t_final defaulting to
``[integrator]``; ``--samples`` and ``--seed`` override it.
Prints the distribution of mode sequences and of the first switching times, beside the
deterministic (relaxed) execution's switching times; ``--plot FILE`` draws their histograms.

With ``--workers N`` or ``--scheduler ADDRESS`` (or ``DASK_SCHEDULER_ADDRESS``) the executions
are drawn in batches on the sweep engine's Dask cluster (``legsim.sweep.stochastic``); each
execution has its own random stream, so the numbers are those of the serial run.

Exit codes: 0 when every sampled execution reached t_final; 3 when some stopped early
(transition budget, non-finite state, overflowing error bound); 2 for errors in the scene or
the arguments. Long runs show the number of executions done on a terminal's stderr (not with
--quiet).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from ..errors import LegsimError

NAME = "stochastic"
HELP = "sample the stochastic approximation of a scene and summarise mode sequences and switching times"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene file (.toml) or bundled scene name")
    parser.add_argument(
        "--samples", type=int, metavar="N", help="number of sampled executions (default: stochastic.samples, else 100)"
    )
    parser.add_argument(
        "--seed", type=int, metavar="S", help="seed of the random generator (default: stochastic.seed, else 0)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="override a scene field, e.g. --set stochastic.h=0.01 --set stochastic.floor=1",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--switches", type=int, default=10, metavar="K", help="summarise the first K switching times (default 10)"
    )
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress line")
    parser.add_argument("--plot", metavar="FILE", help="write histograms of the switching times (.png, .pdf, .svg)")
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="draw the executions on an embedded Dask cluster of N worker processes",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="draw them on a running Dask scheduler (default: $DASK_SCHEDULER_ADDRESS)",
    )
    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds to wait at each step of reaching --scheduler: connection, first answer, first worker "
        "(default 20)",
    )


def run(args: argparse.Namespace) -> int:
    from ..scene import load_scene
    from ..scene.stochastic import ensemble_from_scene
    from ..sweep import engine

    if args.samples is not None and args.samples < 1:
        raise LegsimError(f"--samples must be an integer >= 1, got {args.samples}")
    if args.seed is not None and args.seed < 0:
        raise LegsimError(f"--seed must be an integer >= 0, got {args.seed}")
    if args.switches < 0:
        raise LegsimError(f"--switches must be >= 0, got {args.switches}")
    scene = load_scene(args.scene, overrides=args.overrides)
    histogram = _histogram_writer(args.plot, scene.path)
    counter = _SampleCounter(sys.stderr, scene.name) if not args.quiet and _isatty(sys.stderr) else None
    settings = {"samples": args.samples, "seed": args.seed}
    try:
        if args.workers is not None or args.scheduler or os.environ.get(engine.SCHEDULER_ENV):
            ensemble = _on_engine(args, scene, settings, counter)
        else:
            ensemble = ensemble_from_scene(scene, settings, progress=counter)
    finally:
        if counter is not None:
            counter.close()
    summary = ensemble.summary(max_switches=args.switches)
    summary["deterministic"] = _deterministic(scene, args.switches)
    if histogram is not None:
        summary["outputs"] = {"plot": str(_write_histograms(histogram, ensemble, summary))}
    if args.json:
        print(json.dumps(_finite(summary), allow_nan=False))
    else:
        print(format_summary(summary))
        for kind, path in summary.get("outputs", {}).items():
            print(f"wrote {path} ({kind})")
    if summary["max_radius"] == 0.0:
        print(
            "legsim: note: the error bound is 0 along every execution (the method is exact on these fields and "
            "no floor is declared): the stochastic approximation is the deterministic system itself (paper 004's "
            "Theorem 2 needs a non-trivial bound); declare a local error floor, e.g. --set stochastic.floor=1",
            file=sys.stderr,
        )
    if summary["unresolved"]:
        print(
            f"legsim: warning: in {summary['unresolved']['executions']} of {summary['samples']} executions the error "
            f"ball grew wider than the state itself, the earliest at t={summary['unresolved']['earliest']:.6g} s: "
            "from there it holds the guards around it and the switches drawn say nothing of the system "
            "(a shorter t_final, a smaller h or a smaller floor keeps it narrower)",
            file=sys.stderr,
        )
    stopped = {k: v for k, v in summary["statuses"].items() if k != "finished"}
    if stopped:
        example = next(e for e in ensemble.executions if e.status != "finished")
        print(
            f"legsim: {sum(stopped.values())} of {summary['samples']} sampled executions stopped early: "
            f"{stopped}; e.g. {example.status}: {example.message}",
            file=sys.stderr,
        )
        return 3
    return 0


def _on_engine(args: argparse.Namespace, scene: Any, settings: dict[str, Any], counter: Any) -> Any:
    """The ensemble drawn on the sweep engine (Dask)."""
    from ..sweep.engine import Engine
    from ..sweep.spec import scene_reference
    from ..sweep.stochastic import ensemble_on_engine

    with Engine(workers=args.workers, scheduler=args.scheduler, connect_timeout=args.connect_timeout) as engine:
        return ensemble_on_engine(scene, scene_reference(args.scene), settings, engine, progress=counter)


def _histogram_writer(path: str | None, scene_path: Path | None) -> Any:
    """(output plan, switching-time histogram writer), checked before the run (None without
    --plot): the file must be writable, of a type the writer draws, and not the scene."""
    if path is None:
        return None
    from ..output.files import OutputPlan
    from ..output.writers import find_writer

    writer = find_writer("switching_histograms", "--plot")
    plan = OutputPlan([scene_path] if scene_path is not None else [])
    plan.add("plot", path, what="--plot", suffixes=getattr(writer, "suffixes", ()))
    return plan, writer


def _write_histograms(histogram: Any, ensemble: Any, summary: dict[str, Any]) -> Path:
    plan, writer = histogram
    count = len(summary["switching_times"])
    times = [ensemble.switching_times(i).tolist() for i in range(count)]
    info = {
        "scene": summary.get("scene", summary["system"]),
        "samples": summary["samples"],
        "deterministic": summary["deterministic"]["switching_times"],
    }
    return plan.write("plot", lambda tmp: writer(times, info, tmp))


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class _SampleCounter:
    """``counter(done, total)`` draws ``name  37 / 100 executions  4.2 s`` on one terminal line,
    a few times a second once the run has lasted half a second; ``close()`` erases it."""

    def __init__(self, stream, label: str) -> None:
        import time

        self.stream = stream
        self.label = label
        self.clock = time.perf_counter
        self.started = self.clock()
        self.last = 0.0
        self.width = 0

    def __call__(self, done: int, total: int) -> None:
        now = self.clock()
        if now - self.started < 0.5 or (now - self.last < 0.2 and done < total):
            return
        self.last = now
        text = f"{self.label}  {done} / {total} executions  {now - self.started:.1f} s"
        self.stream.write("\r" + text + " " * max(0, self.width - len(text)))
        self.stream.flush()
        self.width = len(text)

    def close(self) -> None:
        if self.width:
            self.stream.write("\r" + " " * self.width + "\r")
            self.stream.flush()


def _deterministic(scene: Any, count: int) -> dict[str, Any]:
    """The relaxed execution's first switching times and mode sequence, for comparison."""
    execution = scene.simulate()
    return {
        "status": execution.status,
        "transitions": len(execution.transitions),
        "switching_times": [float(tr.time) for tr in execution.transitions[:count]],
        "mode_sequence": execution.mode_sequence[: count + 1],
    }


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if obj == obj and abs(obj) != float("inf") else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _sequence(modes: list[str]) -> str:
    if len(modes) <= 8:
        return " > ".join(modes)
    return " > ".join(modes[:4]) + f" > ... > {modes[-1]}"


def format_summary(s: dict[str, Any]) -> str:
    """Human-readable summary of an ensemble (the text output of ``legsim stochastic``)."""
    lines = [
        f"{s.get('scene', s['system'])}: {s['samples']} stochastic executions to t = {s['t_final']:g} s "
        f"(h = {s['h']:g}, {s['method']}, pair {s['pair']}, floor {s['floor']:g}, {s['intensity']} intensity, "
        f"seed {s['seed']})",
        f"transitions per execution: mean {s['transitions_per_sample']['mean']:.2f}, "
        f"min {s['transitions_per_sample']['min']}, max {s['transitions_per_sample']['max']}; "
        f"{s['distinct_sequences']} distinct mode sequences",
    ]
    for seq in s["sequences"]:
        lines.append(f"  {seq['fraction']:6.1%}  ({seq['transitions']} transitions)  {_sequence(seq['modes'])}")
    det = s["deterministic"]
    if s["switching_times"]:
        lines.append("switching times (s):      n      mean       std       min       max   deterministic")
        for i, sw in enumerate(s["switching_times"]):
            ref = det["switching_times"][i] if i < len(det["switching_times"]) else None
            ref_text = f"{ref:13.6g}" if ref is not None else "            -"
            lines.append(
                f"  #{sw['index']:<3d}              {sw['count']:6d} {sw['mean']:9.6g} {sw['std']:9.3g} "
                f"{sw['min']:9.6g} {sw['max']:9.6g}   {ref_text}"
            )
    if s["min_dwell_time"] is not None:
        lines.append(f"shortest visit: {s['min_dwell_time']:.3g} s")
    lines.append(f"deterministic (relaxed) execution: {det['transitions']} transitions, status {det['status']}")
    lines.append("statuses: " + ", ".join(f"{k} {v}" for k, v in s["statuses"].items()))
    return "\n".join(lines)
