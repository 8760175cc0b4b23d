"""``legsim bench robots`` (legsim/bench/robots.py): its cases, error measure and level table."""

import csv
import itertools
import math

import numpy as np
import pytest
from legsim.robots import _native

from legsim.bench import robots
from legsim.bench.rows import Row


def row(kind, method, error, wall):
    return Row(
        "c", method, kind, 0.01, 1e-6, math.nan, math.inf, "aim", error, math.nan, wall, 1, 1, 0, 1, 1, 1, "finished"
    )


def test_levels_take_the_fastest_run_of_each_family_below_the_level():
    rows = [
        row("relaxed", "relaxed-rk4", 1e-5, 0.002),
        row("relaxed", "relaxed-dop853", 1e-9, 0.003),
        row("solve_ivp", "solve_ivp-DOP853", 1e-7, 0.03),
        row("solve_ivp", "solve_ivp-RK45", 1e-4, 0.01),
    ]
    res = robots.at_levels(rows)
    assert res[0].best["relaxed"].method == "relaxed-rk4" and res[0].best["solve_ivp"].method == "solve_ivp-RK45"
    assert res[0].ratio("solve_ivp") == pytest.approx(5.0)
    assert res[1].best["relaxed"].method == "relaxed-dop853" and res[1].ratio("solve_ivp") == pytest.approx(10.0)
    assert res[2].best["solve_ivp"] is None and res[2].ratio("solve_ivp") is None
    assert "solve_ivp: none" in robots.format_levels(res)


@pytest.mark.skipif(not _native.load(), reason=f"native library: {_native.status()}")
def test_rimless_wheel_case_is_on_its_closed_form_cycle_and_the_sweep_is_measured(tmp_path):
    case, rows, csv_path, _ = robots.run_case("rimless-wheel", quick=True, out=tmp_path, repeats=1, figure=False)
    ref = case.reference
    # Drake's wheel (8 spokes, slope 0.08 rad) started on the closed-form cycle: every impact
    # returns the same post-impact rate, one step of 2 l sin(alpha) apart.
    assert len(ref.transitions) >= 8
    rates = np.array([t.state_after[1] for t in ref.transitions])
    assert np.abs(rates - case.x0[1]).max() < 1e-9
    steps = np.diff([t.state_after[2] for t in ref.transitions])
    assert np.allclose(steps, 2 * math.sin(math.pi / 8), atol=1e-9)
    assert case.error(ref) == 0.0
    families = {r.kind for r in rows}
    assert families == {"relaxed", "relaxed-python", "solve_ivp"}
    # The error falls with eps and the tolerance: the tightest compiled DOP853 run is within
    # 1e-8 of the reference (its strips are 1e-10 rad wide).
    tight = min((r for r in rows if r.method == "relaxed-dop853"), key=lambda r: r.tol)
    assert tight.error < 1e-8 and tight.status == "finished"
    with open(csv_path) as fh:
        assert len(list(csv.DictReader(fh))) == len(rows)
    costs = robots.cost_report(case, rows)
    assert costs["aba_s"] > 0 and costs["field_s"] > 0


def test_zero_time_chains_of_transitions_count_as_one_event():
    # A release followed at once by grazes (rounding decides how many) is one
    # event: its time is the first transition's, its state the last one's.
    from types import SimpleNamespace as T

    chain = [
        T(time=1.0, state_after=np.array([1.0])),
        T(time=1.0, state_after=np.array([2.0])),
        T(time=1.0 + 1e-9, state_after=np.array([3.0])),
        T(time=2.0, state_after=np.array([4.0])),
    ]
    merged = robots.events(T(transitions=chain))
    assert [t for t, _ in merged] == [1.0, 2.0] and [x[0] for _, x in merged] == [3.0, 4.0]


