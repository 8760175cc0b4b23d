"""The exact reference of the forced oscillator with a stop (``OscillatorReference``) on its
own: the ODE by finite differences, the impact law, an independent event-driven DOP853
integration, the energy balance, the sticking condition of the paper, the Zeno sum, and the
resting cases its impact search must not hang on."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from legsim.errors import SimulationError
from legsim.systems.oscillator import EXAMPLES, OscillatorReference

EX1, EX2 = EXAMPLES["ex1"], EXAMPLES["ex2"]


def flight_times(ref: OscillatorReference, t_end: float, n: int, margin: float) -> np.ndarray:
    """n times in [0, t_end] at least ``margin`` away from impacts and outside sticking/chatter."""
    ts = np.linspace(margin, t_end - margin, n)
    impacts = ref.impact_times(t_end)
    keep = np.ones(n, dtype=bool)
    if impacts.size:
        keep &= np.abs(ts[:, None] - impacts[None, :]).min(axis=1) > margin
    for s, e in ref.sticking_intervals(t_end) + ref.chatter_intervals(t_end):
        keep &= (ts < s - margin) | (ts > e + margin)
    return ts[keep]


# -- the reference on its own -----------------------------------------------------------------
@pytest.mark.parametrize("name", ["ex1", "ex2"])
def test_reference_satisfies_the_ode_between_impacts(name, ref1, ref2):
    ref, E = (ref1, EX1) if name == "ex1" else (ref2, EX2)
    d = 1e-2
    ts = flight_times(ref, E["t_max"], 400, 3 * d)
    assert len(ts) > 100
    x = {k: ref.position(ts + k * d) for k in (-2, -1, 0, 1, 2)}
    # Fourth-order central differences: truncation d^4 x^(6) / 90 ~ 1e-10 omega^6 |x| ~ 1e-6 here; the
    # closed form's rounding (phases Omega t ~ 300 rad known to 3e-14) gives ~5 (1e-12) / d^2 ~ 5e-8.
    acc = (-x[2] + 16 * x[1] - 30 * x[0] + 16 * x[-1] - x[-2]) / (12 * d * d)
    vel = (-x[2] + 8 * x[1] - 8 * x[-1] + x[-2]) / (12 * d)
    xd = ref.velocity(ts)
    residual = acc + 2 * E["a"] * xd + E["omega"] ** 2 * x[0] - E["amplitude"] * np.cos(E["frequency"] * ts) / E["mass"]
    scale = E["amplitude"] / E["mass"] + E["omega"] ** 2 * np.abs(x[0]).max()
    assert np.abs(residual).max() < 1e-7 * scale
    assert np.abs(vel - xd).max() < 1e-8 * (1 + np.abs(xd).max())
    assert np.all(x[0] <= E["x_max"])


@pytest.mark.parametrize("name", ["ex1", "ex2"])
def test_reference_impact_law(name, ref1, ref2):
    ref, E = (ref1, EX1) if name == "ex1" else (ref2, EX2)
    times, speeds = ref.impact_times(E["t_max"]), ref.impact_speeds(E["t_max"])
    assert len(times) == len(speeds) > 10
    assert np.all(np.diff(times) > 0) and np.all(speeds >= 0)
    after = ref.states(times)
    np.testing.assert_allclose(after[:, 0], E["x_max"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        after[:, 1][speeds * E["c"] >= ref.zeno_speed],
        -E["c"] * speeds[speeds * E["c"] >= ref.zeno_speed],
        rtol=1e-12,
        atol=1e-15,
    )
    # Just before each impact the mass arrives at the stop with the recorded speed.
    big = speeds > 1e-3
    dt = 1e-9  # short enough for the position's curvature term (< 1e-16 m) not to show
    before = ref.states(times[big] - dt)
    np.testing.assert_allclose(before[:, 1], speeds[big], rtol=1e-5)
    np.testing.assert_allclose(before[:, 0], E["x_max"] - speeds[big] * dt, rtol=0, atol=1e-12)


def event_driven(E: dict, t0: float, y0, t_end: float, stop_speed: float = 0.0):
    """Independent reference: DOP853 from impact to impact with scipy's event location. Each
    flight first runs 1e-5 s without events (shorter than any flight here), because the event
    function is zero at the flight's start, on the stop."""

    def f(t, y):
        return [
            y[1],
            E["amplitude"] * math.cos(E["frequency"] * t) / E["mass"] - 2 * E["a"] * y[1] - E["omega"] ** 2 * y[0],
        ]

    def hit(t, y):
        return y[0] - E["x_max"]

    hit.terminal, hit.direction = True, 1.0
    opts = dict(method="DOP853", rtol=1e-13, atol=1e-14)
    t, y, impacts = t0, list(y0), []
    while True:
        skip = solve_ivp(f, (t, t + 1e-5), y, **opts)
        t, y = t + 1e-5, skip.y[:, -1]
        sol = solve_ivp(f, (t, t_end), y, events=hit, **opts)
        if sol.status != 1:
            return impacts, sol.y[:, -1]
        t, ye = float(sol.t_events[0][0]), sol.y_events[0][0]
        impacts.append((t, ye[1]))
        if ye[1] < stop_speed:
            return impacts, None
        y = [E["x_max"], -E["c"] * ye[1]]


