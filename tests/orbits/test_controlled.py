"""Orbits of controlled scenes: the return map on (section state, controller memory).

The SLIP hopper under Raibert's foot placement (``slip_raibert``, a ``ControlLaw``) keeps three
values across transitions: the last stance's duration T_s, the stance's touchdown time and a
stance flag (both 0 in flight, where the section lies). Its gait is searched with them among
the unknowns and checked against independent evidence: the scene's own closed-loop run (100 hops), which must
settle on the orbit at the rate its leading multiplier predicts, and the Python-API search with
T_s held at its value on the gait (docs/robots.md), whose multipliers are those of the augmented
map's state block. The searches here run at the scene's own rk4 steps, the run's discretization.
"""

import itertools
from dataclasses import replace

import numpy as np
import pytest

from legsim.commands.orbit import format_orbit
from legsim.control import Controller
from legsim.crossings import first_crossing
from legsim.orbits import OrbitError, OrbitProblem, Section, find_orbit, jacobian_fd, jacobian_saltation
from legsim.orbits.returns import ReturnMap
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene

APEX = Section.level("flight", "zd", 0.0, "decreasing")


@pytest.fixture(scope="module")
def scene():
    # The search at the run's own rk4 steps (the scene's [orbit.integrator] is finer): the run
    # settles on the orbit of its own discretization, which the tests below compare it with.
    return load_scene("slip_raibert", ['orbit.integrator={method="rk4", h=1e-3, eps=1e-7, landing="aim"}'])


@pytest.fixture(scope="module")
def settings(scene):
    return problem_from_scene(scene)


@pytest.fixture(scope="module")
def orbit(settings):
    return find_orbit(settings.problem, settings.guess, **settings.solver).raise_for_status()


@pytest.fixture(scope="module")
def run_apexes(scene, settings):
    """(z, psi, xd, T_s) at every apex of the scene's run after its first stance, T_s the
    stance before it from the transition records' entry times (as the controller measures it),
    shape (hops, 4); and the run's energy at the last apex (J)."""
    ex = scene.simulate()
    assert ex.status == "finished"
    rows = []
    for k, seg in enumerate(ex.segments):
        if k < 2 or seg.mode != "flight" or len(seg.t) < 2:
            continue
        hit = first_crossing(seg, settings.problem.bound.s, -1, seg.t[0])
        if hit is not None:
            touchdown, liftoff = ex.transitions[k - 2], ex.transitions[k - 1]
            rows.append(np.r_[hit[1][1:4], liftoff.exit_time - touchdown.exit_time])
    apexes = np.array(rows)
    energy = scene.model.system.energy("flight", np.r_[0.0, apexes[-1, :3], 0.0])
    return apexes, float(energy)


def as_row(result):
    """(z, psi, xd, T_s) of an orbit."""
    return np.r_[result.fixed_point[1:4], result.memory[:1]]


def held_stance_time(law, stance_time):
    """A plain control ``u(t, x)``: the law's flight input with T_s held at ``stance_time`` (s),
    its compiled function evaluated from Python."""
    p = law.params_for("flight")
    memory = np.array([stance_time, 0.0, 0.0])

    def control(t, x):
        u = np.zeros(1)
        law.control(float(t), np.ascontiguousarray(x[:5], dtype=float), memory, p, u)
        return u

    return control


def test_the_gait_reports_the_stance_time_with_its_unit(orbit):
    payload = orbit.to_json()
    assert payload["memory_units"] == {"T_s": "s", "t_touchdown": "s", "stance": ""}
    assert orbit.jacobian_method == "fd" and "does not follow the controller's memory" in orbit.message
    # z, psi, xd and the memory: six multipliers, one of them the energy's 1; the touchdown time
    # and the stance flag are set at the stance's entry before they are read (0 at the section
    # whatever they start at): their multipliers are exactly 0.
    assert len(orbit.multipliers) == 6
    assert abs(orbit.multipliers[0] - 1.0) < 1e-6 and orbit.stable
    assert orbit.memory[1:].tolist() == [0.0, 0.0] and sorted(np.abs(orbit.multipliers))[:2] == [0.0, 0.0]


