"""The pronk hopper's compiled twins (robots/pronk_hopper_twin.py) and Raibert's controller on
the compiled path (``PronkRaibert.compiled_record``).

The reference is the Python path. The twins do the Python callables' IEEE operations in the same
order (the leg length as the square root of a sum and the dot products written out on both
paths, the controller's scalar rules compiled from their Python source), so their values are
equal to the bit, and so are whole runs: the tests compare exactly (tolerance 0).
"""

import contextlib
import math

import legsim.compiled.visit as visit
import numpy as np
import pytest
from legsim.robots import pronk_hopper, pronk_hopper_twin
from legsim.robots.pronk_hopper import BELOW_GROUND, LEGS, MODES, PronkHopper, state_names
from legsim.robots.raibert_pronk import RECORD_NAMES, PronkRaibert

import legsim.compiled as compiled
from legsim.compiled import without_compiled
from legsim.errors import ModelBreakdown
from legsim.relaxed import simulate
from legsim.scene import load_scene

from .test_twins import assert_same_run

RNG = np.random.default_rng(30)
T_FINAL = 3.0  # s: 20 transitions of the pronk_raibert scene, each leg's stance measured 4 times


def random_state(stance: tuple[str, ...]) -> np.ndarray:
    """A state of the mode with legs ``stance``: body near its hopping height, flying legs'
    angles, footholds near the body (feet from 0.3 m above to 0.3 m below the ground)."""
    body = [RNG.uniform(-1.0, 1.0), RNG.uniform(0.7, 1.3), RNG.uniform(-0.3, 0.3), *RNG.uniform(-2.0, 2.0, 3)]
    flying = RNG.uniform(-0.6, 0.6, len(LEGS) - len(stance))
    feet = body[0] + RNG.uniform(-0.5, 0.5, len(stance))
    return np.array([*body, *flying, *feet])


def scene_parts(*overrides: str):
    scene = load_scene("pronk_raibert", [f"integrator.t_final={T_FINAL}", *overrides])
    return scene, scene.model.system, scene.model.info["pronk_hopper"]


def gains(**changes: float) -> dict[str, float]:
    """The pronk_raibert scene's controller parameters, stance_time resolved (s)."""
    values = {"speed": 1.5, "k_x": 0.1, "k_swing": 20.0, "kp_attitude": 900.0, "kd_attitude": 60.0}
    return values | {"stance_time": math.pi * math.sqrt(1.0 / (2 * 250.0))} | changes


@pytest.mark.parametrize("controlled", [False, True], ids=["no-control", "raibert"])
@pytest.mark.parametrize("mode", list(MODES))
def test_twin_computes_the_python_field_guards_and_resets(mode, controlled):
    scene, system, hopper = scene_parts()
    controller = scene.control if controlled else None
    if controlled:
        controller.stance_time = {"left": 0.13, "right": 0.17}  # each leg's own T_s reaches the twin
    data = system.mode_data(mode)
    twin = data.mode.compiled
    twin.controls(controller)(twin.params)  # the record, as Python writes it at an entry
    for x in through_the_ground(MODES[mode]):
        assert past_the_ground(hopper, MODES[mode], x) and np.all(np.isnan(twin.guards(x, twin.params)))
    for _ in range(200):
        x = random_state(MODES[mode])
        u = None if controller is None else controller(mode, 0.0, x)
        assert np.array_equal(twin.field(0.0, x, twin.params), data.mode.field(0.0, x, u))
        guards = twin.guards(x, twin.params)
        if past_the_ground(hopper, MODES[mode], x):
            assert np.all(np.isnan(guards))
            continue
        assert np.array_equal(guards, [guard(x) for guard in data.guards])
        for e, reset in enumerate(data.resets):
            image = twin.resets(x, twin.params, e)
            try:
                expected = reset(x.copy())
            except ModelBreakdown:  # a foot landing below the ground: Python decides
                assert np.isnan(image).any()
                continue
            assert np.array_equal(image, expected)


