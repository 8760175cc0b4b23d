"""The robot scenes under scenarios/: they load, run (the accurate defaults and the papers'
coarse settings, ``*_paper``) and report energies; what each run must show is checked against
the paper's description."""

import math

import numpy as np
import pytest

from legsim.scene import load_scene, run_summary


def test_pronk_paper_scene_is_the_paper_setup():
    scene = load_scene("pronk_paper")
    assert scene.parameters == dict(m=1.0, I=1.0, k=30.0, l=1.0, d=1.0, g=9.81, psi=pytest.approx(math.pi / 5))
    np.testing.assert_array_equal(scene.initial_state, [0, 1.1, 0, 3.4, 0, 0])
    assert (scene.integrator["method"], scene.integrator["h"], scene.integrator["eps"]) == ("rk4", 1e-3, 1e-2)


@pytest.mark.parametrize("name", ["pronk", "pronk_paper"])
def test_pronk_scene_pronks_and_conserves_energy(name):
    scene = load_scene(name)
    ex = scene.simulate()
    summary = run_summary(ex, scene)
    assert summary["status"] == "finished"
    assert summary["energy_initial"] == pytest.approx(0.5 * 3.4**2 + 9.81 * 1.1, abs=1e-12)
    assert abs(summary["energy_final"] - summary["energy_initial"]) < 1e-8
    assert summary["damping_evals"] == 0 and summary["kkt"] == 0  # model counters of the run
    # pronking: the legs touch down and lift off together; the second leg's guard is crossed
    # while the first one's strip holds the state, so the pair is at most one hold (eps) apart.
    eps = scene.integrator["eps"]
    times = [tr.time for tr in ex.transitions]
    assert len(times) == 8
    assert all(0.0 <= b - a <= eps * (1 + 1e-9) for a, b in zip(times[::2], times[1::2], strict=True))


@pytest.mark.parametrize("name", ["pronk_pitched", "pronk_pitched_paper"])
def test_pitched_pronk_scene_lands_on_the_left_leg_first(name):
    scene = load_scene(name)
    assert scene.initial_state[2] == -0.4
    ex = scene.simulate()
    assert ex.status == "finished" and ex.mode_sequence == ["aerial", "left", "both"]
    summary = run_summary(ex, scene)
    assert abs(summary["energy_final"] - summary["energy_initial"]) < 1e-8


def test_pitched_pronk_ends_before_its_hip_reaches_the_ground():
    # The model has no body-ground contact: the accurate run stops being physical when the left
    # hip reaches the ground, about 1 ms after the scene's t_final; the paper's coarse run
    # gets there later by its strip holds (the sum of its eps-wide holds).
    scene = load_scene("pronk_pitched", overrides=["integrator.t_final=0.6"])
    ex = scene.simulate()
    assert ex.status == "model_breakdown"
    hip = scene.model.info["bridge"].frame_positions(ex.final_state[:3], ["hip_left"])["hip_left"]
    assert 0.0 <= hip[1] < 1e-3  # the left hip at the ground
    assert scene.integrator["t_final"] > 0.44 and 0.44 < ex.t_end < 0.445
    paper = load_scene("pronk_pitched_paper", overrides=["integrator.t_final=0.6"]).simulate()
    strip_time = paper.counters["strip_time"]
    assert paper.status == "model_breakdown" and paper.t_end == pytest.approx(ex.t_end + strip_time, abs=1e-3)


def test_slip_scene_conserves_energy():
    scene = load_scene("slip")
    ex = scene.simulate()
    summary = run_summary(ex, scene)
    assert summary["status"] == "finished" and summary["transitions"] == 4
    assert abs(summary["energy_final"] - summary["energy_initial"]) < 1e-8