def test_the_gaits_return_map_is_differentiable_and_its_jacobian_unchanged(settings, orbit):
    # No false positive of the kink check on a smooth map (its columns' defects are 3e-6 .. 3e-5
    # of the floor), and the reported Jacobian is the plain central-difference one, bit for bit.
    assert orbit.differentiable is True and orbit.kinked_coordinates == ()
    # The one warning is the map's refinement: the map moves by the integrator's error (3.6e-8
    # at h/2, eps/2) beyond tol 1e-9, while its noise is rounding (which row is noisiest at that
    # level is rounding's choice, not asserted); no kink warning.
    assert [w.split(" (")[0] for w in orbit.warnings] == ["at finer settings"]
    assert orbit.map_accuracy.refinement > 1e-9 and orbit.map_accuracy.noise < 1e-13
    assert orbit.multipliers_forward is None and orbit.stable is True
    step = settings.solver.get("fd_step")
    plain = jacobian_fd(settings.problem, orbit.fixed_point, orbit.parameters, step, memory=orbit.memory)
    assert np.array_equal(orbit.jacobian, plain)


def test_the_report_names_the_memory_with_its_unit(orbit):
    text = format_orbit(orbit.to_json(), "slip_raibert")
    # names padded to the longest, t_touchdown
    assert f"  T_s         =  {orbit.memory[0]:.10g} s  (controller memory)" in text
    assert "(fd Jacobian," in text


def test_the_memory_at_the_return_is_the_stance_the_return_took(settings, orbit):
    # An independent reading: the return's own transition records.
    ret = ReturnMap(settings.problem)(orbit.fixed_point, memory=orbit.memory + 0.01)
    touchdown, liftoff = ret.transitions
    assert ret.memory_start == pytest.approx(orbit.memory + 0.01, abs=0)
    assert ret.memory_end[0] == pytest.approx(liftoff.exit_time - touchdown.exit_time, abs=1e-15)


def test_the_closed_loop_run_settles_on_the_orbit(settings, orbit, run_apexes):
    # The run's energy drifts by the integrator's error (~1e-7 J over 100 hops) along the
    # family of gaits the energy labels (multiplier 1), so its last apex is compared with the
    # gait at the run's final energy. Off that family the first apex error (~4e-2) has shrunk by
    # |mu_1|^98 < 1e-57: what is left is the orbit's own error, residual <= tol over
    # (1 - |mu_1|) (Newton stops at the residual tol of P(x) - x), twice that as the bound.
    apexes, energy = run_apexes
    same_energy = find_orbit(
        replace(settings.problem, energy=energy), orbit.fixed_point, **{**settings.solver, "memory": orbit.memory}
    ).raise_for_status()
    mu = orbit.spectral_radius
    tol = settings.solver["tol"]
    bound = np.max(np.abs(apexes[0] - as_row(orbit))) * mu ** (len(apexes) - 1) + 2 * tol / (1 - mu)
    assert len(apexes) >= 99
    assert np.max(np.abs(apexes[-1] - as_row(same_energy))) < bound


def test_the_leading_multiplier_is_the_runs_contraction_rate(orbit, run_apexes):
    # While the apex error is between 1e-7 (above the energy drift's 1e-9) and 3e-3 (small enough
    # to be linear: the quadratic term adds ~e to the ratio), successive errors shrink by
    # |mu_1|, up to the second multiplier's share (|mu_2 / mu_1|)^k < 0.7% from the third hop on.
    apexes, _ = run_apexes
    errors = np.max(np.abs(apexes - as_row(orbit)), axis=1)
    linear = [k for k in range(2, len(errors) - 1) if errors[k + 1] > 1e-7 and errors[k] < 3e-3]
    assert len(linear) >= 5
    ratios = errors[[k + 1 for k in linear]] / errors[linear]
    assert np.max(np.abs(ratios / orbit.spectral_radius - 1.0)) < 0.01


def test_holding_the_stance_time_gives_the_same_gait_but_other_multipliers(scene, settings, orbit, run_apexes):
    # The Python-API search of docs/robots.md: the controller's flight law with T_s held at
    # its value on the gait in every flight, Jacobian by saltation matrices.
    held = OrbitProblem(
        system=scene.model.system,
        section=APEX,
        h=1e-3,
        eps=1e-7,
        landing="aim",
        t_max=3.0,
        control=held_stance_time(scene.control, float(orbit.memory[0])),
        cyclic=("x",),
        energy=13.253,
        trivial_multipliers=1,
    )
    result = find_orbit(held, settings.guess, tol=1e-9).raise_for_status()
    # docs/robots.md's numbers, and the augmented search's apex and period to the searches' tol
    assert result.fixed_point[1:4] == pytest.approx([1.2435, 0.1048, 1.452408], abs=5e-5)
    assert result.fixed_point == pytest.approx(orbit.fixed_point, abs=1e-8)
    assert result.period == pytest.approx(orbit.period, abs=1e-8)
    # Off the gait the two maps differ: the run measures T_s at every liftoff and places the
    # next foot with it, which holding T_s leaves out; the run contracts at the augmented
    # map's rate (0.259), not the held map's (0.232).
    apexes, _ = run_apexes
    errors = np.max(np.abs(apexes - as_row(orbit)), axis=1)
    observed = errors[6] / errors[5]
    assert abs(observed - orbit.spectral_radius) < 1e-3 < abs(observed - result.spectral_radius)


