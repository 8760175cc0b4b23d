"""Compile legsim's code ahead of time: ``python -m legsim.prebuild [--out FOLDER]``.

Runs every bundled scene for a moment in a child process whose numba compiles for the generic
x86-64 processor, with legsim's cache pointed at the package's prebuilt folder
(``legsim.compiled.cache.PREBUILT_DIR``): the step loop, the variational equations and every bundled model's and
controller's functions land there, portable to any x86-64 machine, and a first run loads them
instead of compiling for a minute (``legsim.compiled.cache.LegsimCache``). ``make install`` runs it, and so does
a wheel's build (setup.py), so that the wheel ships them.
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
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return warm()
    removed = remove_entries(args.out)
    environment = {**os.environ, "NUMBA_CPU_NAME": PREBUILT_CPU, "LEGSIM_CACHE_DIR": str(args.out)}
    started = time.perf_counter()
    code = subprocess.call([sys.executable, "-m", "legsim.prebuild", "--child"], env=environment)
    seconds = time.perf_counter() - started
    done = f"legsim: prebuilt compiled code in {args.out} ({seconds:.0f} s, {removed} old entries removed)"
    print(done, file=sys.stderr)
    return code


def remove_entries(folder: Path) -> int:
    """Remove the compiled entries (numba's ``.nbi`` index and ``.nbc`` code files) an earlier
    prebuild left in ``folder``: entries of sources since changed are never read again, and a
    wheel would ship them. Other files are left alone."""
    entries = [p for p in folder.rglob("*") if p.suffix in (".nbi", ".nbc") and p.is_file()]
    for path in entries:
        path.unlink()
    return len(entries)


def warm() -> int:
    """Run every bundled scene briefly (in the child): each run compiles what it needs."""
    from . import compiled  # noqa: F401 -- registers the kernel
    from .methods import get_method
    from .orbits import variational
    from .relaxed.driver import Evaluator
    from .scene import bundled_dir, load_scene

    failures = 0
    for path in sorted(bundled_dir().glob("*.toml")):
        name = path.stem
        try:
            scene = load_scene(path, [f"integrator.t_final={WARM_TIME}"])
            execution = scene.simulate()
            seg = execution.segments[0]
            if len(seg.t) > 2:
                evaluator = Evaluator(scene.model.system, get_method(scene.integrator["method"]))
                variational.segment_sensitivity(evaluator, seg, None, False)
        except Exception as exc:  # one scene's failure leaves the others to compile
            failures += 1
            print(f"legsim: prebuild: scene {name}: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
