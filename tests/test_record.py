"""``legsim.record``, the documented public module of recordings: it re-exports legsim.output's
names, and importing it (or the core, or ``legsim replay``) does not import rerun."""

from __future__ import annotations


def test_core_import_does_not_import_rerun():
    import subprocess
    import sys

    code = "import sys, legsim, legsim.record, legsim.commands.replay; print('rerun' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_public_names_are_those_of_legsim_output():
    import legsim.output
    import legsim.record

    for name in legsim.record.__all__:
        assert getattr(legsim.record, name) is getattr(legsim.output, name), name
