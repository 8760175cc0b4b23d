"""Butcher tableaux: their order conditions, the generated steppers against the readable
``rk_step``, and the convergence orders measured on problems with closed-form solutions
(including a time-varying control, which must be sampled at every stage)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from legsim import HybridSystem, Mode, SimulationError, simulate
from legsim.methods import ALIASES, METHODS, get_method
from legsim.relaxed.single import Stepper

ORDERS = {"euler": 1, "rk2": 2, "heun": 2, "rk4": 4, "bs32": 3, "dopri5": 5}


def order_conditions(tab) -> dict[int, list[tuple[float, float]]]:
    """(value, required) of the order conditions for the rooted trees of order 1..5."""
    b, A, c = tab.b, tab.A, tab.c
    Ac, Ac2, Ac3 = A @ c, A @ c**2, A @ c**3
    AAc = A @ Ac
    return {
        1: [(b.sum(), 1.0)],
        2: [(b @ c, 1 / 2)],
        3: [(b @ c**2, 1 / 3), (b @ Ac, 1 / 6)],
        4: [(b @ c**3, 1 / 4), (b @ (c * Ac), 1 / 8), (b @ Ac2, 1 / 12), (b @ AAc, 1 / 24)],
        5: [
            (b @ c**4, 1 / 5),
            (b @ (c**2 * Ac), 1 / 10),
            (b @ (c * Ac2), 1 / 15),
            (b @ (c * AAc), 1 / 30),
            (b @ (Ac * Ac), 1 / 20),
            (b @ Ac3, 1 / 20),
            (b @ (A @ (c * Ac)), 1 / 40),
            (b @ (A @ Ac2), 1 / 60),
            (b @ (A @ AAc), 1 / 120),
        ],
    }


@pytest.mark.parametrize("name", sorted(ORDERS))
def test_tableau_satisfies_exactly_its_order_conditions(name):
    tab = METHODS[name]
    assert tab.order == ORDERS[name]
    conditions = order_conditions(tab)
    for order in range(1, tab.order + 1):
        for value, required in conditions[order]:
            assert value == pytest.approx(required, abs=1e-14), (name, order)
    if tab.order < 5:
        # ... and not those of the next order (otherwise the stated order would be too low).
        assert any(abs(v - r) > 1e-6 for v, r in conditions[tab.order + 1])
    np.testing.assert_allclose(tab.A.sum(axis=1), tab.c, atol=1e-15)
    assert np.all(np.triu(tab.A) == 0.0)  # explicit


@pytest.mark.parametrize("name", ["bs32", "dopri5"])
def test_embedded_weights_have_the_stated_lower_order(name):
    tab = METHODS[name]
    b_hat = tab.b - tab.b_err
    hat = type(tab)(tab.name, tab.error_order, tab.c, tab.A, b_hat)
    conditions = order_conditions(hat)
    for order in range(1, tab.error_order + 1):
        for value, required in conditions[order]:
            assert value == pytest.approx(required, abs=1e-14)
    assert any(abs(v - r) > 1e-6 for v, r in conditions[tab.error_order + 1])


def test_method_names_and_aliases():
    for alias, target in ALIASES.items():
        assert get_method(alias) is METHODS[target]
    assert get_method("RK4") is METHODS["rk4"]
    assert get_method(METHODS["heun"]) is METHODS["heun"]
    with pytest.raises(SimulationError, match=r"^unknown method 'rk9'; choose one of"):
        get_method("rk9")
    with pytest.raises(SimulationError, match=r"^method must be a name or a Tableau, got int"):
        get_method(4)
    with pytest.raises(SimulationError, match=r"rtol/atol need a method with an embedded error estimate"):
        simulate(logistic_system(), [0.1], "m", 1.0, 0.1, 1e-3, "rk4", rtol=1e-6)


def logistic_system() -> HybridSystem:
    return HybridSystem({"m": Mode(1, lambda t, x, u: x * (1.0 - x))})


def logistic_exact(t: float, y0: float) -> float:
    return 1.0 / (1.0 + math.exp(-t) * (1.0 / y0 - 1.0))


def forced_system() -> HybridSystem:
    # x'' = -x + u(t), the force entering through the control path.
    return HybridSystem({"m": Mode(2, lambda t, x, u: np.array([x[1], -x[0] + u]))})


def forced_exact(t: float) -> np.ndarray:
    # From (x, x') = (0, 1) with u = cos(2 t): x = cos(t)/3 + sin(t) - cos(2 t)/3.
    return np.array(
        [math.cos(t) / 3 + math.sin(t) - math.cos(2 * t) / 3, -math.sin(t) / 3 + math.cos(t) + 2 * math.sin(2 * t) / 3]
    )


def fitted_order(hs, errors) -> float:
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


STEP_SIZES = {
    "euler": [0.02, 0.01, 0.005, 0.0025],
    "rk2": [0.1, 0.05, 0.025, 0.0125],
    "heun": [0.1, 0.05, 0.025, 0.0125],
    "bs32": [0.1, 0.05, 0.025, 0.0125],
    "rk4": [0.2, 0.1, 0.05, 0.025],
    "dopri5": [0.2, 0.1, 0.05, 0.025],
}


@pytest.mark.parametrize("name", sorted(ORDERS))
def test_global_error_converges_at_the_method_order(name):
    hs = STEP_SIZES[name]
    err_logistic = [
        abs(simulate(logistic_system(), [0.1], "m", 4.0, h, 1.0, name).final_state[0] - logistic_exact(4.0, 0.1))
        for h in hs
    ]
    control = lambda t, x: math.cos(2.0 * t)  # noqa: E731
    err_forced = [
        np.abs(
            simulate(forced_system(), [0.0, 1.0], "m", 4.0, h, 1.0, name, control).final_state - forced_exact(4.0)
        ).max()
        for h in hs
    ]
    p = ORDERS[name]
    # Asymptotic slopes are exact; 0.2 allows for the next-order term at the coarsest step.
    # dopri5's leading error constant on the logistic equation is so small that the h^6 term
    # still shows at these steps (local slopes 5.5, 5.3, 5.2 falling towards 5), and smaller
    # steps reach rounding: 0.4 there.
    tol = 0.4 if name == "dopri5" else 0.2
    assert fitted_order(hs, err_logistic) == pytest.approx(p, abs=tol)
    assert fitted_order(hs, err_forced) == pytest.approx(p, abs=0.2)


def test_dop853_is_hairers_method_as_scipy_has_it():
    # The coefficients are data in legsim; scipy's DOP853 is an independent copy of Hairer's.
    from scipy.integrate._ivp import dop853_coefficients as ref

    tab = get_method("dop853")
    assert tab.stages == 13 and tab.fsal and tab.order == 8
    np.testing.assert_array_equal(tab.A[:12, :12], ref.A[:12, :12])
    np.testing.assert_array_equal(tab.A[12, :12], ref.B)
    np.testing.assert_array_equal(tab.b_err, ref.E5)
    np.testing.assert_array_equal(tab.b_err_low, ref.E3)
    np.testing.assert_array_equal(tab.dense.A_extra, ref.A[13:])
    np.testing.assert_array_equal(tab.dense.c_extra, ref.C[13:])


def test_dop853_runs_from_simulate_by_name_at_its_order():
    # A regular method name: error-controlled on the logistic equation, its error falls with the
    # tolerance, and fixed steps converge at order 8 (errors halve 256-fold per halving of h).
    y0, t_end = 0.1, 2.0
    errors = []
    for h in (0.5, 0.25):
        ex = simulate(logistic_system(), [y0], "m", t_end, h, 1e-3, "dop853")
        errors.append(abs(ex.final_state[0] - logistic_exact(t_end, y0)))
    assert errors[0] / errors[1] > 2**7
    ex = simulate(logistic_system(), [y0], "m", t_end, 0.5, 1e-3, "DOP853", rtol=1e-10, atol=1e-12)
    assert ex.settings["method"] == "dop853" and abs(ex.final_state[0] - logistic_exact(t_end, y0)) < 1e-9


def test_dop853_tableau_is_eighth_order_with_a_fifth_order_estimate():
    # x' = -x over [0, 1]: the global error of an order-8 method falls by 2^8 when h halves; the
    # embedded estimate h * sum(E5_j k_j) of one step is O(h^6) (fifth-order solution).
    from legsim import HybridSystem, Mode, simulate

    tab = get_method("dop853")
    assert get_method("dop853") is tab and tab.fsal and tab.stages == 13
    system = HybridSystem({"m": Mode(1, lambda t, x, u: -x)})
    hs = (0.5, 0.25, 0.125)
    errors = [abs(simulate(system, [1.0], "m", 1.0, h, 1e-3, tab).final_state[0] - math.exp(-1.0)) for h in hs]
    slopes = np.diff(np.log(errors)) / np.diff(np.log(hs))
    assert np.all(slopes > 7.5), slopes
    stepper = Stepper(tab)
    est = []
    for h in hs:
        x = np.array([1.0])
        _, stages = stepper.step(lambda t, y, u: -y, 0.0, x, h, -x, None)
        est.append(abs(stepper.error_estimate(h, stages)[0]))
    assert np.all(np.diff(np.log(est)) / np.diff(np.log(hs)) > 5.5)
