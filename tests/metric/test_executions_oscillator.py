"""rho^eps between relaxed simulations of the forced oscillator with a stop (paper 000 Table I,
Example 1) and its exact reference: O(eps) + O(h^order) (paper 000 Corollary after Thm. 27).

Observed mechanism of the eps part: after each impact the simulation lags the reference by
its strip time, eps - tau + (t_land - t_cross), between 0 and about eps (tau, the landing depth,
is a fraction of eps that depends on where the step grid falls), so rho / eps is bounded but
jumps around from one eps to the next. The slope is therefore fitted to the mean of rho over
three step sizes (three landing phases) and checked over four decades of eps.

Example 2 is not in the eps tests: its impacts chatter down to a Zeno accumulation with impact
speeds -> 0, where the lag tau / |x'| is no longer O(eps) (docs/metric.md has the numbers). Its
slope in h (rk2, eps = 1e-8) is tested at the end of this file.
"""

from __future__ import annotations

import numpy as np
import pytest

from legsim import simulate
from legsim.metric import position_error, rho
from legsim.systems import oscillator as osc

EX = osc.EXAMPLES["ex1"]
T_END = 10.0  # four impacts; the full t_max = 40 pi is a slow sweep
TIMES = np.linspace(0.0, T_END, 2001)


def _system():
    return osc.make_system(omega=EX["omega"], a=EX["a"], x_max=EX["x_max"], c=EX["c"], mass=EX["mass"])


def _run(system, h: float, eps: float, method: str, t_end: float = T_END):
    control = osc.forcing(EX["amplitude"], EX["frequency"])
    ex = simulate(system, [EX["x0"], EX["xd0"]], "free", t_end, h, eps, method=method, control=control)
    assert ex.status == "finished"
    return ex


@pytest.fixture(scope="module")
def reference():
    return osc.OscillatorReference.example("ex1")


@pytest.mark.parametrize(
    "method, order, steps, eps",
    [
        ("rk2", 2, (1e-2, 5e-3, 2.5e-3), 1e-8),  # the midpoint method of the paper's Fig. 14
        ("rk4", 4, (4e-2, 2e-2, 1e-2), 1e-10),
    ],
)
def test_rho_falls_like_h_to_the_order_of_the_method(reference, method, order, steps, eps):
    system = _system()
    values = [rho(system, _run(system, h, eps, method), reference, TIMES, eps) for h in steps]
    slope = np.polyfit(np.log(steps), np.log(values), 1)[0]
    assert slope == pytest.approx(order, abs=0.25)


def _eps_sweep(reference, epsilons):
    system = _system()
    means = []
    for eps in epsilons:
        # RK4 with h = 1e-2: its error (~3e-6, previous test) stays below the eps part.
        values = [rho(system, _run(system, h, eps, "rk4"), reference, TIMES, eps) for h in (1e-2, 7.7e-3, 6.1e-3)]
        means.append(np.mean(values))
    return np.array(means)


def test_rho_falls_like_eps(reference):
    epsilons = np.logspace(-2, -5, 4)
    means = _eps_sweep(reference, epsilons)
    slope = np.polyfit(np.log(epsilons), np.log(means), 1)[0]
    assert slope == pytest.approx(1.0, abs=0.25)
    ratio = means / epsilons
    assert ratio.max() / ratio.min() < 10.0  # rho = Theta(eps) across three decades


@pytest.mark.slow
def test_rho_falls_like_eps_over_five_decades(reference):
    epsilons = np.logspace(-2, -7, 11)
    means = _eps_sweep(reference, epsilons)
    slope = np.polyfit(np.log(epsilons), np.log(means), 1)[0]
    assert slope == pytest.approx(1.0, abs=0.15)


