"""Small models with geometry for the recording and picture tests: a one-legged hopper whose
modes have different dimensions, and a bouncing ball without geometry."""

from __future__ import annotations

import numpy as np

from legsim.builders import Model
from legsim.hybrid import HybridSystem, Mode, Transition

G = 9.81


def hopper_model(k: float = 400.0, c: float = 0.9, r: float = 0.1) -> Model:
    """A point mass on a massless spring foot: flight (z, zd) and stance (z, zd, n).

    Stance carries a third coordinate n (the touchdown count), so the modes have different
    dimensions and a coordinate that exists in one mode only. Touchdown at z = 0 while falling
    (guard max(z, zd)), lift-off when the spring is back at rest length while rising (guard
    max(-z, -zd)); guard units m (m/s off the guard); the lift-off reset scales the velocity
    by c. Energy (J, unit mass): kinetic + gravity + spring.
    """
    count = {"n": 0}

    def land(x):
        count["n"] += 1
        return np.array([x[0], x[1], float(count["n"])])

    # "and" conditions with max: touchdown needs z < 0 while falling, lift-off z > 0 while
    # rising, so that a guard point q a rounding error past the other mode's guard does not
    # bounce straight back.
    touchdown = Transition("flight", "stance", guard=lambda x: max(x[0], x[1]), name="touchdown", reset=land)
    liftoff = Transition(
        "stance",
        "flight",
        guard=lambda x: max(-x[0], -x[1]),
        name="liftoff",
        reset=lambda x: np.array([x[0], c * x[1]]),
    )

    def energy(mode, x):
        spring = 0.5 * k * x[0] ** 2 if mode == "stance" else 0.0
        return 0.5 * x[1] ** 2 + G * x[0] + spring

    system = HybridSystem(
        {
            "flight": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd")),
            "stance": Mode(3, lambda t, x, u: np.array([x[1], -G - k * x[0], 0.0]), names=("z", "zd", "n")),
        },
        [touchdown, liftoff],
        name="hopper",
        energy=energy,
    )
    th = np.linspace(0.0, 2 * np.pi, 13)

    leg = 0.4  # m, drawn rest length: longer than the deepest compression (z > -0.2), so every
    # frame is drawn above the ground, whichever frame a screenshot catches

    def geometry(mode, x):
        z = x[0]
        body = np.c_[r * np.cos(th), z + leg + r + r * np.sin(th)]
        foot = 0.0 if mode == "stance" else z  # the foot rests on the ground in stance
        # The foot is a single point: recorded as a Rerun point, not a line strip.
        return {"body": body, "leg": np.array([[0.0, z + leg], [0.0, foot]]), "foot": np.array([[0.0, foot]])}

    return Model(
        system,
        "flight",
        {"z": 0.5, "zd": 0.0},
        geometry=geometry,
        scenery={"ground": np.array([[-1.0, 0.0], [1.0, 0.0]])},
    )


def ball_model(c: float = 0.5) -> Model:
    """A bouncing ball without geometry (states and events only): one mode (z, zd), guard
    max(z, zd) (below the floor *and* falling), so that a strip point q on or a rounding error
    past the floor leaves it after the reset instead of bouncing again at once."""
    fl = Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))
    tr = Transition(
        "flight", "flight", guard=lambda x: max(x[0], x[1]), reset=lambda x: np.array([x[0], -c * x[1]]), name="bounce"
    )
    return Model(HybridSystem({"flight": fl}, [tr], name="ball"), "flight", {"z": 1.0, "zd": 0.0})
