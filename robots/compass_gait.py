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

Dynamics (Pinocchio's C++ algorithms through the native library, as model functions that the Python
loop and the compiled kernel both evaluate): the stance phase is the chain ``stance foot -RY- stance
leg -RY- swing leg`` rooted at the stance foot, integrated with ABA. The swing foot passes through
the ground around mid-stance (the model has no knees; the standard analysis ignores this scuffing),
so heel strike is

    guard = max(z_swing, dz_swing/dt, -(x_swing - x_stance))      [m]

past only when the swing foot is below the ground, moving down and in front of the stance foot
(the swing leg crosses the stance leg before the stance leg reaches the normal in the gaits of
interest; at the crossing both terms z and x are 0). eps is in metres of foot depth.

Heel strike is a plastic impact of the swing foot, the stance foot leaving the ground without
impulse: on a second Pinocchio model with a planar floating base at the hip and both feet as
point contacts, the generalised Newton impact gives the post-impact velocity with the new foot
pinned, ``v+ = v - M^-1 J^T (J M^-1 J^T)^-1 J v``. The legs then exchange roles:
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
from legsim.robots._native.calls import lsn_aba, lsn_frames, lsn_impact

from legsim.builders import Builder, Model, Param
from legsim.compiled.functions import model_function
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.model import ModeFunctions
from legsim.terrain import Terrain, slope_frame, walker_slope

from .bridge import add_point_frame, native, planar_floating_base
from .bridge.dynamics import keep, ptr
from .bridge.native import bare_aba, handle_for

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


#: The compass gait's parameter array p: the stance and impact models' native handles, the leg
#: length l (m), the stance model's swing-foot frame id, the impact's constraint block (the
#: swing foot ``foot2`` pinned in x and z: point, frame, sign, 2 rows), its restitution 0, and
#: the joint torques of the passive walker (N m, both 0), which the field hands to ABA as they
#: are rather than allocating a zero array at every evaluation.
CG_STANCE, CG_IMPACT, CG_L, CG_FOOT, CG_BLOCK, CG_COEFF, CG_TAU = 0, 1, 2, 3, 4, 8, 9


@model_function
def stance_field(t, x, u, p, dx):
    """(stanced, hipd, ABA accelerations of the stance chain, 0 for foot_x), shape (5,)."""
    dx[0], dx[1], dx[4] = x[2], x[3], 0.0
    lsn_aba(np.int64(p[CG_STANCE]), x.ctypes.data, ptr(x, 2), ptr(p, CG_TAU), ptr(dx, 2))


@model_function
def swing_foot_motion(x, p):
    """(x, z, vx, vz) of the swing foot relative to the stance foot (m, m/s)."""
    kin = np.empty(4)
    lsn_frames(np.int64(p[CG_STANCE]), x.ctypes.data, ptr(x, 2), np.int64(1), ptr(p, CG_FOOT), kin.ctypes.data)
    return kin


@model_function
def heel_strike_guard(t, x, u, p, g):
    """Heel strike ``max(swing foot height, its vertical velocity, -its lead)`` (m); nan once the
    hip is below the slope: the walker fell (the model has no body-ground contact, and a leg
    hanging under its pinned foot would swing on as a pendulum, a "gait" of legs through the
    ground)."""
    if p[CG_L] * math.cos(x[0]) < 0.0:
        g[0] = math.nan
        return
    kin = swing_foot_motion(x, p)
    g[0] = max(kin[1], kin[3], -kin[0])


@model_function
def heel_strike(e, t, x, u, p, out):
    """Plastic impact of the swing foot on the floating-base model (the stance foot leaving
    without impulse), then the legs exchange roles and foot_x advances by the step."""
    th, phi, thd, phid = x[0], x[1], x[2], x[3]
    leg = p[CG_L]
    qf = np.array([leg * math.sin(th), leg * math.cos(th), th, phi])
    vf = np.array([leg * thd * math.cos(th), -leg * thd * math.sin(th), thd, phid])
    v_plus = np.empty(4)
    level = np.zeros(2)  # the floor z = 0 of the model's tilted frame
    lsn_impact(np.int64(p[CG_IMPACT]), qf.ctypes.data, vf.ctypes.data, np.int64(1), ptr(p, CG_BLOCK),
               level.ctypes.data, ptr(p, CG_COEFF), v_plus.ctypes.data, np.int64(0))  # fmt: skip
    keep(level)
    step = swing_foot_motion(x, p)[0]
    out[0], out[1] = th + phi, -phi
    out[2], out[3] = v_plus[2] + v_plus[3], -v_plus[3]
    out[4] = x[4] + step


