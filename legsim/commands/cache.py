"""``legsim cache``: where legsim keeps its compiled code, and clearing it.

legsim compiles its step loop and each model's functions once per machine and legsim version
(with numba) and loads them from its cache afterwards (``legsim.compiled.cache``). ``legsim
cache`` prints the folder and its size; ``legsim cache clear`` removes the compiled code
(every version's; only numba's cache files, never other files in the folder), so the next run
compiles again.
"""

from __future__ import annotations

import argparse

NAME = "cache"
HELP = "show or clear legsim's cache of compiled code"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", nargs="?", choices=("show", "clear"), default="show", help="show (default) or clear")


def run(args: argparse.Namespace) -> int:
    from ..compiled import cache

    if args.action == "clear":
        folder, count, kept = cache.clear()
        print(f"removed {count} files of compiled code from {folder}")
        if kept:
            shown = ", ".join(str(path) for path in kept[:5]) + (f" and {len(kept) - 5} more" if len(kept) > 5 else "")
            print(f"kept {len(kept)} files that are not compiled code: {shown}")
        return 0
    root, compiled, other = cache.cache_files()
    size = sum(p.stat().st_size for p in compiled)
    print(
        f"{root}: {len(compiled)} files, {size / 1e6:.1f} MB of compiled code, every version's (legsim cache clear "
        f"removes them); this version's in {cache.cache_dir()}"
    )
    if other:
        print(f"{len(other)} other files there are not compiled code and are kept")
    return 0
