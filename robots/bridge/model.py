"""The robot as the bridge's algorithms see it, and their scratch space.

In Pinocchio's style: a ``BridgeModel`` is fixed once built (the Pinocchio model with the spring
legs' foot frames, the resolved contacts, names, damping and actuation) and a ``BridgeData``
holds everything the algorithms write (the Pinocchio data, the evaluation counters and the
per-mode caches). The algorithms are free functions ``f(model, data, ...)`` in the sibling
modules.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.errors import ModelError

from .contacts import Contact, LegFrames, RigidContact, declared_contacts, finite_number, joint_id, resolve_contact

# Jacobians and frame velocities in the world's axes at the frame's origin: rows 0 and 2 are
# the world x and z of the (x, z) plane the robots move in.
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

COUNTERS = (
    "aba",
    "kkt",
    "jacobians",
    "kinematics",
    "spring_forces",
    "damping_evals",
    "actuation_evals",
    "impacts",
    "energy_evals",
    "cache_hits",
    "painleve_sticks",
)


@dataclass(frozen=True, eq=False)
class BridgeModel:
    """A planar robot and its contacts, resolved and checked.

    Attributes
    ----------
    name: the system's name (prefixes every error message).
    pin_model: the bridge's own copy of the Pinocchio model, with a ``<leg>_foot`` frame per spring leg.
    n: number of configuration coordinates, ``nq == nv``.
    contacts: the declarations by name, in declared order.
    rigid: resolved point contacts and joint stops by name, in declared order.
    legs: resolved spring legs by name, in declared order.
    coordinate_names, velocity_names: the n names of q and of v.
    damping_idx, damping_b: velocity indices with joint damping and their coefficients (N m s/rad or N s/m).
    actuated_idx: velocity index of each entry of the control u.
    """

    name: str
    pin_model: pin.Model
    n: int
    contacts: Mapping[str, Contact]
    rigid: Mapping[str, RigidContact]
    legs: Mapping[str, LegFrames]
    coordinate_names: tuple[str, ...]
    velocity_names: tuple[str, ...]
    damping_idx: np.ndarray
    damping_b: np.ndarray
    actuated_idx: np.ndarray

    @property
    def order(self) -> list[str]:
        """Contact names in declared order."""
        return list(self.contacts)

    @property
    def coulomb(self) -> bool:
        """Whether some contact has Coulomb friction (its strikes then choose stuck or slipping
        outcomes, ``friction``)."""
        return any(r.mu is not None for r in self.rigid.values())

    @property
    def timed(self) -> bool:
        """Whether constraint forces depend on the control: they do only through actuated joints."""
        return bool(self.actuated_idx.size)

    @property
    def guard_args(self) -> str:
        """``guard_args`` of the guards on constraint forces: on (t, x, u) when the robot is
        actuated, so that the crossing search evaluates them with the control at each
        interpolated time."""
        return "t,x,u" if self.timed else "x"


@dataclass(eq=False)
class ModeScratch:
    """One mode's one-entry caches, each keyed by the bytes of the state (and control).

    Attributes
    ----------
    dyn_key, dyn_val: the last (acceleration (nv,), constraint forces (rows,)).
    kin_key, kin_val: the last position-level guard values by contact name.
    post: per contact, the last normal force previewed after a plastic impact (key, N or N m).
    """

    dyn_key: bytes = b""
    dyn_val: tuple[np.ndarray, np.ndarray] | None = None
    kin_key: bytes = b""
    kin_val: dict[str, float] = field(default_factory=dict)
    post: dict[str, tuple[bytes, float]] = field(default_factory=dict)


@dataclass(eq=False)
class BridgeData:
    """What the bridge's algorithms write: one Pinocchio data (so a system built on it is not
    thread-safe), the evaluation counters and the per-mode caches."""

    pin_data: pin.Data
    counts: dict[str, int]
    modes: dict[str, ModeScratch] = field(default_factory=dict)
    #: The control of the last dynamics evaluation, and the controls the strike guards were
    #: last evaluated with, by state: a joint impact is resolved by the integrator without a
    #: control, at a state whose guards were evaluated with it (``control_at``).
    last_control: Any = None
    recent_controls: dict[bytes, Any] = field(default_factory=dict)
    #: ``preview(mode, t, x) -> u``: the control a mode will get at a state, given by the
    #: controller driving the robot (``ContactBridge.attach_control``); the mode after an impact
    #: is chosen with the contact forces under it. ``last_time``: the time of the last strike
    #: guard evaluated past its guard (s).
    preview: Callable[[str, float, np.ndarray], Any] | None = None
    last_time: float = 0.0

    def remember_control(self, x: np.ndarray, u: Any) -> None:
        """Remember the control u a guard was evaluated with at x (the last few states)."""
        if u is None:
            return
        if len(self.recent_controls) >= 16:
            self.recent_controls.pop(next(iter(self.recent_controls)))
        self.recent_controls[x.tobytes()] = u

    def control_at(self, x: np.ndarray) -> Any:
        """The control a guard was evaluated with at x, else that of the last dynamics evaluation."""
        return self.recent_controls.get(x.tobytes(), self.last_control)

    @classmethod
    def create(cls, model: BridgeModel) -> BridgeData:
        return cls(model.pin_model.createData(), dict.fromkeys(COUNTERS, 0))

    def scratch(self, mode: str) -> ModeScratch:
        """The caches of mode ``mode`` (created empty on first use)."""
        out = self.modes.get(mode)
        if out is None:
            out = self.modes[mode] = ModeScratch()
        return out


def build_model(
    model: pin.Model,
    contacts: Sequence[Contact],
    *,
    coordinate_names: Sequence[str] | None,
    velocity_names: Sequence[str] | None,
    joint_damping: Mapping[str, float] | None,
    actuated: Sequence[str],
    name: str,
) -> BridgeModel:
    """Check and resolve the ``ContactBridge`` arguments (see there); ``ModelError`` names the
    contact, frame or joint at fault."""
    _check_pin_model(model, name)
    own = pin.Model(model)  # private copy: foot frames are added to it
    declared = declared_contacts(contacts, name)
    rigid: dict[str, RigidContact] = {}
    legs: dict[str, LegFrames] = {}
    for contact in declared.values():
        resolved = resolve_contact(own, contact, name, list(declared))
        if isinstance(resolved, LegFrames):
            legs[contact.name] = resolved
        else:
            rigid[contact.name] = resolved
    n = int(own.nv)
    coords = _unique_names(coordinate_names, "coordinate_names", _joint_dof_names(own), n, name)
    vels = _unique_names(velocity_names, "velocity_names", tuple(f"{c}d" for c in coords), n, name)
    if set(coords) & set(vels):
        raise ModelError(f"{name}: coordinate and velocity names overlap: {sorted(set(coords) & set(vels))}")
    damping_idx, damping_b = _joint_damping(own, joint_damping, name)
    actuated_idx = _actuated_dofs(own, actuated, name)
    return BridgeModel(name, own, n, declared, rigid, legs, coords, vels, damping_idx, damping_b, actuated_idx)


def _check_pin_model(model: Any, name: str) -> None:
    if not isinstance(model, pin.Model):
        raise ModelError(f"{name}: model must be a pinocchio.Model, got {type(model).__name__}")
    if model.nq != model.nv:
        raise ModelError(
            f"{name}: the bridge needs model.nq == model.nv (prismatic and bounded revolute joints), "
            f"got nq={model.nq}, nv={model.nv}"
        )
    if model.nv < 1:
        raise ModelError(f"{name}: the model has no degree of freedom")


def _joint_dof_names(model: pin.Model) -> tuple[str, ...]:
    """Default coordinate names: a one-dof joint's name, or the name + dof index."""
    names = []
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        base = model.names[jid]
        names.extend([base] if j.nv == 1 else [f"{base}{i}" for i in range(j.nv)])
    return tuple(names)