def test_position_error_of_eq_30_is_below_rho_and_converges_with_h(reference):
    # The impact keeps the position, so any path through the stop is at least as long in x as
    # the chord: |x_sim - x_ref| <= d at every instant, and the position-only error of eq. (30)
    # is at most rho^eps (which also charges velocity errors).
    system = _system()
    steps = (1e-2, 5e-3, 2.5e-3)
    errors = []
    for h in steps:
        ex = _run(system, h, 1e-8, "rk2")
        errors.append(position_error(ex, reference, TIMES))
        assert errors[-1] <= rho(system, ex, reference, TIMES, 1e-8)
    assert np.polyfit(np.log(steps), np.log(errors), 1)[0] == pytest.approx(2.0, abs=0.25)


# -- Example 2 of Table I: rho^eps in h --------------------------------------------------------------
EX2 = osc.EXAMPLES["ex2"]
EX2_STEPS = (1e-2, 5e-3, 2.5e-3)  # the rk2 steps of docs/metric.md (and of Example 1 above)
EX2_EPS = 1e-8  # as in docs/metric.md; see the short form for why it does not dominate


def _ex2_slope(t_end: float, samples: int) -> tuple[float, list[float]]:
    """rk2 from Table I's initial state (x0 = x_max, at rest: it sticks until t = 2.498), the
    settings of ``scenarios/metric_digital_control.py --oscillator`` (which gave docs/metric.md's
    2.04); returns the fitted slope of log rho against log h, and the rho values."""
    system = osc.make_system(omega=EX2["omega"], a=EX2["a"], x_max=EX2["x_max"], c=EX2["c"], mass=EX2["mass"])
    reference = osc.OscillatorReference.example("ex2")
    control = osc.forcing(EX2["amplitude"], EX2["frequency"])
    times = np.linspace(0.0, t_end, samples)
    values = []
    for h in EX2_STEPS:
        # The paper's relaxed execution (no continuation): sticking is simulated as eps-deep
        # chatter in the strip (~1e4 transitions per second of sticking at eps = 1e-8), hence the
        # raised cap.
        ex = simulate(
            system,
            [EX2["x0"], EX2["xd0"]],
            "free",
            t_end,
            h,
            EX2_EPS,
            method="rk2",
            control=control,
            max_transitions=10**6,
            continuation=False,
        )
        assert ex.status == "finished"
        values.append(rho(system, ex, reference, times, EX2_EPS))
    return float(np.polyfit(np.log(EX2_STEPS), np.log(values), 1)[0]), values


def test_example_2_rho_falls_like_h_squared_with_rk2():
    # Short form: t in [0, 5] s (the initial stick, its release and three impacts, stopping
    # before the chatter that accumulates at t = 5.0645), sampled as densely as docs/metric.md's
    # 2001 points over 4 pi (801 points, 6.25 ms apart). About 3 s.
    # Measured: rho = 8.13e-5, 1.97e-5, 4.20e-6 (slope 2.14); with eps = 1e-9 instead, 8.01e-5,
    # 1.94e-5, 4.63e-6 (slope 2.06): the eps part moves rho by ~10% at the smallest h, so eps =
    # 1e-8 does not dominate, but it does jitter the fit by ~0.1 (where the step grid meets the
    # guard sets the landing depth, as for Example 1). Hence 2 +- 0.3: wide enough for that
    # jitter, narrow enough to reject order 1 or 3 (and the 1.5 a lost order would give).
    slope, values = _ex2_slope(5.0, 801)
    assert slope == pytest.approx(2.0, abs=0.3)
    assert min(values) > 100 * EX2_EPS  # rho is far above the strip width: the h part is measured


@pytest.mark.slow
def test_example_2_rho_falls_like_h_squared_with_rk2_over_table_1_horizon():
    # The faithful version of docs/metric.md (t in [0, 4 pi], 2001 samples; slope 2.04 from
    # 2.60e-4, 6.60e-5, 1.53e-5). About 30 s: the three sticking phases (7.4 s in all) cost
    # ~1e5 strip transitions per run. Here the supremum falls in the chatter before the Zeno
    # time 5.0645, so it depends on how the 2001-point grid meets that chatter; the tolerance
    # is that of the short form.
    slope, _ = _ex2_slope(4.0 * np.pi, 2001)
    assert slope == pytest.approx(2.0, abs=0.3)
