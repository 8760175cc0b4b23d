"""The work-precision bench: its error measure, its reading of the rows, its files and its CLI."""

import csv
import math
import re

import numpy as np
import pytest

from legsim.bench import (
    COLUMNS,
    Row,
    RunSpec,
    Target,
    evaluate_targets,
    make_case,
    mark_pareto,
)
from legsim.bench.cases import BenchError
from legsim.bench.work_precision import (
    own_points,
    position_error,
    run_one,
    time_to_reach,
)
from legsim.cli import main

METHOD_NAME = re.compile(r"^(relaxed-(euler|rk2|rk4|bs32|dopri5|dop853)(-zeno)?|ps|solve_ivp-(RK23|RK45|DOP853|LSODA|Radau|BDF))$")


def test_error_of_euler_free_fall_is_the_closed_form():
    # Before the first impact (0.4515 s) explicit Euler on z'' = -g gives
    # z_k = z0 - g h^2 k (k - 1) / 2 against z(t_k) = z0 - g t_k^2 / 2: the error at t_k is
    # g h t_k / 2, largest at the last point. The bench must find exactly that.
    case = make_case("bouncing-ball", quick=True)
    case.t_final = 0.4
    h = 0.01
    row = run_one(case, RunSpec("relaxed", "relaxed-euler", h, 1e-3), repeats=1)
    assert row.status == "finished" and row.transitions == 0
    assert row.error == pytest.approx(9.81 * h * 0.4 / 2, rel=1e-9)
    assert row.steps == 40 and row.field_evals == 41


def test_ps_error_is_measured_at_its_own_grid_against_the_closed_form():
    # PS is second order away from the stop (baselines tests); here, with the stop, its error over
    # its grid must fall as h shrinks and match a direct evaluation of eq. (30).
    from legsim.baselines import paoli_schatzman
    from legsim.systems.oscillator import OscillatorReference

    case = make_case("oscillator-ex1", quick=True)
    rows = [run_one(case, RunSpec("ps", "ps", h), repeats=1) for h in (1e-3, 1e-4)]
    assert rows[1].error < 0.2 * rows[0].error
    ps = case.ps
    t, z = paoli_schatzman(ps["a"], ps["omega"], ps["c"], ps["x_max"], lambda t: 20.0 * np.cos(2.5 * t), ps["x0"],
                           ps["xd0"], case.t_final, 1e-3, compiled=True)
    direct = np.abs(z - OscillatorReference.example("ex1").position(t)).max()
    assert rows[0].error == pytest.approx(direct, rel=1e-12)
    assert rows[0].steps == len(t) - 1


def test_own_points_are_the_segment_points_of_every_mode():
    case = make_case("bouncing-ball", quick=True)
    from legsim import simulate

    ex = simulate(case.system, case.x0, case.mode, 1.0, 1e-2, 1e-6, "rk4")
    times, values = own_points(ex, (0,))
    assert len(times) == sum(len(s.t) for s in ex.segments) and values.shape == (len(times), 1)
    assert np.all(np.diff(times) >= 0)
    # A wrong reference shows as its offset.
    assert position_error(times, values, lambda t: case.reference_positions(t) + 0.25) == pytest.approx(
        0.25, abs=row_error(case, ex) + 1e-12)


def row_error(case, ex):
    return position_error(*own_points(ex, case.positions), case.reference_positions)


def _row(method, kind, error, wall):
    return Row("c", method, kind, math.nan, math.nan, math.nan, math.inf, "", error, math.nan, wall, 1, 1, 0, 1, 0,
               0, "finished")


def test_pareto_front_and_time_to_reach():
    rows = [_row("relaxed-rk4", "relaxed", 1e-3, 1.0), _row("relaxed-rk4", "relaxed", 1e-6, 2.0),
            _row("ps", "ps", 1e-2, 0.5), _row("ps", "ps", 1e-4, 10.0), _row("ps", "ps", 1e-7, 3.0),
            _row("solve_ivp-RK45", "solve_ivp", math.inf, 0.1)]
    mark_pareto(rows)
    # By time: 0.1 (inf error: never on the front), 0.5 (1e-2), 1.0 (1e-3), 2.0 (1e-6), 3.0 (1e-7), 10 (1e-4).
    assert [r.pareto for r in rows] == [1, 1, 1, 0, 1, 0]
    assert time_to_reach(rows, 1e-4, "ps").wall_s == 3.0
    assert time_to_reach(rows, 1e-8, "ps") is None
    assert time_to_reach(rows, 1e-4, "relaxed").wall_s == 2.0


def test_targets_report_ratio_and_the_cases_without_one():
    rows = [_row("relaxed-rk4", "relaxed", 1e-4, 0.1), _row("ps", "ps", 5e-4, 4.0), _row("ps", "ps", 1e-2, 1.0)]
    met, unreached, missed = evaluate_targets(rows, [Target("a", 1e-3, "ps", 20.0), Target("b", 1e-4, "ps", 20.0),
                                                     Target("c", 1e-5, "ps", 20.0)])
    assert met.ratio == pytest.approx(40.0) and met.met
    assert unreached.baseline_time is None and unreached.met and "never reaches" in unreached.note
    assert missed.relaxed_time is None and missed.met is False
    slow = evaluate_targets(rows, [Target("d", 1e-3, "ps", 50.0)])[0]
    assert slow.ratio == pytest.approx(40.0) and not slow.met


