"""``legsim bench robots`` (legsim/bench/robots.py): its cases, error measure and level table."""

import csv
import math

import numpy as np
import pytest

from legsim import _native
from legsim.bench import robots
from legsim.bench.work_precision import Row


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