def test_reference_agrees_with_event_driven_integration_example1(ref1):
    impacts, final = event_driven(EX1, 0.0, [EX1["x0"], EX1["xd0"]], EX1["t_max"])
    times = np.array([t for t, _ in impacts])
    np.testing.assert_allclose(ref1.impact_times(EX1["t_max"]), times, rtol=0, atol=1e-8)
    np.testing.assert_allclose(ref1.impact_speeds(EX1["t_max"]), [v for _, v in impacts], rtol=1e-7)
    np.testing.assert_allclose(ref1.state(EX1["t_max"]), final, rtol=1e-7)


def test_reference_agrees_with_event_driven_integration_example2_chatter(ref2):
    # Example 2 from its first release (at rest on the stop) through the chatter down to 1e-3 m/s.
    release = ref2.sticking_intervals(5.0)[0][1]
    impacts, _ = event_driven(EX2, release, [EX2["x_max"], 0.0], 10.0, stop_speed=1e-3)
    n = len(impacts)
    assert n == 9  # speeds halve from 0.2 m/s: 0.2 * 0.5^8 < 1e-3
    np.testing.assert_allclose(ref2.impact_times(6.0)[:n], [t for t, _ in impacts], rtol=0, atol=1e-8)
    np.testing.assert_allclose(ref2.impact_speeds(6.0)[:n], [v for _, v in impacts], rtol=1e-6)


def test_reference_energy_balance_over_flights(ref1):
    # dE/dt = u xd - 2 a m xd^2 between impacts; E drops by (1 - c^2) m v^2 / 2 at each impact.
    E = EX1
    times = ref1.impact_times(30.0)

    def energy(s):
        return 0.5 * E["mass"] * (s[1] ** 2 + E["omega"] ** 2 * s[0] ** 2)

    def power(t):
        return (
            E["amplitude"] * math.cos(E["frequency"] * t) * ref1.velocity(t)
            - 2 * E["a"] * E["mass"] * ref1.velocity(t) ** 2
        )

    for t1, t2 in itertools.pairwise(times):
        work, _ = quad(power, t1, t2, epsabs=1e-11, epsrel=1e-11, limit=200)
        before = ref1.state(t2 - 1e-12 * (t2 - t1))
        assert energy(before) - energy(ref1.state(t1)) == pytest.approx(work, rel=1e-7, abs=1e-7)
    speeds = ref1.impact_speeds(30.0)
    lost = [energy(ref1.state(t - 1e-10)) - energy(ref1.state(t)) for t in times]
    np.testing.assert_allclose(lost, 0.5 * E["mass"] * (1 - E["c"] ** 2) * speeds**2, rtol=1e-6)


def test_reference_without_forcing_or_damping_conserves_energy():
    ref = OscillatorReference(omega=2.0, a=0.0, x_max=0.5, c=1.0, x0=-1.0, xd0=0.0)
    ts = np.linspace(0, 20, 2001)
    s = ref.states(ts)
    energy = 0.5 * (s[:, 1] ** 2 + 4.0 * s[:, 0] ** 2)
    np.testing.assert_allclose(energy, 2.0, rtol=1e-12)
    # With c = 1 the motion is the free cosine x = -cos(2 t) folded at the stop: the arc
    # cos(2 t) < -0.5 beyond it is skipped, so impacts come every 2 acos(-0.5) / omega.
    period = 2.0 * math.acos(-0.5) / 2.0
    np.testing.assert_allclose(np.diff(ref.impact_times(20.0)), period, rtol=1e-12)


def test_example2_sticking_follows_the_stop_reaction(ref2):
    T = EX2["t_max"]
    sticks = ref2.sticking_intervals(T)
    # Paper 000 below Table I: the mass stays at the stop while its reaction is compressive, i.e.
    # while the free acceleration cos(t) - omega^2 x_max = cos(t) + 0.8 pushes into the stop; it
    # leaves when that changes sign: at acos(-0.8) + 2 pi k.
    assert len(sticks) == 3
    assert sticks[0] == (0.0, pytest.approx(math.acos(-0.8), abs=1e-14))
    assert sticks[1][1] == pytest.approx(2 * math.pi + math.acos(-0.8), abs=1e-13)
    for s, e in sticks:
        inside = np.linspace(s, min(e, T), 500)
        assert np.all(ref2.free_acceleration(inside) >= -1e-12)
        np.testing.assert_array_equal(ref2.states(inside[1:-1]), [[EX2["x_max"], 0.0]] * 498)
    # The second and third sticking phases start where the chatter accumulates.
    np.testing.assert_allclose([s for s, _ in sticks[1:]], ref2.zeno_times(T), rtol=0, atol=0)
    # Between, the mass is off the stop.
    assert ref2.position(4.0) < EX2["x_max"] - 0.05


