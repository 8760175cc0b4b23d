"""The rimless wheel rolling down a slope (McGeer 1990; Coleman, Chatterjee & Ruina 1997).

A hub of mass m (and rotational inertia I about the hub; I = 0 is McGeer's point-mass wheel)
carries ``spokes`` massless spokes of length l, 2 alpha = 2 pi / spokes apart. One spoke tip is
pinned to the slope at a time; the wheel rotates about it as an inverted pendulum. We work in
the slope's frame (x downhill along the slope, z normal to it; gravity tilted by ``slope``).

Coordinates (mode ``stance``):

* ``theta``: the stance spoke's angle from the slope normal (rad), > 0 once the hub is ahead of
  (downhill of) the contact; a stance phase runs from -alpha to alpha;
* ``thetad``: its rate (rad/s);
* ``foot_x``: position of the contact along the slope (m), a cyclic coordinate.

Transitions (Pinocchio's C++ algorithms through the native library, as model functions that the
Python loop and the compiled kernel both evaluate: the stance phase is one RY joint at the
contact integrated by ABA; an impact conserves the angular momentum about the striking spoke's
tip, computed from the centroidal momentum plus the moment of the linear momentum, and divides it
by the rotational inertia about the new contact from CRBA; a floating-base impact would be
singular for the point-mass wheel, I = 0):

* ``impact``: the leading spoke strikes, ``theta`` reaching alpha while increasing; guard
  ``max(alpha - theta, -thetad)`` [rad]. Plastic impact on the new spoke, the old one leaving
  without impulse; then ``theta -> theta - 2 alpha``, ``foot_x`` += the step.
* ``back_impact``: rolling back, the trailing spoke strikes at ``theta = -alpha``; guard
  ``max(theta + alpha, thetad)`` [rad]; ``theta -> theta + 2 alpha``.

Closed forms (used by the tests): angular momentum about the new contact is conserved, so
``thetad+ = c thetad-``, ``c = (I + m l^2 cos 2 alpha) / (I + m l^2)``. Over a stance phase the
energy gives ``thetad-^2 = thetad+^2 + K``, ``K = 4 m g l sin(alpha) sin(slope) / (I + m l^2)``,
so the step map is ``w -> c sqrt(w^2 + K)``, its fixed point ``w*^2 = c^2 K / (1 - c^2)`` and its
derivative there ``c^2`` (the step-to-step contraction). Step length ``2 l sin(alpha)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin
from legsim.robots._native.calls import lsn_aba, lsn_crba, lsn_momentum_about

from legsim.builders import Builder, Model, Param
from legsim.compiled.functions import model_function
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.model import ModeFunctions
from legsim.terrain import Terrain, slope_frame, walker_slope

from .bridge import add_point_frame, native
from .bridge.dynamics import ptr
from .bridge.native import bare_aba, handle_for

STATE_NAMES = ("theta", "thetad", "foot_x")
STATE_UNITS = ("rad", "rad/s", "m")

PARAMETERS = {
    "m": Param(1.0, "hub mass", "kg", low=0.0, low_open=True),
    "I": Param(0.0, "rotational inertia about the hub (0: point mass, McGeer)", "kg m^2", low=0.0),
    "l": Param(1.0, "spoke length", "m", low=0.0, low_open=True),
    "spokes": Param(10, "number of spokes (2 alpha = 2 pi / spokes)", "", low=3, high=1000),
    "g": Param(9.81, "gravitational acceleration", "m/s^2", low=0.0, low_open=True),
    "slope": Param(5.0, "slope angle (downhill in +x)", "deg", low=-45.0, high=45.0),
}

#: Just after an impact on the steady rolling orbit of the default parameters (closed form).
INITIAL_STATE = {"theta": -math.pi / 10, "thetad": 1.41496, "foot_x": 0.0}


def _gravity(g: float, slope_deg: float) -> pin.Motion:
    s = math.radians(slope_deg)
    return pin.Motion(np.array([g * math.sin(s), 0.0, -g * math.cos(s), 0.0, 0.0, 0.0]))


def _hub_inertia(m: float, inertia: float, com: np.ndarray) -> pin.Inertia:
    return pin.Inertia(m, com, np.diag([inertia, inertia, inertia]))


#: The rimless wheel's parameter array p: the stance model's native handle, alpha (rad), the
#: front and back spoke tips' frame ids.
RW_HANDLE, RW_ALPHA, RW_FRONT, RW_BACK = 0, 1, 2, 3


@model_function
def stance_field(t, x, u, p, dx):
    """(thetad, ABA acceleration about the stance tip, 0 for foot_x), shape (3,)."""
    tau = np.zeros(1)
    dx[0], dx[2] = x[1], 0.0
    lsn_aba(np.int64(p[RW_HANDLE]), x.ctypes.data, ptr(x, 1), tau.ctypes.data, ptr(dx, 1))


@model_function
def spoke_guards(t, x, u, p, g):
    """``max(alpha - theta, -thetad)`` (the front spoke, rolling forward) and ``max(theta +
    alpha, thetad)`` (the back spoke, rolling back) (rad)."""
    g[0] = max(p[RW_ALPHA] - x[0], -x[1])
    g[1] = max(x[0] + p[RW_ALPHA], x[1])


@model_function
def spoke_impact(e, t, x, u, p, out):
    """Plastic impact of the front (e = 0) or back (e = 1) spoke: the angular momentum about the
    striking tip P, ``H_P = (spin about the centre of mass) + (c - P) x m v_c``, is conserved, and
    after it the wheel turns about P with ``H_P = M(theta') thetad'``."""
    h = np.int64(p[RW_HANDLE])
    frame = p[RW_FRONT] if e == 0 else p[RW_BACK]
    shift = -2.0 * p[RW_ALPHA] if e == 0 else 2.0 * p[RW_ALPHA]
    momentum = np.empty(3)
    lsn_momentum_about(h, x.ctypes.data, ptr(x, 1), np.int64(frame), momentum.ctypes.data)
    new = np.array([x[0] + shift])
    inertia = np.empty(1)
    lsn_crba(h, new.ctypes.data, inertia.ctypes.data)
    out[0] = new[0]
    out[1] = momentum[0] / inertia[0]
    out[2] = x[2] + momentum[1]


class RimlessWheel:
    """The rimless wheel: its Pinocchio model, its mode written as model functions (field, the
    two spokes' guards and impacts), energy and pictures."""

    def __init__(
        self,
        m: float = 1.0,
        I: float = 0.0,  # noqa: E741 -- the paper's symbol and the scene parameter's name
        l: float = 1.0,  # noqa: E741 -- the paper's symbol and the scene parameter's name
        spokes: int = 10,
        g: float = 9.81,
        slope: float = 5.0,
    ) -> None:
        self.m, self.I, self.l, self.spokes, self.g, self.slope = m, I, l, int(spokes), g, slope
        self.alpha = math.pi / self.spokes
        chain = pin.Model()
        j = chain.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "theta")
        chain.appendBodyToJoint(j, _hub_inertia(m, I, np.array([0.0, 0.0, l])), pin.SE3.Identity())
        add_point_frame(chain, "hub", j, (0.0, 0.0, l))
        a2 = 2 * self.alpha
        # The neighbouring spoke tips in the stance joint's frame (the hub at (0, 0, l)).
        add_point_frame(chain, "front_tip", j, (l * math.sin(a2), 0.0, l - l * math.cos(a2)))
        add_point_frame(chain, "back_tip", j, (-l * math.sin(a2), 0.0, l - l * math.cos(a2)))
        chain.gravity = _gravity(g, slope)
        self._model = chain
        self._data = chain.createData()
        self.handle = handle_for(chain, "rimless_wheel")
        front, back = chain.getFrameId("front_tip"), chain.getFrameId("back_tip")
        self.functions = ModeFunctions(
            stance_field, spoke_guards, spoke_impact, params=[self.handle, self.alpha, front, back]
        )

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Kinetic plus gravitational energy (J), the contact at height 0 along the slope."""
        q, v = np.array([float(x[0])]), np.array([float(x[1])])
        return float(
            pin.computeKineticEnergy(self._model, self._data, q, v)
            + pin.computePotentialEnergy(self._model, self._data, q)
        )

    def counters(self) -> dict[str, int]:
        """The model's evaluation counters (``ContactBridge.counters``)."""
        return native.counts(self.handle)

    def system(self, x0: Sequence[float] | np.ndarray | None = None) -> HybridSystem:
        mode = Mode(3, names=STATE_NAMES, units=STATE_UNITS, functions=self.functions)
        transitions = [
            Transition("stance", "stance", name="impact"),
            Transition("stance", "stance", name="back_impact"),
        ]
        return HybridSystem(
            {"stance": mode},
            transitions,
            name="rimless_wheel",
            energy=self.energy,
            initial=None if x0 is None else ("stance", np.asarray(x0, dtype=float)),
        )

    def geometry(self, mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        """Spokes and hub in the world (x, z) plane (m), the slope descending to +x."""
        th, foot = float(x[0]), float(x[2])
        spoke_length = self.l
        hub = np.array([foot + spoke_length * math.sin(th), spoke_length * math.cos(th)])
        rot = slope_frame(self.slope)
        spokes = []
        for k in range(self.spokes):
            ang = th + 2 * self.alpha * k
            tip = hub - spoke_length * np.array([math.sin(ang), math.cos(ang)])
            spokes.append(rot @ hub)
            spokes.append(rot @ tip)
        return {"spokes": np.array(spokes), "hub": (rot @ hub)[None, :]}


def build(params: dict[str, Any], effects: dict[str, dict[str, Any]], terrain: Terrain | None = None) -> Model:
    """Builder callback: the rimless wheel with the given parameters; a scene's ``[terrain]``
    slope (through the origin, falling towards +x) replaces its ``slope`` parameter."""
    slope = walker_slope(params["slope"], PARAMETERS["slope"].default, terrain, "rimless_wheel", -45.0, 45.0)
    params = {**params, "slope": slope}
    rw = RimlessWheel(params["m"], params["I"], params["l"], params["spokes"], params["g"], params["slope"])
    initial = dict(INITIAL_STATE)
    initial["theta"] = -rw.alpha
    x0 = np.array([initial[n] for n in STATE_NAMES])
    system = rw.system(x0)
    rot = slope_frame(params["slope"])
    ground = np.array([rot @ np.array([-1.0, 0.0]), rot @ np.array([12.0, 0.0])])
    info = {
        "guard_units": {
            "impact": "rad (spoke angle past alpha, rolling forward)",
            "back_impact": "rad (spoke angle past -alpha, rolling back)",
        },
        "parameters": dict(params),
        "rimless_wheel": rw,
        "bare_aba": bare_aba(rw.handle),
        # the stance spoke's tip, the one contact (legsim.viz.contacts)
        "contact_points": lambda mode, x: {"stance_spoke": rot @ np.array([float(x[2]), 0.0])},
    }
    return Model(
        system=system,
        initial_mode="stance",
        initial_state=initial,
        geometry=rw.geometry,
        scenery={"ground": ground},
        counters=rw.counters,
        info=info,
    )


BUILDER = Builder(
    name="rimless_wheel",
    description="rimless wheel rolling down a slope (McGeer; Coleman et al.): plastic spoke impacts",
    parameters=PARAMETERS,
    effects={},
    build=build,
    terrain=True,
)


def make(parameters: dict[str, Any] | None = None) -> Model:
    """Build the model as a scene would (validated parameters)."""
    return BUILDER.make(parameters, {})
