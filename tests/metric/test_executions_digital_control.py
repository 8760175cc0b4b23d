"""Paper 000 Section V-A: the digital control system, where nearby executions take different
mode sequences and only the quotient metric sees them as close.

The resets are the identity and the four domains (third quadrant, xi2 <= 0, xi1 <= 0, the
plane) glue into the plane: a chord from a point of mode "2" (xi1 < 0 < xi2 near the origin)
to one of mode "1" (xi2 < 0 < xi1) crosses either the third quadrant (through mode "0") or
the first (through mode "3"), so the quotient distance is the planar distance |y - z| at every
instant, whatever the modes (the paper: "equal to that between the trajectories of the
discontinuous vector field"). With eps = 0 (exact executions) rho is therefore
sup_t |y_delta(t) - z_delta(t)|, linear in delta, while a metric charging 1 for a mode
mismatch stays above 1.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import simulate
from legsim.metric import distances, rho, trajectory_space_distance
from legsim.systems import digital_control as dc

T_END = 2.0
DELTAS = np.array([1e-1, 3e-2, 1e-2, 3e-3, 1e-3])


def _pair(delta: float):
    x0 = dc.nominal_initial_state()
    return dc.make_reference(x0 + np.array([-delta, 0.0])), dc.make_reference(x0 + np.array([0.0, -delta]))


def _times(y, z, delta: float) -> np.ndarray:
    # Dense where the two executions sit in different modes (an interval of length O(delta)).
    events = np.array(y.transition_times + z.transition_times)
    return np.union1d(np.linspace(0.0, T_END, 201), np.linspace(events.min() - delta, events.max() + delta, 201))


def test_y_and_z_take_different_mode_sequences():
    for delta in DELTAS:
        y, z = _pair(delta)
        assert y.mode_sequence == ["0", "2", "3"]
        assert z.mode_sequence == ["0", "1", "3"]


@pytest.mark.parametrize("delta", DELTAS[[0, 2, 4]])
def test_quotient_distance_is_the_planar_distance_at_every_instant(delta):
    y, z = _pair(delta)
    times = _times(y, z, delta)
    d = distances(dc.make_system(), y, z, times, 0.0)
    planar = np.linalg.norm(y.states(times) - z.states(times), axis=1)
    assert np.any(np.array(y.modes(times)) != np.array(z.modes(times)))  # the window is sampled
    np.testing.assert_allclose(d, planar, rtol=1e-9, atol=1e-12)


def test_rho_goes_to_zero_linearly_while_trajectory_space_distance_stays_above_one():
    system = dc.make_system()
    rhos, window, traj = [], [], []
    for delta in DELTAS:
        y, z = _pair(delta)
        times = _times(y, z, delta)
        d = distances(system, y, z, times, 0.0)
        mismatch = np.array(y.modes(times)) != np.array(z.modes(times))
        rhos.append(d.max())
        window.append(d[mismatch].max())
        traj.append(trajectory_space_distance(y, z, times))
    slope = np.polyfit(np.log(DELTAS), np.log(rhos), 1)[0]
    slope_window = np.polyfit(np.log(DELTAS), np.log(window), 1)[0]
    assert slope == pytest.approx(1.0, abs=0.02)
    assert slope_window == pytest.approx(1.0, abs=0.05)
    # The sup is the initial offset |(-delta, 0) - (0, -delta)| = sqrt(2) delta: the flow contracts.
    np.testing.assert_allclose(rhos, math.sqrt(2) * DELTAS, rtol=1e-9)
    assert min(traj) >= 1.0


def test_relaxed_simulations_of_y_and_z_are_close_in_rho_eps():
    # The same comparison between two relaxed simulations (eps = h = 1e-4, RK4): their mode
    # sequences differ, yet rho^eps is sqrt(2) delta up to O(eps) (the strips delay each
    # crossing by about eps / |xi'| ~ eps).
    system = dc.make_system()
    eps, h = 1e-4, 1e-4
    x0 = dc.nominal_initial_state()
    times = np.linspace(0.0, T_END, 801)
    values = []
    for delta in (1e-1, 3e-2, 1e-2):
        y = simulate(system, x0 + np.array([-delta, 0.0]), "0", T_END, h, eps)
        z = simulate(system, x0 + np.array([0.0, -delta]), "0", T_END, h, eps)
        assert y.mode_sequence == ["0", "2", "3"] and z.mode_sequence == ["0", "1", "3"]
        values.append(rho(system, y, z, times, eps))
        assert trajectory_space_distance(y, z, times) >= 1.0
    np.testing.assert_allclose(values, math.sqrt(2) * np.array([1e-1, 3e-2, 1e-2]), atol=4 * eps)


def test_scenario_script_prints_the_table_and_writes_the_figure(tmp_path, capsys):
    # scenarios/metric_digital_control.py: the table's rho column is the closed form sqrt(2)
    # delta, the trajectory-space column stays above 1, and the figure is a readable PNG; a
    # folder that cannot be made is refused before the sweep.
    import importlib.util
    import os
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scenarios" / "metric_digital_control.py"
    spec = importlib.util.spec_from_file_location("metric_digital_control", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    assert script.main(["--out", str(tmp_path), "--deltas", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = [[float(v) for v in line.split()] for line in lines[1:3]]
    for delta, rho_exact, _, rho_eps, trajectory in rows:
        assert rho_exact == pytest.approx(math.sqrt(2) * delta, rel=1e-4)  # printed to 5 digits
        assert abs(rho_eps - rho_exact) <= 4e-4 and trajectory >= 1.0  # 4 eps, as above
    figure = tmp_path / "metric_digital_control.png"
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(figure).st_mode & 0o777 == 0o666 & ~mask  # like any file the user writes (not 0600)
    assert [f.name for f in tmp_path.iterdir()] == [figure.name]
    with pytest.raises(SystemExit):
        script.main(["--out", "/proc/no/such/folder", "--deltas", "2"])
    assert "cannot create the folder" in capsys.readouterr().err
