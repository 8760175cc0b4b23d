"""docs/recording.md's demo prints what the commands print: ``legsim run pronk_pitched`` with
every output and ``legsim replay`` of its recording, run as shown, their output compared line
for line (the wall time's value and the scenes' folder aside)."""

from __future__ import annotations

import shlex

import pytest

from helpers.doc_blocks import comparable, session
from legsim.cli import main


def test_the_recording_demo_prints_what_the_docs_show(tmp_path, monkeypatch, capsys):
    from legsim.robots import _native

    if _native.status() != "available":
        pytest.skip(f"the demo shows the compiled path's counters; native library: {_native.status()}")
    monkeypatch.chdir(tmp_path)
    shown = session("docs/recording.md", "## Demo")
    assert [command.split()[:2] for command, _ in shown] == [["legsim", "run"], ["legsim", "replay"]]
    for command, expected in shown:
        assert main(shlex.split(command)[1:]) == 0, command
        printed = capsys.readouterr().out.splitlines()
        assert comparable(printed) == comparable(expected), command