def test_the_saltation_jacobian_refuses_a_controller(settings, orbit):
    ret = ReturnMap(settings.problem)(orbit.fixed_point, memory=orbit.memory)
    with pytest.raises(OrbitError, match="does not follow a controller's memory"):
        jacobian_saltation(settings.problem, ret)
    DP = jacobian_fd(settings.problem, orbit.fixed_point, memory=orbit.memory)
    assert DP.shape == (settings.problem.dim + 3,) * 2


def test_a_memory_guess_of_the_wrong_size_is_refused(settings):
    with pytest.raises(
        OrbitError, match=r"memory guess must be 3 finite number\(s\) \(\['T_s', 't_touchdown', 'stance'\]\)"
    ):
        find_orbit(settings.problem, settings.guess, memory=[0.1, 0.2])


class Integrator(Controller):
    """A controller with state it does not declare."""

    def __init__(self) -> None:
        self.total = 0.0

    def reset(self, mode, t, x):
        self.total += x[0]

    def __call__(self, mode, t, x):
        return np.zeros(1)


def test_a_controller_without_declared_memory_is_refused(scene):
    with pytest.raises(OrbitError, match="controller Integrator does not declare its memory") as info:
        OrbitProblem(system=scene.model, section=APEX, h=1e-3, eps=1e-7, controller=lambda model: Integrator())
    assert info.value.key == "controller"


def test_a_stateless_controller_adds_no_unknowns():
    # joint_pd declares an empty memory: the search runs it as it is, on the state alone.
    scene = load_scene("quadruped_stand")
    section = Section.level(scene.initial_mode, "zd", 0.0, "decreasing")
    plain = OrbitProblem(system=scene.model, section=section, h=1e-3, eps=1e-4, cyclic=("x",))
    controlled = replace(plain, controller=lambda model: scene.make_controller())
    assert controlled.memory_names == () and controlled.memory_guess.shape == (0,)
    assert controlled.unknown_names == plain.unknown_names


def test_a_fixed_memory_value_is_held_at_its_guess(settings, orbit):
    # Fixing T_s at its value on the gait leaves the same gait to find, with T_s no unknown (its
    # periodicity row stays: an overdetermined, consistent system).
    held = replace(settings.problem, fixed=("T_s",))
    assert held.unknown_names == ["z", "psi", "xd", "t_touchdown", "stance"]
    result = find_orbit(held, orbit.fixed_point + 1e-3 * np.r_[0, 1, 0, 1, 0], memory=orbit.memory, jacobian="fd")
    assert result.raise_for_status().memory.tolist() == orbit.memory.tolist()
    assert result.fixed_point == pytest.approx(orbit.fixed_point, abs=1e-8)
    with pytest.raises(OrbitError, match=r"fixed coordinate\(s\) \['T_x'\] are not coordinates"):
        replace(settings.problem, fixed=("T_x",))


@pytest.mark.slow
def test_the_quadrupeds_run_settles_on_its_pronk_from_apex_to_apex():
    """The Raibert-controlled quadruped's 20 s in-place pronk settles: from one apex to the next
    its configuration changes by 1.9e-2 at first and by about 1e-5 at the end, and its thrust
    settles with it. The gait it settles on is not vouched for as an orbit: the return map jumps
    at the symmetric gait (tests/orbits/test_accuracy.py, docs/orbits.md)."""
    scene = load_scene("quadruped_pronk")
    settings = problem_from_scene(scene)
    ex = scene.simulate()
    assert ex.status == "finished"
    n = scene.model.system.mode("flight").dim
    thrust = n + scene.control.memory_names.index("thrust_hind")
    apexes = []  # the state, the controller's memory after the plant's, at each apex
    for k, seg in enumerate(ex.segments):
        hit = first_crossing(seg, settings.problem.bound.s, -1, seg.t[0]) if k and seg.mode == "flight" else None
        if hit is not None:
            apexes.append(hit[1])
    assert len(apexes) >= 40
    config = slice(1, 7)
    steps = [np.max(np.abs(b[config] - a[config])) for a, b in itertools.pairwise(apexes)]
    assert steps[0] > 1e-2 and max(steps[-5:]) < 1e-4
    thrusts = [abs(b[thrust] - a[thrust]) for a, b in itertools.pairwise(apexes)]
    assert max(thrusts[-5:]) < 0.01 * max(thrusts[:5])