def through_the_ground(stance: tuple[str, ...]) -> list[np.ndarray]:
    """For each flying leg, a state with its foot 0.255 m under the ground (psi = 0.3 rad, body
    0.7 m high) and sinking at 0.1 m/s, the other flying leg's foot in the air (psi = 1.4 rad)."""
    flying = [leg for leg in LEGS if leg not in stance]
    states = []
    for leg in flying:
        psi = [0.3 if other == leg else 1.4 for other in flying]
        states.append(np.array([0.0, 0.7, 0.0, 1.0, -0.1, 0.0, *psi, *(0.2 for _ in stance)]))
    return states


def past_the_ground(hopper: PronkHopper, stance: tuple[str, ...], x: np.ndarray) -> bool:
    """Whether a flying foot is below ``BELOW_GROUND`` with its touchdown guard negative by its
    rate (max(height, rate) = rate < 0): where the Python touchdown is a ModelBreakdown, the
    twin's domain ends (``pronk_hopper_twin``)."""
    names = state_names(stance)
    for leg in LEGS:
        if leg not in stance:
            foot, rate = hopper.foot_in_flight(leg, x, x[names.index(f"psi_{leg}")])
            if foot[1] < -BELOW_GROUND and foot[1] < rate < 0.0:
                return True
    return False


def test_compiled_record_carries_the_controllers_values_now():
    scene, _, hopper = scene_parts()
    controller = scene.control
    controller.reset("both", 1.0, np.zeros(8))
    controller.reset("aerial", 1.25, np.zeros(8))  # both legs stood 0.25 s
    record = dict(zip(RECORD_NAMES, controller.compiled_record(hopper), strict=True))
    assert record["T_s_left"] == record["T_s_right"] == 0.25
    assert (record["k_swing"], record["kp_attitude"], record["kd_attitude"]) == (20.0, 900.0, 60.0)
    assert (record["speed"], record["k_x"], record["l"], record["k"]) == (1.5, 0.1, 1.0, 250.0)
    assert controller.compiled_record(object()) is None  # another robot's model
    other = PronkHopper(m=1.0, I=1.0, k=250.0, l=1.0, d=0.8, g=9.81)
    assert controller.compiled_record(other) is None  # hips spaced otherwise: the twin's geometry differs


@contextlib.contextmanager
def kernel_calls(monkeypatch):
    """A list that gets an entry at every call of the kernel from Python (a visit Python entered,
    or an entry it hands over)."""
    calls = []
    real_visit, real_entry = compiled.run_visit_compiled, compiled.enter_compiled
    with monkeypatch.context() as m:
        m.setattr(compiled, "run_visit_compiled", lambda *a: calls.append(1) or real_visit(*a))
        m.setattr(compiled, "enter_compiled", lambda *a: calls.append(1) or real_entry(*a))
        yield calls


def kernel_run(monkeypatch, system, control, x0, mode="aerial", t_final=T_FINAL, h=1e-3, eps=1e-7):
    """The run (rk4, aimed landing: the scene's settings) and how often the kernel was called."""
    with kernel_calls(monkeypatch) as calls:
        ex = simulate(system, x0.copy(), mode, t_final, h, eps, "rk4", control, landing="aim")
    return ex, len(calls)


def test_pronk_raibert_scene_runs_compiled_as_on_the_python_path(monkeypatch):
    # Python enters every mode (resetting the controller, writing its record); the kernel takes
    # each visit's steps. Each leg's T_s changes at each of its liftoffs, which only a record
    # written at every entry follows.
    runs = []
    for python in (False, True):
        scene, system, _ = scene_parts()
        controller = scene.control  # a new controller at each access
        ex, n_kernel = kernel_run(
            monkeypatch, without_compiled(system) if python else system, controller, scene.initial_state
        )
        runs.append((ex, n_kernel, controller.memory()))
    (fast, n_fast, memory_fast), (slow, n_slow, memory_slow) = runs
    assert fast.status == "finished" and len(fast.transitions) >= 16
    assert n_slow == 0 and n_fast == len(fast.segments)  # every visit's steps in the kernel
    assert_same_run(fast, slow, tol=0.0)
    np.testing.assert_array_equal(memory_fast, memory_slow)
    initial = gains()["stance_time"]
    assert np.all(np.abs(memory_fast - initial) > 1e-3)  # the record's T_s changed from its first value