def test_quick_bench_writes_csv_figure_and_table(tmp_path, capsys):
    code = main(["bench", "work-precision", "--case", "oscillator-ex1", "--quick", "--out", str(tmp_path), "--quiet"])
    assert code == 0
    out = capsys.readouterr().out
    assert "targets:" in out and "Ex.1 error <= 1e-3" in out
    with open(tmp_path / "oscillator-ex1.csv", newline="") as fh:
        reader = csv.DictReader(fh)
        assert tuple(reader.fieldnames) == COLUMNS
        rows = list(reader)
    for required in ("method", "h", "eps", "tol", "error", "wall_s", "steps"):
        assert required in COLUMNS
    assert {r["kind"] for r in rows} == {"relaxed", "ps", "solve_ivp"}
    assert all(METHOD_NAME.match(r["method"]) for r in rows)
    for r in rows:
        assert float(r["wall_s"]) > 0 and int(r["steps"]) > 0
        assert float(r["error"]) >= 0
        if r["kind"] == "relaxed":
            assert float(r["h"]) > 0 and float(r["eps"]) > 0 and float(r["rho"]) > 0
    # The marked front: faster runs have larger errors.
    front = sorted((r for r in rows if r["pareto"] == "1"), key=lambda r: float(r["wall_s"]))
    assert front and all(float(a["error"]) > float(b["error"]) for a, b in zip(front, front[1:]))
    assert (tmp_path / "oscillator-ex1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob("*.tmp*"))  # written atomically


def test_zeno_variant_of_ex2_beats_the_chattering_plain_run(tmp_path, capsys):
    # Example 2 sticks on the stop twice; the plain relaxed run (continuation=False) chatters there
    # (one strip crossing every ~sqrt(2 eps / F) s) while the -zeno run, with the default
    # continuation, sticks. Its error against the closed
    # form must then be below the plain run's at the same h and eps, and below the 1e-6 m of the
    # speed target, the level the plain integrator misses.
    code = main(["bench", "work-precision", "--case", "oscillator-ex2", "--quick", "--out", str(tmp_path),
                 "--quiet", "--no-figure", "--rho-points", "0"])
    assert code == 0
    out = capsys.readouterr().out
    assert "plain or Zeno continuation" in out and "takes the model's Zeno continuation (simulate's default" in out
    with open(tmp_path / "oscillator-ex2.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(METHOD_NAME.match(r["method"]) for r in rows)
    zeno = [r for r in rows if r["method"].endswith("-zeno")]
    assert {r["method"] for r in zeno} == {"relaxed-rk4-zeno"} and all(r["kind"] == "relaxed" for r in zeno)
    plain = {(r["h"], r["eps"]): r for r in rows if r["method"] == "relaxed-rk4"}
    pairs = [(z, plain[(z["h"], z["eps"])]) for z in zeno if (z["h"], z["eps"]) in plain]
    assert pairs
    for z, p in pairs:
        assert z["status"] == p["status"] == "finished"
        # Far fewer transitions: resting instead of chattering (each rest costs a stick and a release).
        assert int(z["transitions"]) * 10 < int(p["transitions"])
    smallest_eps = min(pairs, key=lambda zp: float(zp[0]["eps"]))
    z, p = smallest_eps
    assert float(z["error"]) < float(p["error"]) and float(z["error"]) < 1e-6


def test_zeno_rows_count_in_targets_only_where_asked():
    rows = [_row("relaxed-rk4", "relaxed", 2e-6, 0.1), _row("relaxed-rk4-zeno", "relaxed", 1e-7, 0.01),
            _row("ps", "ps", 5e-7, 1.0)]
    both, plain = evaluate_targets(rows, [Target("all", 1e-6, "ps", 10.0),
                                          Target("plain", 1e-6, "ps", 10.0, relaxed="plain")])
    assert both.ratio == pytest.approx(100.0) and both.met and "Zeno continuation" in both.note
    assert plain.relaxed_time is None and plain.met is False


def test_zeno_run_rejected_on_a_case_without_the_variant():
    with pytest.raises(BenchError, match="no Zeno continuation variant"):
        run_one(make_case("bouncing-ball", quick=True), RunSpec("relaxed", "relaxed-rk4-zeno", 1e-2, 1e-6, zeno=True),
                repeats=1)


def test_bench_rejects_bad_input(capsys):
    assert main(["bench", "work-precision", "--case", "nope", "--quick"]) == 2
    err = capsys.readouterr().err
    assert "unknown case 'nope'" in err and "oscillator-ex1" in err and "double-pendulum" in err
    assert main(["bench", "work-precision", "--case", "bouncing-ball", "--repeats", "0"]) == 2
    assert "--repeats must be >= 1" in capsys.readouterr().err
    with pytest.raises(BenchError, match="no Paoli-Schatzman baseline"):
        run_one(make_case("bouncing-ball", quick=True), RunSpec("ps", "ps", 1e-3), repeats=1)


def test_aiming_lands_with_fewer_trial_steps_than_halving():
    from legsim.bench.overhead import landing_costs
    from legsim.systems.fast import make_oscillator_example

    system, x0, _ = make_oscillator_example("ex1")
    costs = landing_costs(system, x0, "free", 12.0, 1e-2, 1e-6)
    assert costs["halve"]["transitions"] == costs["aim"]["transitions"] >= 4
    # Halving from h = 1e-2 to a depth below 1e-6 m at ~30 m/s takes ~log2(h v / eps) ~ 18 trials
    # per landing at least; aiming on the interpolant needs about one.
    assert costs["halve"]["trial_steps_per_transition"] > 10
    assert costs["aim"]["trial_steps_per_transition"] < 2
    assert costs["aim"]["extra_field_evals_per_transition"] < costs["halve"]["extra_field_evals_per_transition"]
