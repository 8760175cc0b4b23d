"""The command line tells the truth about itself: every number a help text names as a default is
the one the code uses (the option's own default, or the constant the code falls back on), and
the usage lines list the cases a bench accepts."""

from __future__ import annotations

import argparse
import re

import pytest

from legsim.cli import build_parser, main

#: "(default 3, 1 with --quick)" -> "3, 1 with --quick": what a help text says of a default.
DEFAULT = re.compile(r"default:? ([^;)]*)")
NUMBER = re.compile(r"(?<![\w.-])-?\d+(?:\.\d+)?(?:e-?\d+)?(?![\w.])")


def options() -> dict[tuple[str, ...], argparse.Action]:
    """Every option of every command, by (command, subcommand..., option string)."""
    found: dict[tuple[str, ...], argparse.Action] = {}

    def walk(parser: argparse.ArgumentParser, path: tuple[str, ...]) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, (*path, name))
            elif action.option_strings:
                found[(*path, action.option_strings[-1])] = action

    walk(build_parser(), ())
    return found


def stated_defaults(action: argparse.Action) -> list[float]:
    """The numbers the option's help names as defaults, in order."""
    return [float(n) for said in DEFAULT.findall(action.help or "") for n in NUMBER.findall(said)]


def _resolved_defaults() -> dict[tuple[str, ...], list[float]]:
    """The defaults the code applies to the options left None by argparse, as their help
    states them (in the same order)."""
    import inspect

    from legsim.bench import targets, work_precision
    from legsim.bench.cases import make_case
    from legsim.commands import orbit, sweep
    from legsim.output.rrd.live import CONNECT_TIMEOUT
    from legsim.scene import load_scene
    from legsim.scene.certify import section_schema as certify_schema
    from legsim.scene.stochastic import section_schema as stochastic_schema
    from legsim.sweep import engine
    from legsim.sweep.engine import Engine

    scene = load_scene("two_tanks")
    robots_rho = {make_case(name, quick=True).rho_points for name in ("pronk", "double-pendulum")}
    assert len(robots_rho) == 1
    wp = ("bench", "work-precision")
    return {
        (*wp, "--repeats"): [work_precision.REPEATS, work_precision.REPEATS_QUICK],
        (*wp, "--rho-points"): [work_precision.RHO_POINTS, work_precision.RHO_POINTS_QUICK, *robots_rho],
        (*wp, "--extend-budget"): [targets.EXTENSION_BUDGET, targets.EXTENSION_BUDGET_QUICK],
        ("certify", "--max-refinements"): [certify_schema(scene)["max_refinements"].default],
        ("stochastic", "--samples"): [stochastic_schema(scene)["samples"].default],
        ("stochastic", "--seed"): [stochastic_schema(scene)["seed"].default],
        ("run", "--connect-timeout"): [CONNECT_TIMEOUT],
        ("stochastic", "--connect-timeout"): [engine.CONNECT_TIMEOUT],
        ("sweep", "--connect-timeout"): [engine.CONNECT_TIMEOUT],
        ("sweep", "--samples"): [sweep.RANDOM_SAMPLES],
        ("sweep", "--batch"): [inspect.signature(Engine).parameters["target_seconds"].default],
        ("orbit", "--steps"): [orbit.FAMILY_OPTIONS["steps"][2]],
        ("orbit", "--locate"): [orbit.FAMILY_OPTIONS["locate"][2]],
    }


def test_every_default_a_help_text_names_is_the_codes():
    resolved = _resolved_defaults()
    checked = set()
    for key, action in options().items():
        said = stated_defaults(action)
        if not said:
            continue
        if action.default is None:
            assert key in resolved, f"{' '.join(key)}: its help names a default the test does not know: {action.help}"
            assert said == [float(v) for v in resolved[key]], f"{' '.join(key)}: help says {said}: {action.help}"
        else:
            assert said == [float(action.default)], f"{' '.join(key)}: default {action.default!r}, help: {action.help}"
        checked.add(key)
    assert set(resolved) <= checked  # every resolved default is still named by its help


def test_the_check_reads_a_wrong_number():
    action = argparse.Action(["--x"], "x", default=None, help="budget (default 60, 5 with --quick; 0: none)")
    assert stated_defaults(action) == [60.0, 5.0]


@pytest.mark.parametrize(
    "argv, names",
    [
        (["bench", "work-precision", "--help"], "bench.names:CASE_NAMES"),
        (["bench", "targets", "--help"], "bench.names:CASE_NAMES"),
        (["bench", "robots", "--help"], "bench.robots:ALL_CASES"),
    ],
)
def test_the_usage_line_lists_the_cases(argv, names, capsys):
    import importlib

    module, attribute = names.split(":")
    cases = getattr(importlib.import_module(f"legsim.{module}"), attribute)
    assert main(argv) == 0
    usage = capsys.readouterr().out.split("\n\n")[0]
    assert "--case{" + ",".join(cases) + "}" in "".join(usage.split())


def test_the_work_precision_cases_are_the_benchs():
    from legsim.bench.cases import CASE_NAMES, make_case

    assert [make_case(name, quick=True).name for name in CASE_NAMES] == list(CASE_NAMES)


def test_a_full_sweep_without_a_case_says_why_and_what_instead(capsys):
    assert main(["bench", "work-precision"]) == 2
    err = capsys.readouterr().err
    assert "needs --case CASE (oscillator-ex1, oscillator-ex2, bouncing-ball, pronk, double-pendulum)" in err
    assert "--quick without --case runs every case's short form" in err


def test_quick_without_a_case_runs_every_cases_short_form(tmp_path, capsys):
    code = main(
        ["bench", "work-precision", "--quick", "--no-figure", "--quiet", "--out", str(tmp_path), "--format", "json"]
    )
    assert code == 0
    import json

    from legsim.bench.names import CASE_NAMES

    document = json.loads(capsys.readouterr().out)
    assert [t["title"] for t in document["tables"]] == list(CASE_NAMES)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{name}.csv" for name in CASE_NAMES)