def test_double_pendulum_paper_scenes_are_paper_003_fig_2():
    plastic = load_scene("double_pendulum_plastic_paper")
    zeno = load_scene("double_pendulum_zeno_paper")
    for scene in (plastic, zeno, load_scene("double_pendulum_plastic"), load_scene("double_pendulum_zeno")):
        np.testing.assert_allclose(scene.initial_state, np.radians([30, 25, 0, 0]), rtol=0, atol=1e-15)
    for scene in (plastic, zeno):
        assert (scene.integrator["method"], scene.integrator["h"], scene.integrator["eps"]) == ("euler", 1e-3, 0.2)
    assert plastic.effects["stop"]["restitution"] == 0.0 and zeno.effects["stop"]["restitution"] == 0.5

    # Fig. 2c is the paper's relaxed execution: every impact resets to unconstrained motion and
    # the impacts accumulate; past the accumulation the run says it holds the state.
    assert zeno.integrator["continuation"] is False
    ex = zeno.simulate()
    assert ex.status == "finished" and ex.t_end == zeno.integrator["t_final"]
    assert set(ex.mode_sequence) == {"unconstrained"} and len(ex.transitions) > 20
    speeds = [abs(tr.state_before[3]) for tr in ex.transitions]
    assert speeds[8] < 0.05 * speeds[0]  # impacts accumulate: approach speeds fall by about c each
    assert [(w.kind, w.details["transition"]) for w in ex.warnings] == [("accumulation", "bounce_stop")]


@pytest.mark.parametrize("name", ["double_pendulum_plastic", "double_pendulum_plastic_paper"])
def test_plastic_double_pendulum_rests_on_its_stop_and_is_released(name):
    scene = load_scene(name)
    ex = scene.simulate()
    assert ex.status == "finished" and "constrained" in ex.mode_sequence
    assert {"impact_stop", "release_stop"} <= {tr.name for tr in ex.transitions}
    summary = run_summary(ex, scene)
    # plastic impacts only remove energy; the integrators' drift over 10 s is far smaller than their loss
    assert summary["energy_final"] < summary["energy_initial"]


def test_zeno_double_pendulum_comes_to_rest_on_its_stop_and_swings_on():
    # By default each accumulation of impacts ends in the constrained mode, released where
    # eq. (31) changes sign, theta1 = 0 for unit masses and lengths, and link 1 keeps swinging.
    # At the accurate setting the strips' holds are far below 1% of the run: no warning.
    zeno = load_scene("double_pendulum_zeno")
    assert zeno.integrator["continuation"] is True
    ex = zeno.simulate()
    assert ex.status == "finished" and ex.t_end == zeno.integrator["t_final"]
    names = [tr.name for tr in ex.transitions]
    assert names.count("rest_stop") >= 2 and "constrained" in ex.mode_sequence
    releases = [tr for tr in ex.transitions if tr.name == "release_stop"]
    assert len(releases) >= 2 and all(abs(tr.state_before[0]) < 1e-9 for tr in releases)
    assert ex.warnings == []


@pytest.mark.parametrize("name", ["pronk", "pronk_pitched", "slip", "double_pendulum_plastic"])
def test_geometry_is_polylines_of_the_robot(name):
    scene = load_scene(name)
    ex = scene.simulate()
    model = scene.model
    rest_length = scene.parameters.get("l")
    for seg in ex.segments:
        for x in seg.x[:: max(1, len(seg.x) // 5)]:
            parts = model.geometry(seg.mode, x)
            for part, line in parts.items():
                assert line.ndim == 2 and line.shape[1] == 2 and np.all(np.isfinite(line)), part
            for part, line in parts.items():
                if part.startswith("leg_"):
                    hip, foot = line
                    length = np.linalg.norm(hip - foot)
                    stance = part[4:] + "_foot_x" in scene.model.system.state_names(seg.mode)
                    if stance:  # the foot is pinned at its foothold on the ground
                        names = scene.model.system.state_names(seg.mode)
                        assert foot.tolist() == [x[names.index(part[4:] + "_foot_x")], 0.0]
                        assert length <= rest_length + 1e-9
                    else:  # flight: rest length
                        assert length == pytest.approx(rest_length, abs=1e-12)
            if name.startswith("double"):
                link1, link2 = parts["link1"], parts["link2"]
                assert np.linalg.norm(link1[1] - link1[0]) == pytest.approx(1.0, abs=1e-12)
                assert np.linalg.norm(link2[1] - link2[0]) == pytest.approx(1.0, abs=1e-12)
                # the stop lies along link 1's extension (theta2 = 0)
                d1 = link1[1] - link1[0]
                ds = parts["stop"][1] - parts["stop"][0]
                assert abs(d1[0] * ds[1] - d1[1] * ds[0]) < 1e-12 and d1 @ ds > 0
    for line in model.scenery.values():
        assert line.ndim == 2 and line.shape[1] == 2