def test_slip_raibert_case_runs_on_the_compiled_path_and_its_error_falls_with_the_tolerance(tmp_path, capsys):
    from legsim.bench.work_precision import read_rows

    assert robots.main(["slip-raibert"], quick=True, out=str(tmp_path), repeats=1, figure=False, log=None) == 0
    out = capsys.readouterr().out
    # raibert_slip is a compiled ControlLaw: the output says so, and has a compiled family
    # (rk4 and aimed landing) beside the Python path's dense DOP853.
    assert robots.COMPILED_PATH_NOTE in out and "python/compiled" in out and "relaxed:" in out
    rows = read_rows(tmp_path / "robots-slip-raibert.csv")
    assert {r.kind for r in rows} == {"relaxed", "relaxed-python", "solve_ivp"}
    assert {r.method for r in rows if r.kind == "relaxed-python"} == {"relaxed-dop853-dense"}
    assert {"relaxed-rk4", "relaxed-dop853", "relaxed-dopri5", "solve_ivp-LSODA"} <= {r.method for r in rows}
    # Two independent integrators of the closed loop (relaxed DOP853 with strips of 1e-2 tol,
    # solve_ivp DOP853 at 1e-12) agree ever better as the tolerance falls: each hundredfold
    # tighter tolerance gains at least tenfold, down to below 1e-8 (measured: 3e-4, 5e-7, 2e-8,
    # 6e-10 at 1e-4 ... 1e-10).
    dense = sorted((r for r in rows if r.method == "relaxed-dop853-dense"), key=lambda r: -r.tol)
    errors = [r.error for r in dense]
    assert len(errors) == 4 and all(b < a / 10 for a, b in itertools.pairwise(errors))
    assert errors[-1] < 1e-8


def test_every_controlled_run_gets_a_fresh_controller():
    case = robots.make_robot_case("slip-raibert", quick=True)
    # Raibert's controller remembers the last stance's duration: a controller carried over
    # from an earlier run would place the first foot elsewhere, and the error would change.
    assert len(robots.events(case.reference)) >= 3 and case.error(case.reference) == 0.0
    spec = robots.RunSpec("relaxed-python", "relaxed-dop853-dense", 0.1, 1e-10, 1e-8, "dense")
    first, again = robots.run_one(case, spec, 1), robots.run_one(case, spec, 2)
    assert first.error == again.error < 1e-7


@pytest.mark.xfail(
    strict=True,
    reason=(
        "known defect: the relaxed runs differ from the event-driven reference by 8e-3 at every "
        "tolerance; the sequences part at a graze of the hind foot 0.25 ms after the front foot's "
        "touchdown, which the relaxed run strikes again at once and the reference 17 us later "
        "(choosing outcomes under the input before them instead does not change it); "
        "docs/targets.md, 'Known defects'"
    ),
)
def test_quadruped_run_case_error_falls_with_the_tolerance():
    case = robots.make_robot_case("quadruped-run", quick=True)
    assert case.controlled is not None and case.t_final == case.controlled.t_quick
    # raibert_runner is a compiled ControlLaw: the rk4 and aimed runs take the compiled path.
    assert case.controlled.compiled and robots.takes_compiled_path(case.system, case.new_control())
    ref_events = robots.events(case.reference)
    assert len(ref_events) >= 1 and ref_events[0][0] == pytest.approx(0.1628, abs=1e-3)  # the landing
    errors = []
    for tol in (1e-4, 1e-8):
        spec = robots.RunSpec("relaxed-python", "relaxed-dop853-dense", 0.02, 1e-9, tol, "dense")
        row_ = robots.run_one(case, spec, 1)
        assert row_.status == "finished"
        errors.append(row_.error)
    # Measured: 1.6e-5 and 1.8e-10 (the error of the later events is about 2 eps).
    assert errors[1] < errors[0] / 100 and errors[1] < 1e-8


def test_each_relaxed_family_runs_on_the_path_it_is_named_for():
    # The families' ratio ("python/compiled") compares the two paths: the same settings, one
    # run by the compiled kernel, the other by the Python loop.
    case = robots.make_robot_case("slip-raibert", quick=True)
    for kind, path in (("relaxed", "compiled_steps"), ("relaxed-python", "python_steps")):
        spec = robots.RunSpec(kind, "relaxed-dop853-dense", 0.1, 1e-8, 1e-6, "dense")
        counters = robots._relaxed_call(case, spec, robots._ControllerMaker(case))().counters
        assert counters[path] == counters["steps"] > 0