def test_a_record_written_only_at_the_first_entry_would_part_from_the_python_path(monkeypatch):
    # The stateful check above can fail: twins that keep each mode's first record (the initial
    # T_s) place the feet elsewhere from the second flight on.
    written = set()
    real_write = pronk_hopper_twin._write_record

    def write_once(p, record):
        if id(p) not in written:
            written.add(id(p))
            real_write(p, record)

    scene, system, _ = scene_parts()
    slow, _ = kernel_run(monkeypatch, without_compiled(system), scene.control, scene.initial_state)
    scene, system, _ = scene_parts()
    monkeypatch.setattr(pronk_hopper_twin, "_write_record", write_once)
    stale, n_kernel = kernel_run(monkeypatch, system, scene.control, scene.initial_state)
    assert n_kernel > 0
    assert np.max(np.abs(stale.final_state - slow.final_state)) > 1e-3


def test_the_uncontrolled_hopper_runs_compiled_as_on_the_python_path(monkeypatch):
    # Pitched, the legs land and leave one at a time: the kernel crosses the four transitions itself.
    hopper = PronkHopper(m=1.0, I=1.0, k=30.0, l=1.0, d=1.0, g=9.81)
    start = {**pronk_hopper.INITIAL_STATE, "theta": 0.1}
    x0 = np.array([start[name] for name in state_names(())])
    fast, n_fast = kernel_run(monkeypatch, hopper.system(), None, x0, t_final=0.62, eps=1e-6)
    slow, n_slow = kernel_run(monkeypatch, without_compiled(hopper.system()), None, x0, t_final=0.62, eps=1e-6)
    assert fast.status == "finished" and len(fast.transitions) == 4
    assert n_slow == 0 and 0 < n_fast < len(fast.segments)  # after each mode's first entry the kernel crossed
    assert_same_run(fast, slow, tol=0.0)


def test_a_foot_landing_below_the_ground_ends_both_paths_alike(monkeypatch):
    # Low and rising, the legs far forward: they swing down through the ground while the body
    # rises (the touchdown guard's rate does not see the swing); at the apex the rate turns
    # negative with the left foot 0.18 m under: the twin's guards are nan, Python takes the step.
    overrides = (
        "initial.state.z=0.75",
        "initial.state.zd=1.0",
        "initial.state.psi_left=1.2",
        "initial.state.psi_right=1.2",
    )
    fallbacks = []
    real_rest = visit._python_rest
    monkeypatch.setattr(visit, "_python_rest", lambda *a: fallbacks.append(1) or real_rest(*a))
    runs = []
    for python in (False, True):
        scene, system, _ = scene_parts(*overrides)
        runs.append(
            kernel_run(monkeypatch, without_compiled(system) if python else system, scene.control, scene.initial_state)
        )
    (fast, n_fast), (slow, _) = runs
    assert n_fast > 0 and fallbacks == [1]
    assert fast.status == "model_breakdown" and "left foot is 0.184 m below the ground" in fast.message
    assert (fast.status, fast.message, fast.t_end) == (slow.status, slow.message, slow.t_end)
    assert np.array_equal(fast.final_state, slow.final_state) and not fast.transitions
    assert fast.counters["steps"] == slow.counters["steps"]
    # The kernel's trial into the nan guards is taken again by Python: rk4's three later stages
    # count twice (the first is the accepted point's field, which both reuse).
    assert fast.counters["field_evals"] == slow.counters["field_evals"] + 3


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda: PronkRaibert(PronkHopper(1.0, 1.0, 250.0, 1.0, 0.8, 9.81), gains()), id="other-hips"),
        pytest.param(lambda: lambda t, x: np.zeros(4), id="plain-function"),
    ],
)
def test_a_control_the_twin_cannot_compute_runs_on_the_python_path(monkeypatch, make):
    scene, system, _ = scene_parts()
    fast, n_kernel = kernel_run(monkeypatch, system, make(), scene.initial_state, t_final=1.0)
    slow, _ = kernel_run(monkeypatch, without_compiled(system), make(), scene.initial_state, t_final=1.0)
    assert n_kernel == 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)


