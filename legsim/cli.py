"""The ``legsim`` command line.

Subcommands are modules of ``legsim.commands``, discovered with ``pkgutil``: each defines
``NAME`` (str), ``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int`` (the
exit code). A new command is a new module; nothing here changes. Command modules are imported
at every start, so they keep heavy imports (rerun, matplotlib, pinocchio, scipy) inside ``run``.

Exit codes: 0 success; 2 a usage error or any ``LegsimError`` (one line ``legsim: error: ...``
on stderr, the traceback only with ``--debug``); 3 a run that stopped before t_final (the
command says why); 1 an unexpected internal error; 130 interrupted (Ctrl-C); 143 terminated
(SIGTERM, which is turned into the same clean shutdown as Ctrl-C: no temporary file is left).
Messages are printed with their control characters escaped: they quote scene files, names and
recordings that may come from someone else.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import signal
import sys
import traceback
from collections.abc import Sequence
from contextlib import suppress
from types import ModuleType
from typing import NoReturn

from .errors import LegsimError, Terminated
from .interrupts import stop_on_signals

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_ERROR = 2
EXIT_STOPPED = 3
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 128 + signal.SIGTERM

REQUIRED = ("NAME", "HELP", "add_arguments", "run")


def discover_commands() -> tuple[dict[str, ModuleType], dict[str, str]]:
    """The command modules of ``legsim.commands`` by NAME, and the ones that failed to import
    (module name -> reason), so that one broken command does not take the others down."""
    from . import commands as package

    found: dict[str, ModuleType] = {}
    broken: dict[str, str] = {}
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        try:
            module = importlib.import_module(f"{package.__name__}.{info.name}")
        except Exception as exc:  # report it when the command is used, not at every start
            broken[info.name] = f"{type(exc).__name__}: {exc}"
            continue
        missing = [attr for attr in REQUIRED if not hasattr(module, attr)]
        if missing:
            broken[info.name] = f"module {module.__name__} lacks {missing}"
            continue
        found[str(module.NAME)] = module
    return found, broken


def _version() -> str:
    from .version import __version__

    return __version__


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with one subparser per discovered command."""
    common = argparse.ArgumentParser(add_help=False)
    # SUPPRESS lets --debug be given before or after the command without one hiding the other.
    common.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show the full traceback of errors"
    )
    parser = argparse.ArgumentParser(
        prog="legsim",
        parents=[common],
        description="Simulate legged robots as controlled hybrid systems with the relaxed hybrid integrator.",
        epilog="Run `legsim COMMAND --help` for a command's options.",
    )
    parser.add_argument("--version", action="version", version=f"legsim {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    commands, broken = discover_commands()
    for name, module in commands.items():
        p = sub.add_parser(name, parents=[common], help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    for name, reason in broken.items():
        if name in commands:
            continue
        p = sub.add_parser(name, parents=[common], help=f"(unavailable: {reason})")
        p.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
        p.set_defaults(_run=_unavailable(name, reason))
    return parser


def _unavailable(name: str, reason: str):
    def run(args: argparse.Namespace) -> int:
        raise LegsimError(f"command '{name}' is unavailable: its module failed to load ({reason})")

    return run


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    with stop_on_signals():
        try:
            return _dispatch(argv)
        except LegsimError as exc:
            return _report(f"legsim: error: {exc}", debug, EXIT_ERROR)
        except OSError as exc:
            if isinstance(exc, BrokenPipeError):
                return _broken_pipe()
            return _report(f"legsim: error: {exc}", debug, EXIT_ERROR)
        except Terminated:
            return _report("legsim: terminated", debug, EXIT_TERMINATED)
        except KeyboardInterrupt:
            return _report("legsim: interrupted", debug, EXIT_INTERRUPTED)
        except Exception as exc:
            return _report(
                f"legsim: internal error: {type(exc).__name__}: {exc}"
                + ("" if debug else " (run with --debug for the traceback)"),
                debug,
                EXIT_INTERNAL,
            )


def _dispatch(argv: list[str]) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help, --version, usage errors (already printed)
        return int(exc.code) if isinstance(exc.code, int) else EXIT_ERROR
    if getattr(args, "_run", None) is None:
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    _say_compiles()
    return int(args._run(args) or 0)


def _say_compiles() -> None:
    """Have the compiled path say on stderr, in one line, when it compiles for this machine
    (the first run after installing takes that time once)."""
    from .compiled import kernel
    from .output.untrusted import printable

    kernel.on_compile = lambda message: print(printable(message), file=sys.stderr, flush=True)


def _report(line: str, debug: bool, code: int) -> int:
    from .output.untrusted import printable

    if debug:
        traceback.print_exc()
    print(printable(line), file=sys.stderr)
    return code


def _broken_pipe() -> int:
    # The reader went away (`legsim scenes | head`): stop quietly, and keep Python from
    # complaining about the unflushable stdout at exit.
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return EXIT_OK


def entry() -> NoReturn:
    """The ``legsim`` program (``python -m legsim.cli``, ``python -m legsim``): ``main``, its exit
    code the process's. An interrupted command has done its clean-up inside ``main`` (temporary
    files removed, the sweep's rows merged, its workers stopped); it then leaves without the
    interpreter's teardown, which takes a second or more once Dask, numba and Rerun are loaded,
    so that Ctrl-C and SIGTERM end a sweep or a live recording within 2 s."""
    code = main()
    if code in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        for stream in (sys.stdout, sys.stderr):
            with suppress(Exception):  # a closed or broken stream has nothing left to say
                stream.flush()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    entry()
