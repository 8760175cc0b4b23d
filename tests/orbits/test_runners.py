"""Running gaits: SLIP and the pronk (helper robots on the Pinocchio bridge), from the bundled
orbit scenes, against an independent computation.

Reference. A SLIP apex-to-apex map written from scratch: ballistic flight in closed form down to
touchdown at z = l cos(psi); stance m p'' = k (l - r) (p - foot) / r + m g integrated by scipy's
DOP853 (rtol = atol = 1e-12) to the liftoff event r = l; ballistic flight up to the apex. The
touchdown angle that returns the paper's apex (z = 1.1 m, xd = 3.4 m/s) is found by Brent's
method, and the apex-height multiplier at constant energy by central differences.

The pronk with theta = 0 is the SLIP with the two legs' stiffness added (paper 000, Sec. V-C):
the same touchdown angle, period and stride, and the SLIP's multipliers among its own.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from legsim.orbits import find_orbit
from legsim.scene import load_scene
from legsim.scene.orbit import problem_from_scene

M, K, L, G = 1.0, 60.0, 1.0, 9.81
Z0, XD0 = 1.1, 3.4


def slip_apex_map(z0, xd0, psi):
    z_td = L * math.cos(psi)
    vz = -math.sqrt(2 * G * (z0 - z_td))
    t_fall = -vz / G
    foot = xd0 * t_fall + L * math.sin(psi)

    def stance(t, y):
        dx, dz = y[0] - foot, y[1]
        r = math.hypot(dx, dz)
        f = K * (L - r) / r
        return [y[2], y[3], f * dx / M, f * dz / M - G]

    def liftoff(t, y):
        return math.hypot(y[0] - foot, y[1]) - L

    liftoff.terminal, liftoff.direction = True, 1
    sol = solve_ivp(
        stance, (0.0, 5.0), [xd0 * t_fall, z_td, xd0, vz], method="DOP853", rtol=1e-12, atol=1e-12, events=liftoff
    )
    x, z, vx, vz = sol.y_events[0][0]
    t_rise = vz / G
    return {"z": z + vz**2 / (2 * G), "xd": vx, "period": t_fall + sol.t_events[0][0] + t_rise, "step": x + vx * t_rise}


@pytest.fixture(scope="module")
def reference():
    psi = brentq(lambda p: slip_apex_map(Z0, XD0, p)["z"] - Z0, 0.60, 0.65, xtol=1e-14)
    out = slip_apex_map(Z0, XD0, psi)
    energy = G * Z0 + 0.5 * XD0**2

    def apex(z):
        return slip_apex_map(z, math.sqrt(2 * (energy - G * z)), psi)["z"]

    d = 1e-6
    out.update(psi=psi, multiplier=(apex(Z0 + d) - apex(Z0 - d)) / (2 * d))
    return out


@pytest.fixture(scope="module")
def slip_orbit():
    settings = problem_from_scene(load_scene("slip_orbit"))
    res = find_orbit(settings.problem, settings.guess, **settings.solver)
    assert res.converged, res.message
    return res


def test_slip_orbit_matches_the_independent_computation(slip_orbit, reference):
    res = slip_orbit
    # RK4 at h = 1e-3 against DOP853 at 1e-12: agreement to ~1e-10.
    assert abs(res.parameters["psi"] - reference["psi"]) < 1e-9
    assert abs(res.period - reference["period"]) < 1e-9
    assert abs(res.step_length - reference["step"]) < 1e-8
    assert res.fixed_point.tolist() == [0.0, Z0, XD0, 0.0]
    # Two multipliers: energy (exactly 1) and the apex height map at constant energy.
    mu = sorted(res.multipliers.real)
    assert abs(mu[0] - 1.0) < 1e-6
    # The reference multiplier is a central difference at 1e-6 (~1e-7); ours uses forward
    # differences of the field inside the saltation product (~1e-8 relative each).
    assert abs(mu[1] - reference["multiplier"]) < 1e-6 * reference["multiplier"]
    assert np.all(np.abs(res.multipliers.imag) < 1e-9)
    # The passive SLIP at this speed and angle is unstable, as the paper's run shows.
    assert res.stable is False and res.spectral_radius > 5.0


def test_pronk_orbit_is_the_slip_orbit(slip_orbit):
    # Started from the SLIP's angle, Newton has nothing left to do if the two orbits coincide.
    psi = slip_orbit.parameters["psi"]
    settings = problem_from_scene(load_scene("pronk_orbit", overrides=[f"robot.parameters.psi={psi!r}"]))
    res = find_orbit(settings.problem, settings.guess, **settings.solver)
    assert res.converged, res.message
    assert res.iterations <= 1
    assert abs(res.parameters["psi"] - slip_orbit.parameters["psi"]) < 1e-10
    assert abs(res.period - slip_orbit.period) < 1e-10
    assert abs(res.step_length - slip_orbit.step_length) < 1e-9
    # Both legs touch down and lift off together (one strip after the other at the same instant).
    assert sorted(res.transitions) == ["liftoff_left", "liftoff_right", "touchdown_left", "touchdown_right"]
    mu = res.multipliers
    assert len(mu) == 4  # 6 coordinates, minus the flow, minus the cyclic x
    for m in slip_orbit.multipliers:
        assert np.min(np.abs(mu - m)) < 1e-6
    # The two others belong to the pitch motion, which the SLIP does not have.
    pitch = [m for m in mu if np.min(np.abs(slip_orbit.multipliers - m)) > 1e-3]
    assert len(pitch) == 2 and abs(pitch[0] - np.conj(pitch[1])) < 1e-9


@pytest.mark.parametrize("eps", [4e-2, 1e-2, 1e-3])
def test_pronk_orbit_does_not_degrade_with_eps(eps, reference):
    # The fixed point through two simultaneous touchdowns and liftoffs, as eps shrinks: the
    # strips hold the state for eps - tau seconds at each of the 4 transitions, which delays the
    # relaxed return by at most 4 eps (the hold is time, not motion), while the gait itself
    # (angle, stride, period without the holds) stays at the independent SLIP's values to
    # RK4's accuracy at h = 1e-3 whatever eps.
    settings = problem_from_scene(load_scene("pronk_orbit", overrides=[f"integrator.eps={eps!r}"]))
    res = find_orbit(settings.problem, settings.guess, **settings.solver)
    assert res.converged, res.message
    assert abs(res.parameters["psi"] - reference["psi"]) < 1e-9
    assert abs(res.period - reference["period"]) < 1e-9
    assert abs(res.step_length - reference["step"]) < 1e-8
    delay = res.return_time - res.period
    assert 0.0 < delay <= 4 * eps * (1 + 1e-9)