def test_example2_chatter_is_geometric_with_ratio_c(ref2):
    speeds = ref2.impact_speeds(6.0)
    ratios = speeds[1:] / speeds[:-1]
    # Flights shrink like the speed, so damping and the forcing's drift matter less and less.
    assert abs(ratios[-1] - EX2["c"]) < 1e-6
    assert np.all(np.abs(np.diff(np.abs(ratios[5:] - EX2["c"]))) < 1e-3)


@pytest.mark.parametrize("zeno_speed", [1e-4, 1e-5, 1e-6])
def test_zeno_sum_error_is_of_order_speed_squared(zeno_speed):
    fine = OscillatorReference.example("ex2", zeno_speed=1e-12).zeno_times(4 * math.pi)
    coarse = OscillatorReference.example("ex2", zeno_speed=zeno_speed).zeno_times(4 * math.pi)
    F = OscillatorReference.example("ex2").free_acceleration(fine)
    # The summed flights 2 c^k w / F neglect terms of relative order w (damping, dF/dt): O(w^2).
    assert np.all(np.abs(coarse - fine) <= 10 * (zeno_speed / F) ** 2)


def test_reference_refuses_what_eq_28_does_not_cover():
    from legsim import ModelError

    with pytest.raises(ModelError, match=r"^oscillator reference: needs sub-critical damping 0 <= a < omega"):
        OscillatorReference(omega=1.0, a=1.5)
    with pytest.raises(ModelError, match=r"^oscillator reference: undamped resonance"):
        OscillatorReference(omega=2.0, a=0.0, amplitude=1.0, frequency=2.0)
    # A subnormal damping at resonance: the particular amplitude U / (2 a Omega) overflows.
    with pytest.raises(ModelError, match=r"^oscillator reference: forcing at 2 rad/s .* resonance"):
        OscillatorReference(omega=2.0, a=2.225073858507203e-309, amplitude=1.0, frequency=2.0)
    # 1e-9 damping at resonance amplifies the static deflection 1 / omega^2 by omega / (2 a) = 1e9.
    with pytest.raises(ModelError, match=r"within 1e\+08 amplification of resonance"):
        OscillatorReference(omega=2.0, a=1e-9, amplitude=1.0, frequency=2.0)
    # Detuned by 1e-3 it is amplified omega^2 / (omega^2 - Omega^2) = 1000-fold: a closed form.
    assert OscillatorReference(
        omega=2.0, a=0.0, amplitude=1.0, frequency=2.0 * math.sqrt(0.999)
    ).p_amp == pytest.approx(1000 / 4)
    with pytest.raises(ModelError, match=r"^oscillator reference: x0 = 2.0 lies beyond the stop x_max = 1.0"):
        OscillatorReference(x_max=1.0, x0=2.0)


@pytest.mark.parametrize("x_max, amplitude, frequency", [(0.0, 0.0, 0.0), (0.0, 0.0, 1.3), (0.25, 1.5625, 0.0)])
def test_reference_mass_at_rest_on_a_stop_at_equilibrium_stays_at_rest(x_max, amplitude, frequency):
    # F(t) = u/m - omega^2 x_max vanishes identically (omega = 2.5: 2.5^2 * 0.25 = 1.5625), so the
    # exact solution is x = x_max, xd = 0 for ever; an impact search that started a flight there
    # would bisect the zero gap over the whole flight down to 1e-13 s and never return.
    ref = OscillatorReference(2.5, 0.05, x_max, 0.5, 1.0, amplitude, frequency, x_max, 0.0)
    states = ref.states([0.0, 0.7, 10.0])
    assert np.array_equal(states, np.tile([x_max, 0.0], (3, 1)))
    assert len(ref.impact_times(10.0)) == 0


def test_reference_plastic_impact_at_the_equilibrium_stop_rests_there():
    # c = 0, stop at the spring's equilibrium, unforced: the free motion from x0 < 0 at rest reaches
    # x = 0 when cos(wd t + phase) decays to zero; after the plastic impact F = 0, so the mass rests.
    omega, a, x0 = 2.5, 0.05, -0.3
    ref = OscillatorReference(omega, a, 0.0, 0.0, 1.0, 0.0, 0.0, x0, 0.0)
    wd = math.sqrt(omega**2 - a**2)
    # x = x0 e^{-a t} (cos wd t + (a/wd) sin wd t) = 0 at tan(wd t) = -wd/a
    t_hit = (math.pi - math.atan(wd / a)) / wd
    impacts = ref.impact_times(5.0)
    assert len(impacts) == 1 and impacts[0] == pytest.approx(t_hit, rel=1e-12)
    assert np.array_equal(ref.states([t_hit + 1e-6, 5.0]), np.zeros((2, 2)))


def test_reference_impact_search_has_a_work_bound():
    # A flight whose gap is zero everywhere (forced here by claiming the resting mass does not
    # stay) must end in a named error, not a hang.
    class Leaves(OscillatorReference):
        def _stays(self, t):
            return False

    ref = Leaves(2.5, 0.05, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0)
    ref.max_refinements = 2_000
    with pytest.raises(SimulationError, match="visited 2000 intervals"):
        ref.state(1.0)
