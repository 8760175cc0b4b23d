"""benchmarks/mujoco_compare.py: the MJCF it writes from the URDF, and, where MuJoCo's own venv
exists (``LEGSIM_MUJOCO_PYTHON``, default /work/mujoco-venv/bin/python), that the two models
agree and that each simulator's error against its own reference shrinks with its step. No
timing is asserted."""

from __future__ import annotations

import importlib.util
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
MUJOCO_PYTHON = os.environ.get("LEGSIM_MUJOCO_PYTHON", "/work/mujoco-venv/bin/python")


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("mujoco_compare", ROOT / "benchmarks" / "mujoco_compare.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_mjcf_has_legsim_order_point_feet_and_the_pd(bench):
    order = ("x", "z", "pitch", "front_hip", "front_knee", "hind_hip", "hind_knee")
    xml = bench.mjcf(
        ROOT / "scenarios" / "quadruped.urdf",
        order,
        {"hind_foot": 0.8, "front_foot": 0.8},
        60.0,
        3.0,
        [0.5, -1.0, -0.5, 1.0],
        order[3:],
        {"hind_knee": (0.15, 10.0)},
    )
    root = ET.fromstring(xml)
    assert tuple(j.get("name") for j in root.iter("joint")) == order
    feet = {g.get("name"): g for g in root.iter("geom") if g.get("type") == "sphere"}
    assert set(feet) == {"hind_foot", "front_foot"}
    assert float(feet["hind_foot"].get("size")) == bench.FOOT_RADIUS
    floor = next(g for g in root.iter("geom") if g.get("type") == "plane")
    assert float(floor.get("pos").split()[2]) == -bench.FOOT_RADIUS  # a foot touches where legsim's point does
    # MuJoCo takes the larger friction of the two geoms: the floor's must not exceed the feet's 0.8.
    assert float(floor.get("friction").split()[0]) <= 0.8 == float(feet["hind_foot"].get("friction").split()[0])
    masses = [float(i.get("mass")) for i in root.iter("inertial")]
    assert sum(masses) == pytest.approx(5.0 + 2 * (0.4 + 0.15))
    actuators = list(root.iter("general"))
    assert [a.get("joint") for a in actuators] == list(order[3:])
    assert actuators[0].get("biasprm").split() == ["0", "-60.0", "-3.0"]


@pytest.mark.skipif(not os.path.exists(MUJOCO_PYTHON), reason=f"no MuJoCo venv at {MUJOCO_PYTHON}")
def test_models_agree_and_errors_shrink_with_the_step(bench):
    t_final = 0.5  # the landing (t = 0.18 s) and the first of the settling
    legsim, worker, _robot, _loaded = bench.start(MUJOCO_PYTHON, t_final)
    try:
        assert bench.check_model(legsim, worker, np.random.default_rng(1)) < bench.MASS_TOLERANCE
        m_ref = bench.mujoco_positions(worker, ("RK4", 5e-5), t_final)["q"]
        m_err = [
            bench.error(bench.mujoco_positions(worker, ("implicitfast", dt), t_final)["q"], m_ref)
            for dt in (4e-3, 2e-3, 1e-3)
        ]
        rk4 = bench.error(bench.mujoco_positions(worker, ("RK4", 1e-3), t_final)["q"], m_ref)
        unstable = bench.mujoco_positions(worker, ("RK4", 4e-3), t_final)
    finally:
        worker.close()
    assert m_err[0] > m_err[1] > m_err[2] > rk4 > 0.0, (m_err, rk4)
    assert bench.error(unstable["q"], m_ref) > 1.0  # RK4 diverges on the stiff PD at 4 ms
    l_ref = legsim.run(("rk4", 1e-4, 1e-8, None), record=True)[1]  # run() checks: no Python step
    l_err = [
        bench.error(legsim.run(config, record=True)[1], l_ref)
        for config in (("ros34pw2", 2e-2, 1e-2, 1e-1), ("ros34pw2", 2e-2, 1e-3, 1e-2), ("ros34pw2", 2e-2, 1e-5, 1e-4))
    ]
    assert l_err[0] > l_err[1] > l_err[2] > 0.0, l_err
    # The two contact models differ (rigid impact against soft contact): more than either's error.
    assert bench.error(m_ref, l_ref) > max(m_err[-1], l_err[-1])
