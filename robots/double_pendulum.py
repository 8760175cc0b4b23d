"""Double pendulum with a mechanical stop (paper 003, Section V, Fig. 2).

Two links hang from a pivot at the origin; ``theta1`` is the angle of link 1 from the downward
vertical, ``theta2`` the angle of link 2 relative to link 1 (both rad, positive swinging link
tips towards +x). Each link is a point mass at its end (m1, m2 kg; L1, L2 m); the paper leaves
the values to its code, we take m1 = m2 = 1 kg and L1 = L2 = 1 m with g = 9.81 m/s^2.

A stop at ``theta2 = 0`` (effect ``stop``) keeps ``theta2 >= 0``. Modes:

* ``unconstrained``: both joints free, by the native library's forward dynamics;
* ``constrained`` (only when the stop's restitution is 0): link 2 held against the stop, the
  stop torque lambda (N m) from the KKT dynamics.

Transitions and guard units (eps is measured in them):

* ``impact_stop`` (c = 0, unconstrained -> constrained) and ``bounce_stop`` (c > 0, a
  self-transition): guard ``max(theta2, dtheta2/dt)`` in rad; reset paper 003 eq. (30);
* ``release_stop`` (constrained -> unconstrained): guard lambda in N m, the zero crossing of
  paper 003 eq. (31) (lambda = -(31) as printed: the paper's sign makes lambda > 0 when the free
  acceleration of theta2 is positive, i.e. when the link would leave the stop; we report the
  force the stop exerts, > 0 while it holds the link).

Without the stop effect the system has one mode and no guard.

Effect ``controller`` (off by default): a PD controller on the shoulder joint ``theta1``,
``u = kp (target - theta1) - kd dtheta1/dt`` (N m), the generalised torque of that joint in both
modes. Only with it is the joint actuated: then the bridge adds u to the shoulder torque, the
stop's force-dependent guards are evaluated under it, and the ``Model`` carries the control (the
bundled ``joint_pd`` law without gravity compensation, ``controllers.joint_pd``); without it no
actuation term exists (``actuation_evals`` stays 0).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import ZENO_EFFECT, ZENO_WINDOW, Builder, Effect, Model, Param

from .bridge import ContactBridge, JointStop, add_point_frame
from .controllers import joint_pd

COORDINATES = ("theta1", "theta2")
#: The joint the ``controller`` effect drives: the Pinocchio joint name of theta1 (the shoulder).
SHOULDER = "theta1"
VELOCITIES = ("theta1d", "theta2d")
STATE_NAMES = COORDINATES + VELOCITIES

#: Paper 003 Fig. 2 initial condition (30 deg, 25 deg, 0, 0), in rad and rad/s.
INITIAL_STATE = {"theta1": math.radians(30.0), "theta2": math.radians(25.0), "theta1d": 0.0, "theta2d": 0.0}

PARAMETERS = {
    "m1": Param(1.0, "mass at the end of link 1", "kg", low=0.0, low_open=True),
    "m2": Param(1.0, "mass at the end of link 2", "kg", low=0.0, low_open=True),
    "L1": Param(1.0, "length of link 1", "m", low=0.0, low_open=True),
    "L2": Param(1.0, "length of link 2", "m", low=0.0, low_open=True),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0),
}

EFFECTS = {
    "gravity": Effect("gravity g pulling the masses down", default_on=True),
    "stop": Effect(
        "mechanical stop on theta2 (domain theta2 >= position)",
        default_on=True,
        parameters={
            "restitution": Param(
                0.0, "coefficient of restitution c (0: plastic, enters the constrained mode)", low=0.0, high=1.0
            ),
            "position": Param(0.0, "stop angle", "rad", low=-math.pi, high=math.pi),
        },
    ),
    "zeno": ZENO_EFFECT,
    "damping": Effect(
        "viscous joint damping",
        parameters={
            "b1": Param(0.1, "damping of joint 1", "N m s/rad", low=0.0),
            "b2": Param(0.1, "damping of joint 2", "N m s/rad", low=0.0),
        },
    ),
    "controller": Effect(
        "PD controller on the shoulder joint theta1: u = kp (target - theta1) - kd dtheta1/dt (N m)",
        parameters={
            # Defaults hold the straight pendulum near the bottom: kp = 50 N m/rad exceeds the
            # gravity stiffness (m1 + m2) g L1 + m2 g L2 = 29.4 N m/rad of the default links, and
            # kd = 10 N m s/rad damps the shoulder's swing (inertia 5 kg m^2, stiffness 79 N m/rad:
            # damping ratio 0.25) so that it settles within a few seconds.
            "kp": Param(50.0, "proportional gain", "N m/rad", low=0.0),
            "kd": Param(10.0, "derivative gain (on dtheta1/dt, the target is constant)", "N m s/rad", low=0.0),
            "target": Param(0.0, "shoulder angle the controller holds", "rad", low=-math.pi, high=math.pi),
        },
    ),
}


def pinocchio_model(m1: float = 1.0, m2: float = 1.0, L1: float = 1.0, L2: float = 1.0, g: float = 9.81) -> pin.Model:
    """The Pinocchio model: two RY joints, point masses at the link ends, frames ``elbow`` and
    ``tip``. The pivot frame is turned half a turn about z so that positive angles swing the
    links towards +x."""
    model = pin.Model()
    turn = pin.SE3(pin.utils.rotate("z", math.pi), np.zeros(3))
    j1 = model.addJoint(0, pin.JointModelRY(), turn, "theta1")
    model.appendBodyToJoint(j1, pin.Inertia(m1, np.array([0.0, 0.0, -L1]), np.zeros((3, 3))), pin.SE3.Identity())
    j2 = model.addJoint(j1, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.0, 0.0, -L1])), "theta2")
    model.appendBodyToJoint(j2, pin.Inertia(m2, np.array([0.0, 0.0, -L2]), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "elbow", j2, (0.0, 0.0, 0.0))
    add_point_frame(model, "tip", j2, (0.0, 0.0, -L2))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -g, 0.0, 0.0, 0.0]))
    return model


def make_bridge(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> ContactBridge:
    """The contact bridge for validated builder parameters and the effects switched on."""
    g = params["g"] if "gravity" in effects else 0.0
    model = pinocchio_model(params["m1"], params["m2"], params["L1"], params["L2"], g)
    contacts = []
    if "stop" in effects:
        s = effects["stop"]
        contacts.append(JointStop("stop", "theta2", position=s["position"], side="lower", restitution=s["restitution"]))
    damping = None
    if "damping" in effects:
        damping = {"theta1": effects["damping"]["b1"], "theta2": effects["damping"]["b2"]}
    names: dict[tuple[str, ...], str] = {(): "unconstrained"}
    if contacts:
        names[("stop",)] = "constrained"
    # Actuate the shoulder only when a controller is asked for: an actuated bridge declares its
    # force-dependent guards on (t, x, u) and adds the control to every field evaluation.
    actuated = (SHOULDER,) if "controller" in effects else ()
    return ContactBridge(
        model,
        contacts,
        coordinate_names=COORDINATES,
        velocity_names=VELOCITIES,
        mode_names=names,
        joint_damping=damping,
        actuated=actuated,
        name="double_pendulum",
    )


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback: the double pendulum with only the effects named."""
    bridge = make_bridge(params, effects)
    L1, L2 = params["L1"], params["L2"]
    x0 = np.array([INITIAL_STATE[n] for n in STATE_NAMES])
    system = bridge.system("unconstrained", x0)
    stop = effects.get("stop")

    def geometry(mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        pos = bridge.frame_positions(np.asarray(x)[:2], ("elbow", "tip"))
        pivot = np.zeros(2)
        parts = {
            "link1": np.array([pivot, pos["elbow"]]),
            "link2": np.array([pos["elbow"], pos["tip"]]),
            "mass1": pos["elbow"][None, :],
            "mass2": pos["tip"][None, :],
        }
        if stop is not None:
            # The stop turns with link 1: draw it where link 2 lies at theta2 = position.
            ang = float(x[0]) + stop["position"]
            tip = pos["elbow"] + 0.35 * L2 * np.array([math.sin(ang), -math.cos(ang)])
            parts["stop"] = np.array([pos["elbow"], tip])
        return parts

    reach = 1.1 * (L1 + L2)
    control = None
    if "controller" in effects:
        # The shoulder's PD as the bundled joint-space one without gravity compensation.
        pd = effects["controller"]
        control = joint_pd(bridge, pd["kp"], pd["kd"], [pd["target"]], gravity=False)
    info = bridge.model_info(parameters=dict(params), effects=dict(effects))
    if "zeno" in effects:
        info[ZENO_WINDOW] = effects["zeno"]["window"]
    return Model(
        system=system,
        initial_mode="unconstrained",
        initial_state=dict(INITIAL_STATE),
        control=control,
        geometry=geometry,
        scenery={"support": np.array([[-0.25 * reach, 0.0], [0.25 * reach, 0.0]])},
        counters=bridge.counters,
        info=info,
    )


BUILDER = Builder(
    name="double_pendulum",
    description="double pendulum with a mechanical stop at theta2 = 0 (paper 003 Fig. 2)",
    parameters=PARAMETERS,
    effects=EFFECTS,
    build=build,
)


def make(parameters: dict[str, Any] | None = None, effects: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters and effects)."""
    return BUILDER.make(parameters, effects)
