"""The hybrid-system model: every construction error is a ModelError naming the mode or
transition at fault, and the read-only views say what the integrator will use."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, ModelError, Transition, simulate
from legsim.graph import reachable_modes


def zero_field(n: int):
    return lambda t, x, u: np.zeros(n)


def two_modes(**kwargs) -> HybridSystem:
    return HybridSystem({"a": Mode(2, zero_field(2)), "b": Mode(2, zero_field(2))}, **kwargs)


# -- Mode and Transition ------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [0, -1, 1.5, True])
def test_mode_dimension_must_be_a_positive_integer(dim):
    with pytest.raises(ModelError, match=rf"^Mode dim must be a positive integer, got {dim!r}"):
        Mode(dim, zero_field(1))


def test_mode_field_must_be_callable():
    with pytest.raises(ModelError, match=r"^Mode field must be callable f\(t, x, u\), got str"):
        Mode(2, "f")


def test_mode_names_must_match_the_dimension_and_be_unique():
    with pytest.raises(ModelError, match=r"^Mode has dim 2 but 1 coordinate names \('z',\)"):
        Mode(2, zero_field(2), names=("z",))
    with pytest.raises(ModelError, match=r"^Mode coordinate names must be unique, got \('z', 'z'\)"):
        Mode(2, zero_field(2), names=("z", "z"))


def test_mode_default_names():
    assert Mode(3, zero_field(3)).names == ("x0", "x1", "x2")


def test_transition_guard_and_reset_must_be_callable():
    with pytest.raises(ModelError, match=r"^transition a->b: guard must be callable guard\(x\) -> float"):
        Transition("a", "b", 1.0)
    with pytest.raises(ModelError, match=r"^transition hop: reset must be callable reset\(x\) -> x' or None"):
        Transition("a", "b", lambda x: 0.0, reset=3, name="hop")
    with pytest.raises(ModelError, match=r"^transition a->b: guard_gradient must be callable or None"):
        Transition("a", "b", lambda x: 0.0, guard_gradient=[1, 0])


def test_transition_ends_must_be_mode_names():
    with pytest.raises(ModelError, match=r"^transition 1->b: source and target must be mode names \(str\)"):
        Transition(1, "b", lambda x: 0.0)


# -- HybridSystem construction ----------------------------------------------------------------
def test_system_needs_a_mapping_of_modes():
    with pytest.raises(ModelError, match=r"^hybrid system: a hybrid system needs at least one mode"):
        HybridSystem({})
    with pytest.raises(ModelError, match=r"^sys: modes must be a mapping name -> Mode, got list"):
        HybridSystem([Mode(1, zero_field(1))], name="sys")
    with pytest.raises(ModelError, match=r"^hybrid system: mode 'a' must be a legsim.Mode, got int"):
        HybridSystem({"a": 1})
    with pytest.raises(ModelError, match=r"^hybrid system: mode names must be non-empty strings, got ''"):
        HybridSystem({"": Mode(1, zero_field(1))})


def test_unknown_source_and_target_modes_are_named():
    with pytest.raises(
        ModelError, match=r"^hybrid system: transition x->a leaves unknown mode 'x' \(modes: \['a', 'b'\]\)"
    ):
        two_modes(transitions=[Transition("x", "a", lambda x: 0.0)])
    with pytest.raises(
        ModelError, match=r"^hybrid system: transition a->zz targets unknown mode 'zz' \(modes: \['a', 'b'\]\)"
    ):
        two_modes(transitions=[Transition("a", "zz", lambda x: 0.0)])


def test_transitions_must_be_transitions():
    with pytest.raises(ModelError, match=r"^hybrid system: transitions must be legsim.Transition, got int"):
        two_modes(transitions=[1])


def test_identity_reset_between_dimensions_is_refused():
    modes = {"a": Mode(2, zero_field(2)), "b": Mode(3, zero_field(3))}
    with pytest.raises(ModelError, match=r"^hybrid system: transition a->b has no reset but changes dimension 2 -> 3"):
        HybridSystem(modes, [Transition("a", "b", lambda x: 0.0)])


def test_field_output_dimension_is_checked_on_the_initial_state():
    with pytest.raises(ModelError, match=r"^hybrid system: field of mode 'a' returned shape \(3,\), expected \(2,\)"):
        HybridSystem({"a": Mode(2, zero_field(3))}, initial=("a", [0.0, 0.0]))


def test_failing_field_is_named():
    with pytest.raises(ModelError, match=r"^hybrid system: field of mode 'a' failed at t=0.0: ZeroDivisionError"):
        HybridSystem({"a": Mode(2, lambda t, x, u: 1 / 0)}, initial=("a", [0.0, 0.0]))


def test_guard_must_return_a_real_scalar():
    with pytest.raises(
        ModelError, match=r"^hybrid system: guard of transition g2 must return a scalar, got shape \(2,\)"
    ):
        two_modes(transitions=[Transition("a", "b", lambda x: np.zeros(2), name="g2")], initial=("a", [0.0, 0.0]))
    with pytest.raises(ModelError, match=r"^hybrid system: guard of transition gn returned nan at x="):
        two_modes(transitions=[Transition("a", "b", lambda x: float("nan"), name="gn")], initial=("a", [0.0, 0.0]))
    with pytest.raises(
        ModelError,
        match=r"^hybrid system: guard of transition gs must return a real number "
        r"\(a float\), got str 'high'",
    ):
        two_modes(transitions=[Transition("a", "b", lambda x: "high", name="gs")], initial=("a", [0.0, 0.0]))
    for value, shown in ((True, "bool True"), (None, "NoneType None")):
        with pytest.raises(
            ModelError, match=rf"guard of transition gb must return a real number \(a float\), got {shown}"
        ):
            two_modes(transitions=[Transition("a", "b", lambda x, v=value: v, name="gb")], initial=("a", [0.0, 0.0]))


def test_reset_output_dimension_is_checked_against_the_target():
    with pytest.raises(
        ModelError,
        match=r"^hybrid system: reset of transition r3 returned shape \(3,\), expected "
        r"\(2,\) for mode 'b'",
    ):
        two_modes(
            transitions=[Transition("a", "b", lambda x: 1.0, lambda x: np.zeros(3), name="r3")],
            initial=("a", [0.0, 0.0]),
        )


def test_initial_state_shape_and_mode_are_checked():
    with pytest.raises(
        ModelError,
        match=r"^hybrid system: initial state in mode 'a' has shape \(3,\), expected \(2,\) "
        r"with coordinates \('x0', 'x1'\)",
    ):
        two_modes(initial=("a", [0.0, 0.0, 0.0]))
    with pytest.raises(ModelError, match=r"^hybrid system: unknown mode 'c' \(modes: \['a', 'b'\]\)"):
        two_modes(initial=("c", [0.0, 0.0]))
    with pytest.raises(ModelError, match=r"^hybrid system: initial state in mode 'a' is not finite"):
        two_modes(initial=("a", [0.0, np.inf]))


def test_energy_and_expand_must_be_callable():
    with pytest.raises(ModelError, match=r"^hybrid system: energy must be callable energy\(mode, x\) -> float"):
        two_modes(energy=3)
    with pytest.raises(ModelError, match=r"^hybrid system: expand must be callable"):
        two_modes(expand="lazy")


def test_reset_of_wrong_dimension_found_mid_run_names_the_transition():
    # The reset is fine at the initial state and wrong only at the guard: the run raises there.
    system = HybridSystem(
        {"a": Mode(1, lambda t, x, u: np.array([1.0]))},
        [Transition("a", "a", lambda x: 1.0 - x[0], lambda x: np.zeros(1 if x[0] < 0.5 else 2), name="wrap")],
        initial=("a", [0.0]),
    )
    with pytest.raises(
        ModelError,
        match=r"^hybrid system: reset of transition wrap returned shape \(2,\), expected "
        r"\(1,\) for mode 'a'",
    ):
        simulate(system, [0.0], "a", 2.0, 0.1, 1e-3)


def test_lazily_expanded_modes():
    def expand(name: str):
        k = int(name)
        return Mode(1, lambda t, x, u: np.array([1.0])), [
            Transition(name, str(k + 1), lambda x: 1.0 - x[0], lambda x: np.array([0.0]))
        ]

    system = HybridSystem({}, expand=expand, name="ladder")
    ex = simulate(system, [0.0], "0", 3.5, 0.1, 1e-3)
    assert ex.status == "finished"
    # One rung per unit of time (plus at most eps of strip hold per rung).
    assert ex.mode_sequence == ["0", "1", "2", "3"]
    assert sorted(system.modes) == ["0", "1", "2", "3", "4"]  # expanded on use only (4 as 3's target)

    def broken(name: str):
        raise KeyError(name)

    with pytest.raises(ModelError, match=r"^broken: expand\('7'\) failed: KeyError: '7'"):
        HybridSystem({}, expand=broken, name="broken").mode("7")


def test_domain_views():
    system = two_modes(
        transitions=[
            Transition("a", "b", lambda x: 1.0 - x[0], name="up"),
            Transition("a", "b", lambda x: x[1], name="side"),
        ]
    )
    np.testing.assert_array_equal(system.guard_values("a", np.array([0.5, -0.25])), [0.5, -0.25])
    assert system.in_domain("a", np.array([0.5, 0.25]))
    assert not system.in_domain("a", np.array([0.5, -0.25]))
    assert system.in_domain("a", np.array([0.5, -0.25]), eps=0.3)  # inside the relaxed domain
    assert [tr.name for tr in system.outgoing("a")] == ["up", "side"]
    assert system.outgoing("b") == ()
    assert reachable_modes(system, "a") == ["a", "b"]


def test_dims_that_is_no_function_is_refused_naming_it():
    with pytest.raises(ModelError, match="dims must be callable"):
        HybridSystem({}, expand=lambda name: None, dims=3)


def test_two_transitions_of_one_mode_with_one_name_are_refused():
    """A record names its transition: two edges of one mode named alike would make an execution
    ambiguous (which one was taken?)."""

    def mode():
        return Mode(1, field=lambda t, x: np.array([1.0]))

    edges = [
        Transition("A", "B", guard=lambda t, x: 1.0 - x[0], name="hit"),
        Transition("A", "C", guard=lambda t, x: 2.0 - x[0], name="hit"),
    ]
    with pytest.raises(ModelError, match=r"mode 'A' has several transitions named \['hit'\]"):
        HybridSystem({"A": mode(), "B": mode(), "C": mode()}, edges)
    # One name in two modes is fine: each record names its source too.
    back = [
        Transition("A", "B", guard=lambda t, x: 1.0 - x[0], name="hit"),
        Transition("B", "A", guard=lambda t, x: x[0], name="hit"),
    ]
    assert len(HybridSystem({"A": mode(), "B": mode()}, back).transitions) == 2
