"""Subcommands of the ``legsim`` command line, one module each.

A module here is a command when it defines ``NAME`` (str), ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int`` (the exit code; see ``legsim.cli`` for their
meaning). ``legsim.cli`` imports every module at start: keep heavy imports inside ``run``.
Errors a user can provoke are raised as ``LegsimError`` subclasses; the CLI prints them as one
line. Modules whose names start with ``_`` are skipped. ``legsim.commands.run`` exposes
``add_output_arguments``/``plan_outputs``/``write_output``/``format_summary`` for commands that write or print
executions the same way (``replay``).
"""
