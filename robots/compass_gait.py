"""The passive compass gait walker (Goswami, Thuilot & Espiau 1996/1998; McGeer 1990).

Two rigid legs of length l = a + b joined at the hip, each a point mass m at distance a from its
foot (b from the hip), and a point mass m_H at the hip, walking passively down a slope of angle
``slope``. We work in the slope's frame: x along the slope (downhill positive), z normal to it,
so the ground is z = 0 and gravity is tilted, ``g (sin slope, 0, -cos slope)``.

Coordinates (mode ``stance``; the stance foot is pinned):

* ``stance``: the stance leg's angle from the slope normal (rad), > 0 once the hip is ahead of
  (downhill of) the stance foot;
* ``hip``: the swing leg's angle relative to the stance leg (rad); the swing leg's own angle
  (from its foot up to the hip, from the slope normal) is ``stance + hip``;
* ``stanced``, ``hipd``: their rates (rad/s);
* ``foot_x``: position of the stance foot along the slope (m); it only grows by one step length
  at each heel strike (a cyclic coordinate, declared ``cyclic`` by the orbit scene).

Goswami et al. measure the angles from the true vertical, positive backwards: their support and
non-support angles are ``theta_s = -stance - slope`` and ``theta_ns = -(stance + hip) - slope``
(slope in rad), with rates ``-stanced`` and ``-(stanced + hipd)``.

Dynamics (Pinocchio through ``legsim.robots.bridge.ContactBridge``): the stance phase is the chain
``stance foot -RY- stance leg -RY- swing leg`` rooted at the stance foot, integrated with
``pinocchio.aba``. The swing foot passes through the ground around mid-stance (the model has no
knees; the standard analysis ignores this scuffing), so heel strike is

    guard = max(z_swing, dz_swing/dt, -(x_swing - x_stance))      [m]

past only when the swing foot is below the ground, moving down and in front of the stance foot
(the swing leg crosses the stance leg before the stance leg reaches the normal in the gaits of
interest; at the crossing both terms z and x are 0). eps is in metres of foot depth.

Heel strike is a plastic impact of the swing foot, the stance foot leaving the ground without
impulse: on a second Pinocchio model with a planar floating base at the hip and both feet as
point contacts, ``ContactBridge.impact_velocity`` gives the post-impact velocity with the new
foot pinned, ``v+ = v - M^-1 J^T (J M^-1 J^T)^-1 J v``. The legs then exchange roles:
``(stance, hip) -> (stance + hip, -hip)`` and the rates likewise; ``foot_x`` advances by the step.
The stance foot is assumed to stay on the ground (its normal force is not checked). A hip below
the slope ends a run (status ``model_breakdown``): the walker fell.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.builders import Builder, Model, Param
from legsim.errors import ModelBreakdown
from legsim.hybrid import HybridSystem, Mode, Transition

from .bridge import ContactBridge, PointContact, add_point_frame, planar_floating_base

STATE_NAMES = ("stance", "hip", "stanced", "hipd", "foot_x")
STATE_UNITS = ("rad", "rad", "rad/s", "rad/s", "m")

PARAMETERS = {
    "m": Param(5.0, "mass of each leg (a point at distance a from the foot)", "kg", low=0.0, low_open=True),
    "mH": Param(10.0, "hip mass", "kg", low=0.0),
    "a": Param(0.5, "distance from a foot to its leg's mass", "m", low=0.0, low_open=True),
    "b": Param(0.5, "distance from a leg's mass to the hip", "m", low=0.0, low_open=True),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0, low_open=True),
    "slope": Param(3.0, "slope angle (downhill in +x)", "deg", low=-30.0, high=30.0),
}

#: The stable period-one gait at the standard parameters (3 deg), just after heel strike, from
#: tests/test_orbits_walkers.py's independent reference (scipy, rtol 1e-12), rounded.
INITIAL_STATE = {"stance": -0.271029, "hip": 0.542057, "stanced": 1.092384, "hipd": -0.715010, "foot_x": 0.0}


def _gravity(g: float, slope_deg: float) -> pin.Motion:
    s = math.radians(slope_deg)
    return pin.Motion(np.array([g * math.sin(s), 0.0, -g * math.cos(s), 0.0, 0.0, 0.0]))


def stance_model(m: float, mH: float, a: float, b: float, g: float, slope: float) -> pin.Model:
    """The stance chain: RY joint ``stance`` at the stance foot (the origin), RY joint ``hip``
    at the hip; frames ``hip_point`` and ``swing_foot``."""
    leg_length = a + b
    model = pin.Model()
    j1 = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "stance")
    model.appendBodyToJoint(j1, pin.Inertia(m, np.array([0.0, 0.0, a]), np.zeros((3, 3))), pin.SE3.Identity())
    if mH > 0:
        model.appendBodyToJoint(
            j1, pin.Inertia(mH, np.array([0.0, 0.0, leg_length]), np.zeros((3, 3))), pin.SE3.Identity()
        )
    j2 = model.addJoint(j1, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.0, 0.0, leg_length])), "hip")
    model.appendBodyToJoint(j2, pin.Inertia(m, np.array([0.0, 0.0, -b]), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "hip_point", j2, (0.0, 0.0, 0.0))
    add_point_frame(model, "swing_foot", j2, (0.0, 0.0, -leg_length))
    model.gravity = _gravity(g, slope)
    return model


def floating_model(m: float, mH: float, a: float, b: float, g: float, slope: float) -> pin.Model:
    """Both legs free: planar floating base (x, z, pitch) at the hip carrying leg 1 (pitch is its
    angle), RY joint ``hip`` carrying leg 2; frames ``foot1`` and ``foot2``."""
    leg_length = a + b
    model = pin.Model()
    jp = planar_floating_base(model, names=("hip_x", "hip_z", "leg1"))
    model.appendBodyToJoint(jp, pin.Inertia(m, np.array([0.0, 0.0, -b]), np.zeros((3, 3))), pin.SE3.Identity())
    if mH > 0:
        model.appendBodyToJoint(jp, pin.Inertia(mH, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    j2 = model.addJoint(jp, pin.JointModelRY(), pin.SE3.Identity(), "hip")
    model.appendBodyToJoint(j2, pin.Inertia(m, np.array([0.0, 0.0, -b]), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "foot1", jp, (0.0, 0.0, -leg_length))
    add_point_frame(model, "foot2", j2, (0.0, 0.0, -leg_length))
    model.gravity = _gravity(g, slope)
    return model


class CompassGait:
    """The compass gait's pieces: field, heel-strike guard and reset, energy, kinematics."""

    def __init__(
        self, m: float = 5.0, mH: float = 10.0, a: float = 0.5, b: float = 0.5, g: float = 9.81, slope: float = 3.0
    ) -> None:
        self.m, self.mH, self.a, self.b, self.g, self.slope = m, mH, a, b, g, slope
        self.l = a + b
        self.stance_bridge = ContactBridge(
            stance_model(m, mH, a, b, g, slope),
            (),
            coordinate_names=("stance", "hip"),
            velocity_names=("stanced", "hipd"),
            mode_names={(): "stance"},
            name="compass_gait",
        )
        self.impact_bridge = ContactBridge(
            floating_model(m, mH, a, b, g, slope),
            (PointContact("foot1", "foot1"), PointContact("foot2", "foot2", releases=("foot1",))),
            coordinate_names=("hip_x", "hip_z", "leg1", "hip"),
            name="compass_gait_impact",
        )
        self._mode4 = self.stance_bridge.mode("stance")
        # Own kinematics buffer for guards and pictures (the bridge's Data serves the field).
        self._kin_model = self.stance_bridge.model
        self._kin_data = self._kin_model.createData()
        self._der_data = self._kin_model.createData()
        self._foot_id = self._kin_model.getFrameId("swing_foot")
        self._hip_id = self._kin_model.getFrameId("hip_point")

    # -- continuous dynamics ---------------------------------------------------------------
    def field(self, t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
        out = np.zeros(5)
        out[:4] = self._mode4.field(t, x[:4], u)
        return out

    def jacobian(self, t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
        """df/dx (5, 5) from ``pinocchio.computeABADerivatives`` (for saltation Jacobians)."""
        q, v = np.asarray(x[:2], dtype=float), np.asarray(x[2:4], dtype=float)
        pin.computeABADerivatives(self._kin_model, self._der_data, q, v, np.zeros(2))
        J = np.zeros((5, 5))
        J[0, 2] = J[1, 3] = 1.0
        J[2:4, 0:2] = self._der_data.ddq_dq
        J[2:4, 2:4] = self._der_data.ddq_dv
        return J

    # -- kinematics ------------------------------------------------------------------------
    def swing_foot(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Swing foot position (x, z) relative to the stance foot (m) and velocity (m/s)."""
        q, v = np.asarray(x[:2], dtype=float), np.asarray(x[2:4], dtype=float)
        pin.forwardKinematics(self._kin_model, self._kin_data, q, v)
        p = pin.updateFramePlacement(self._kin_model, self._kin_data, self._foot_id).translation
        w = pin.getFrameVelocity(
            self._kin_model, self._kin_data, self._foot_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        ).linear
        return np.array([p[0], p[2]]), np.array([w[0], w[2]])

    def heel_strike_guard(self, x: np.ndarray) -> float:
        """max(swing foot height, its vertical velocity, -(its lead over the stance foot)) [m].

        Raises ModelBreakdown once the hip is below the slope: the walker has fallen (the model
        has no body-ground contact, and a leg hanging under its pinned foot would swing on as a
        pendulum, a "gait" of legs through the ground)."""
        hip_z = self.l * math.cos(float(x[0]))
        if hip_z < 0.0:
            raise ModelBreakdown(
                f"compass_gait: the hip is {-hip_z:.3g} m below the slope (stance leg at "
                f"{float(x[0]):.3g} rad from the normal): the walker fell"
            )
        p, w = self.swing_foot(x)
        return max(p[1], w[1], -p[0])

    def step_length(self, x: np.ndarray) -> float:
        """Distance (m) from the stance foot to the swing foot along the slope."""
        return float(self.swing_foot(x)[0][0])

    # -- heel strike -------------------------------------------------------------------------
    def heel_strike(self, x: np.ndarray) -> np.ndarray:
        """Plastic impact of the swing foot, then the legs exchange roles."""
        th, phi, thd, phid = (float(v) for v in x[:4])
        leg_length = self.l
        q_f = np.array([leg_length * math.sin(th), leg_length * math.cos(th), th, phi])
        v_f = np.array([leg_length * thd * math.cos(th), -leg_length * thd * math.sin(th), thd, phid])
        v_plus = self.impact_bridge.impact_velocity([("foot2", 0.0)], q_f, v_f)
        new_stance_rate = v_plus[2] + v_plus[3]
        return np.array([th + phi, -phi, new_stance_rate, -v_plus[3], x[4] + self.step_length(x)])

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Kinetic plus gravitational energy (J), the stance foot at height 0 along the slope."""
        return self.stance_bridge.energy("stance", np.asarray(x, dtype=float)[:4])

    def system(self, x0: Sequence[float] | np.ndarray | None = None) -> HybridSystem:
        from .bridge.walker_twins import compass_gait_twin

        mode = Mode(
            5,
            self.field,
            names=STATE_NAMES,
            jacobian=self.jacobian,
            compiled=compass_gait_twin(self),
            units=STATE_UNITS,
        )
        heel = Transition("stance", "stance", guard=self.heel_strike_guard, reset=self.heel_strike, name="heel_strike")
        return HybridSystem(
            {"stance": mode},
            [heel],
            name="compass_gait",
            energy=self.energy,
            initial=None if x0 is None else ("stance", np.asarray(x0, dtype=float)),
        )

    def geometry(self, mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        """Legs and masses in the world (x, z) plane (m), the slope drawn descending to +x."""
        x = np.asarray(x, dtype=float)
        q = x[:2]
        pin.forwardKinematics(self._kin_model, self._kin_data, q)
        hip = pin.updateFramePlacement(self._kin_model, self._kin_data, self._hip_id).translation[[0, 2]]
        foot = pin.updateFramePlacement(self._kin_model, self._kin_data, self._foot_id).translation[[0, 2]]
        origin = np.array([x[4], 0.0])
        rot = _slope_rotation(self.slope)
        pts = {"stance_foot": origin, "hip": origin + hip, "swing_foot": origin + foot}
        world = {k: rot @ v for k, v in pts.items()}
        return {
            "stance_leg": np.array([world["stance_foot"], world["hip"]]),
            "swing_leg": np.array([world["hip"], world["swing_foot"]]),
            "hip_mass": world["hip"][None, :],
        }


def _slope_rotation(slope_deg: float) -> np.ndarray:
    s = math.radians(slope_deg)
    # Slope coordinates (x downhill, z normal) to world coordinates (z up).
    return np.array([[math.cos(s), math.sin(s)], [-math.sin(s), math.cos(s)]])


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]]) -> Model:
    """Builder callback: the compass gait with the given parameters."""
    cg = CompassGait(params["m"], params["mH"], params["a"], params["b"], params["g"], params["slope"])
    x0 = np.array([INITIAL_STATE[n] for n in STATE_NAMES])
    system = cg.system(x0)
    rot = _slope_rotation(params["slope"])
    ground = np.array([rot @ np.array([-1.0, 0.0]), rot @ np.array([8.0, 0.0])])
    info = {
        "guard_units": {"heel_strike": "m (swing foot depth below the slope, in front and descending)"},
        "parameters": dict(params),
        "compass_gait": cg,
        # the stance foot, the one contact (legsim.viz.contacts)
        "contact_points": lambda mode, x: {"stance_foot": cg.geometry(mode, x)["stance_leg"][0]},
    }
    return Model(
        system=system,
        initial_mode="stance",
        initial_state=dict(INITIAL_STATE),
        geometry=cg.geometry,
        scenery={"ground": ground},
        counters=cg.stance_bridge.counters,
        info=info,
    )


BUILDER = Builder(
    name="compass_gait",
    description=(
        "passive compass gait walker on a slope (Goswami et al.): two rigid legs, hip mass, plastic heel strike"
    ),
    parameters=PARAMETERS,
    effects={},
    build=build,
)


def make(parameters: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters)."""
    return BUILDER.make(parameters, {})