def test_a_controller_of_another_stiffness_is_computed_with_its_own(monkeypatch):
    # The record carries the controller's k and l: a controller made for a stiffer hopper limits
    # its torques by its own spring on both paths.
    def make():
        return PronkRaibert(PronkHopper(1.0, 1.0, 400.0, 1.0, 1.0, 9.81), gains())

    scene, system, _ = scene_parts("initial.state.theta=0.05")
    fast, n_kernel = kernel_run(monkeypatch, system, make(), scene.initial_state, t_final=1.0)
    slow, _ = kernel_run(monkeypatch, without_compiled(system), make(), scene.initial_state, t_final=1.0)
    assert n_kernel > 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)
    own, _ = kernel_run(monkeypatch, system, scene.control, scene.initial_state, t_final=1.0)
    assert np.max(np.abs(own.final_state - fast.final_state)) > 1e-6  # the stiffness in the record counts


def test_bench_case_runs_its_compiled_family_in_the_kernel(monkeypatch):
    # `legsim bench robots --case pronk-raibert`: its compiled family runs in the kernel, the
    # Python path's best (DOP853, dense landing) does not; both reach the reference.
    from legsim.bench import robots

    case = robots.make_robot_case("pronk-raibert", quick=True)
    specs = robots.case_sweep(case, quick=True)
    assert {spec.kind for spec in specs} == {"relaxed", "relaxed-python", "solve_ivp"}
    rows = {}
    for kind, method, landing in (
        ("relaxed", "relaxed-dopri5", "aim"),
        ("relaxed-python", "relaxed-dop853-dense", "dense"),
    ):
        spec = robots.RunSpec(kind, method, 0.1, 1e-10, 1e-8, landing)
        with kernel_calls(monkeypatch) as calls:
            rows[kind] = (robots.run_one(case, spec, 1), len(calls))
    (fast, n_fast), (slow, n_slow) = rows["relaxed"], rows["relaxed-python"]
    assert n_fast > 0 and n_slow == 0
    assert fast.transitions == slow.transitions
    # measured 1.05e-7 (dopri5, aimed) against solve_ivp at 1e-12
    assert fast.status == slow.status == "finished" and max(fast.error, slow.error) < 1e-6


class SoftAttitude(PronkRaibert):
    """A law the twin does not know: the stance torques halved in ``__call__``."""

    def __call__(self, mode, t, x):
        u = super().__call__(mode, t, x)
        u[2:] *= 0.5
        return u


class ShiftedPlacement(PronkRaibert):
    """A law the twin does not know: every touchdown angle 0.05 rad further forward."""

    def target_angle(self, leg, theta, xd):
        return super().target_angle(leg, theta, xd) + 0.05


@pytest.mark.parametrize("law", [SoftAttitude, ShiftedPlacement])
def test_a_subclass_that_changes_the_law_runs_on_the_python_path(monkeypatch, law):
    # The twin computes PronkRaibert's law from its record: a subclass overriding __call__ or
    # target_angle must not get a record, else the kernel silently runs the base class's law.
    scene, system, hopper = scene_parts("initial.state.theta=0.05")
    fast, n_kernel = kernel_run(monkeypatch, system, law(hopper, gains()), scene.initial_state, t_final=1.0)
    slow, _ = kernel_run(monkeypatch, without_compiled(system), law(hopper, gains()), scene.initial_state, t_final=1.0)
    assert n_kernel == 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)


class RightFirstMemory(PronkRaibert):
    """The same law, its memory listed right leg first (``memory`` is the orbit search's view of
    the controller, not what its law reads): the twin must still compute the law."""

    def memory(self):
        return super().memory()[::-1]

    def restore(self, mode, memory):
        super().restore(mode, np.asarray(memory)[::-1])


def test_the_record_carries_each_legs_stance_time_as_the_law_reads_it(monkeypatch):
    # Pitched, the legs' stances differ, so their T_s differ: a record taking them in the
    # memory's order would swap the legs' foot placements.
    scene, system, hopper = scene_parts("initial.state.theta=0.05")
    fast, n_kernel = kernel_run(monkeypatch, system, RightFirstMemory(hopper, gains()), scene.initial_state)
    slow, _ = kernel_run(monkeypatch, without_compiled(system), RightFirstMemory(hopper, gains()), scene.initial_state)
    assert n_kernel > 0 and fast.status == "finished"
    assert_same_run(fast, slow, tol=0.0)
