"""Small analytic hybrid systems whose return maps are known in closed form, for the orbit tests.

* impact oscillator: a damped oscillator x'' + 2 zeta w x' + w^2 x = 0 on x >= 0 with a wall at
  x = 0 (restitution e) that also kicks the velocity by D: v+ = -e v- + D. From x = 0 with
  velocity V it returns after pi / w_d with speed V rho, rho = exp(-zeta w pi / w_d), so the
  map V -> e rho V + D is linear: V* = D / (1 - e rho), multiplier e rho, period pi / w_d.
* Hopf oscillator with a reset: r' = mu r (1 - r^2), theta' = w; crossing the positive x axis
  upwards resets r -> kappa r and theta -> -beta. Over the arc time T = beta / w,
  r(T)^2 = 1 / (1 + (r0^-2 - 1) E), E = exp(-2 mu T), so r* ^2 = (kappa^2 - E) / (1 - E) and the
  multiplier is E / kappa^2. Nonlinear field, guard and reset: the saltation test bed.
* hopping ball: free flight z'' = -g, and at the ground a reset zd+ = D - k zd- (an actuated
  bounce whose take-off speed falls with the impact speed). Apex speeds map as v -> D - k v:
  v* = D / (1 + k), apex height v*^2 / 2g, multiplier -k (period doubling at k = 1).
"""

import math

import numpy as np

from legsim import HybridSystem, Mode, Transition
from legsim.orbits import Section

G = 9.81


def impact_oscillator(zeta=0.1, omega=2.0, e=0.8, kick=1.0):
    def field(t, x, u):
        return np.array([x[1], -2 * zeta * omega * x[1] - omega**2 * x[0]])

    return HybridSystem(
        {"free": Mode(2, field, names=("x", "v"))},
        [
            Transition(
                "free",
                "free",
                guard=lambda x: max(x[0], x[1]),
                reset=lambda x: np.array([x[0], -e * x[1] + kick]),
                name="impact",
            )
        ],
        name="impact oscillator",
    )


def oscillator_closed_form(zeta=0.1, omega=2.0, e=0.8, kick=1.0):
    wd = omega * math.sqrt(1 - zeta**2)
    rho = math.exp(-zeta * omega * math.pi / wd)
    v_star = kick / (1 - e * rho)
    # Largest displacement after leaving the wall with speed V: (V / w) exp(-zeta w t_peak).
    t_peak = math.acos(zeta) / wd
    x_max = v_star / omega * math.exp(-zeta * omega * t_peak)
    return {"v": v_star, "multiplier": e * rho, "period": math.pi / wd, "x_max": x_max}


def hopf_reset(mu=1.0, omega=2 * math.pi, kappa=0.9, beta=2.0, analytic_derivatives=False):
    def field(t, x, u):
        r2 = x[0] ** 2 + x[1] ** 2
        return np.array([mu * x[0] * (1 - r2) - omega * x[1], mu * x[1] * (1 - r2) + omega * x[0]])

    def jac(t, x, u):
        r2 = x[0] ** 2 + x[1] ** 2
        return np.array(
            [
                [mu * (1 - r2) - 2 * mu * x[0] ** 2, -2 * mu * x[0] * x[1] - omega],
                [-2 * mu * x[0] * x[1] + omega, mu * (1 - r2) - 2 * mu * x[1] ** 2],
            ]
        )

    c, s = math.cos(beta), math.sin(beta)
    rot = np.array([[c, s], [-s, c]])  # rotation by -beta

    def reset(x):
        return kappa * rot @ x

    extra = {}
    if analytic_derivatives:
        extra = {"guard_gradient": lambda x: np.array([0.0, -1.0]), "reset_jacobian": lambda x: kappa * rot}
    return HybridSystem(
        {"arc": Mode(2, field, names=("x", "y"), jacobian=jac if analytic_derivatives else None)},
        [Transition("arc", "arc", guard=lambda x: max(-x[1], -x[0]), reset=reset, name="jump", **extra)],
        name="hopf with reset",
    )


def hopf_closed_form(mu=1.0, omega=2 * math.pi, kappa=0.9, beta=2.0):
    E = math.exp(-2 * mu * beta / omega)
    r_star = math.sqrt((kappa**2 - E) / (1 - E))
    return {"r": r_star, "multiplier": E / kappa**2, "period": beta / omega}


def hopping_ball(params):
    kick, k = params["kick"], params.get("k", 0.5)
    return HybridSystem(
        {"flight": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))},
        [
            Transition(
                "flight",
                "flight",
                guard=lambda x: max(x[0], x[1]),
                reset=lambda x: np.array([x[0], kick + k * x[1]]),
                name="bounce",
            )
        ],
        name="hopping ball",
        energy=lambda mode, x: 0.5 * x[1] ** 2 + G * x[0],
    )


#: The hopping ball's apex: zd = 0 while zd decreases in flight.
APEX = Section.level("flight", "zd", 0.0, "decreasing")