class CompassGait:
    """The compass gait: its Pinocchio models, its mode written as model functions (field,
    heel-strike guard and reset), energy, Jacobian and pictures."""

    def __init__(
        self, m: float = 5.0, mH: float = 10.0, a: float = 0.5, b: float = 0.5, g: float = 9.81, slope: float = 3.0
    ) -> None:
        self.m, self.mH, self.a, self.b, self.g, self.slope = m, mH, a, b, g, slope
        self.l = a + b
        self._kin_model = stance_model(m, mH, a, b, g, slope)
        self._impact_model = floating_model(m, mH, a, b, g, slope)
        self._kin_data = self._kin_model.createData()
        self._der_data = self._kin_model.createData()
        self._foot_id = self._kin_model.getFrameId("swing_foot")
        self._hip_id = self._kin_model.getFrameId("hip_point")
        self.handle = handle_for(self._kin_model, "compass_gait")
        impact = handle_for(self._impact_model, "compass_gait")
        foot2 = self._impact_model.getFrameId("foot2")
        self.functions = ModeFunctions(
            stance_field,
            heel_strike_guard,
            heel_strike,
            params=[self.handle, impact, self.l, self._foot_id, 1.0, foot2, 1.0, 2.0, 0.0, 0.0, 0.0],
            nan_breaks=True,
            range_note="the hip is below the slope: the walker fell",
        )

    def jacobian(self, t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
        """df/dx (5, 5) from ``pinocchio.computeABADerivatives`` (for saltation Jacobians)."""
        q, v = np.asarray(x[:2], dtype=float), np.asarray(x[2:4], dtype=float)
        pin.computeABADerivatives(self._kin_model, self._der_data, q, v, np.zeros(2))
        J = np.zeros((5, 5))
        J[0, 2] = J[1, 3] = 1.0
        J[2:4, 0:2] = self._der_data.ddq_dq
        J[2:4, 2:4] = self._der_data.ddq_dv
        return J

    def swing_foot(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Swing foot position (x, z) relative to the stance foot (m) and velocity (m/s), by
        Pinocchio's kinematics (for pictures and checks; the guard reads the same frame)."""
        q, v = np.asarray(x[:2], dtype=float), np.asarray(x[2:4], dtype=float)
        pin.forwardKinematics(self._kin_model, self._kin_data, q, v)
        p = pin.updateFramePlacement(self._kin_model, self._kin_data, self._foot_id).translation
        w = pin.getFrameVelocity(self._kin_model, self._kin_data, self._foot_id, pin.LOCAL_WORLD_ALIGNED).linear
        return np.array([p[0], p[2]]), np.array([w[0], w[2]])

    def step_length(self, x: np.ndarray) -> float:
        """Distance (m) from the stance foot to the swing foot along the slope."""
        return float(self.swing_foot(x)[0][0])

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Kinetic plus gravitational energy (J), the stance foot at height 0 along the slope."""
        q, v = np.asarray(x[:2], dtype=float), np.asarray(x[2:4], dtype=float)
        model, data = self._kin_model, self._kin_data
        return float(pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(model, data, q))

    def counters(self) -> dict[str, int]:
        """The stance model's evaluation counters (``ContactBridge.counters``)."""
        return native.counts(self.handle)

    def system(self, x0: Sequence[float] | np.ndarray | None = None) -> HybridSystem:
        mode = Mode(5, names=STATE_NAMES, jacobian=self.jacobian, units=STATE_UNITS, functions=self.functions)
        heel = Transition("stance", "stance", name="heel_strike")
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
        rot = slope_frame(self.slope)
        pts = {"stance_foot": origin, "hip": origin + hip, "swing_foot": origin + foot}
        world = {k: rot @ v for k, v in pts.items()}
        return {
            "stance_leg": np.array([world["stance_foot"], world["hip"]]),
            "swing_leg": np.array([world["hip"], world["swing_foot"]]),
            "hip_mass": world["hip"][None, :],
        }


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]], terrain: Terrain | None = None) -> Model:
    """Builder callback: the compass gait with the given parameters; a scene's ``[terrain]``
    slope (through the origin, falling towards +x) replaces its ``slope`` parameter."""
    slope = walker_slope(params["slope"], PARAMETERS["slope"].default, terrain, "compass_gait", -30.0, 30.0)
    params = {**params, "slope": slope}
    cg = CompassGait(params["m"], params["mH"], params["a"], params["b"], params["g"], params["slope"])
    x0 = np.array([INITIAL_STATE[n] for n in STATE_NAMES])
    system = cg.system(x0)
    rot = slope_frame(params["slope"])
    ground = np.array([rot @ np.array([-1.0, 0.0]), rot @ np.array([8.0, 0.0])])
    info = {
        "guard_units": {"heel_strike": "m (swing foot depth below the slope, in front and descending)"},
        "parameters": dict(params),
        "compass_gait": cg,
        "bare_aba": bare_aba(cg.handle),
        # the stance foot, the one contact (legsim.viz.contacts)
        "contact_points": lambda mode, x: {"stance_foot": cg.geometry(mode, x)["stance_leg"][0]},
    }
    return Model(
        system=system,
        initial_mode="stance",
        initial_state=dict(INITIAL_STATE),
        geometry=cg.geometry,
        scenery={"ground": ground},
        counters=cg.counters,
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
    terrain=True,
)


def make(parameters: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters)."""
    return BUILDER.make(parameters, {})