def _unique_names(
    given: Iterable[Any] | None, label: str, default: Iterable[str], n: int, robot: str
) -> tuple[str, ...]:
    names = tuple(default if given is None else (str(s) for s in given))
    if len(names) != n or len(set(names)) != len(names):
        raise ModelError(f"{robot}: {label} must be {n} unique names, got {names}")
    return names


def _joint_damping(
    model: pin.Model, joint_damping: Mapping[str, float] | None, robot: str
) -> tuple[np.ndarray, np.ndarray]:
    """(velocity indices, coefficients) of the joints with positive damping."""
    idx: list[int] = []
    bs: list[float] = []
    for jname, b in (joint_damping or {}).items():
        b = finite_number(b, f"{robot}: joint_damping['{jname}']", low=0.0)
        if b > 0.0:
            j = model.joints[joint_id(model, jname, "joint_damping", robot)]
            idx.extend(range(j.idx_v, j.idx_v + j.nv))
            bs.extend([b] * j.nv)
    return np.array(idx, dtype=int), np.array(bs)


def _actuated_dofs(model: pin.Model, actuated: Sequence[str], robot: str) -> np.ndarray:
    """Velocity index of each actuated joint, in the order of the control's entries."""
    dofs = []
    for jname in actuated:
        j = model.joints[joint_id(model, jname, "actuated", robot)]
        if j.nv != 1:
            raise ModelError(f"{robot}: actuated joint '{jname}' must have one dof, has {j.nv}")
        dofs.append(j.idx_v)
    return np.array(dofs, dtype=int)
