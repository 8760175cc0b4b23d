"""Compile legsim's code ahead of time: ``python -m legsim.prebuild [--out FOLDER]``.

Runs every bundled scene for a moment in child processes whose numba compiles for the generic
x86-64 processor, with legsim's cache pointed at the package's prebuilt folder
(``legsim.compiled.cache.PREBUILT_DIR``): the step loop, the variational equations and every bundled model's and
controller's functions land there, portable to any x86-64 machine, and a first run loads them
instead of compiling for a minute (``legsim.compiled.cache.LegsimCache``). ``make install`` runs it, and so does
a wheel's build (setup.py), so that the wheel ships them.

The two largest parts, the step loop and the models' functions, do not depend on each other (the
loop calls a model's functions by address), so two children compile them side by side; a last
child then runs every scene, loading those and compiling what remains.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

from .compiled.cache import PREBUILT_CPU, PREBUILT_DIR

#: Simulated seconds each scene runs for: enough to reach its modes' first transitions.
WARM_TIME = 0.3


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m legsim.prebuild", description=__doc__)
    parser.add_argument("--out", type=Path, default=PREBUILT_DIR.parent, help="the prebuilt folder's parent")
    parser.add_argument("--child", choices=sorted(CHILDREN), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return CHILDREN[args.child]()
    removed = remove_entries(args.out)
    environment = {**os.environ, "NUMBA_CPU_NAME": PREBUILT_CPU, "LEGSIM_CACHE_DIR": str(args.out)}
    started = time.perf_counter()

    def child(part: str) -> subprocess.Popen[bytes]:
        return subprocess.Popen([sys.executable, "-m", "legsim.prebuild", "--child", part], env=environment)

    side_by_side = {part: child(part) for part in ("loop", "models")}
    finished = wait_all(side_by_side)
    both = time.perf_counter() - started
    code = max([child("scenes").wait(), *(code for code, _ in finished.values())])
    seconds = time.perf_counter() - started
    parts = ", ".join(f"{part} {at - started:.0f} s" for part, (_, at) in finished.items())
    done = (
        f"legsim: prebuilt compiled code in {args.out} ({seconds:.0f} s: {parts} side by side, "
        f"scenes {seconds - both:.0f} s; {removed} old entries removed)"
    )
    print(done, file=sys.stderr)
    return code


def wait_all(processes: dict[str, subprocess.Popen[bytes]]) -> dict[str, tuple[int, float]]:
    """Wait for every process: {name: (exit code, ``time.perf_counter()`` when it was seen done)}.
    The times show which part of the side-by-side compilation the other waits for."""
    finished: dict[str, tuple[int, float]] = {}
    while len(finished) < len(processes):
        for name, process in processes.items():
            code = process.poll()
            if name not in finished and code is not None:
                finished[name] = (code, time.perf_counter())
        time.sleep(0.2)
    return finished


def remove_entries(folder: Path) -> int:
    """Remove the compiled entries (numba's ``.nbi`` index and ``.nbc`` code files) an earlier
    prebuild left in ``folder``: entries of sources since changed are never read again, and a
    wheel would ship them. Other files are left alone."""
    entries = [p for p in folder.rglob("*") if p.suffix in (".nbi", ".nbc") and p.is_file()]
    for path in entries:
        path.unlink()
    return len(entries)


def bundled_scenes() -> list[Path]:
    from .scene import bundled_dir

    return sorted(bundled_dir().glob("*.toml"))


def compile_loop() -> int:
    """Compile the step loop and the variational equations (in a child): the bouncing ball's run
    takes them, its own few functions with them."""
    return warm([path for path in bundled_scenes() if path.stem == LOOP_SCENE])


def compile_models() -> int:
    """Compile the model and controller functions of every mode each bundled scene can reach
    from its initial mode (in a child), without running the step loop."""
    from .compiled import kernel
    from .control import ControlLaw
    from .relaxed.layout import M_READY
    from .relaxed.tables import RunTables
    from .scene import load_scene

    failures = 0
    for path in bundled_scenes():
        try:
            scene = load_scene(path, [f"integrator.t_final={WARM_TIME}"])
            control = scene.control
            tables = RunTables(scene.model.system, None, control if isinstance(control, ControlLaw) else None)
            tables.register(scene.initial_mode)
            while not all(tables.modes[: len(tables.names), M_READY]):
                tables.prepare(next(row for row in range(len(tables.names)) if tables.modes[row, M_READY] == 0))
            for function, kind in zip(tables.functions, tables.kinds, strict=True):
                if kernel.compiles(function):
                    kernel.address(function, kind)
        except Exception as exc:  # one scene's failure leaves the others to compile
            failures += 1
            print(f"legsim: prebuild: scene {path.stem}: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 1 if failures else 0


def warm(paths: list[Path] | None = None) -> int:
    """Run every bundled scene (or those of ``paths``) briefly: each run compiles what it needs."""
    from . import compiled  # noqa: F401 -- registers the kernel
    from .methods import get_method
    from .orbits import variational
    from .relaxed.driver import Evaluator
    from .scene import load_scene

    failures = 0
    for path in bundled_scenes() if paths is None else paths:
        name = path.stem
        try:
            scene = load_scene(path, [f"integrator.t_final={WARM_TIME}"])
            execution = scene.simulate()
            seg = execution.segments[0]
            if len(seg.t) > 2:
                evaluator = Evaluator(scene.model.system, get_method(scene.integrator["method"]))
                variational.segment_sensitivity(evaluator, seg, None, False)
                if seg.x.shape[1] == scene.model.system.modes[seg.mode].dim:  # no controller memory
                    variational.point_on_step(evaluator, seg, 0, 0.5 * float(seg.t[1] - seg.t[0]))
        except Exception as exc:  # one scene's failure leaves the others to compile
            failures += 1
            print(f"legsim: prebuild: scene {name}: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 1 if failures else 0


#: The scene whose run compiles the step loop; its model is arithmetic, quick to compile.
LOOP_SCENE = "bouncing_ball"
#: The children's parts: the first two side by side, then the last.
CHILDREN = {"loop": compile_loop, "models": compile_models, "scenes": warm}

if __name__ == "__main__":
    raise SystemExit(main())
