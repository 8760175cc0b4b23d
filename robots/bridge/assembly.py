"""``ContactBridge``: the facade that composes the bridge's modules into a ``legsim.HybridSystem``.

It owns a ``BridgeModel`` (fixed), a ``BridgeData`` (scratch) and the ``ModeCatalog``; every
method resolves the mode and hands over to the free functions of ``dynamics``, ``guards``,
``impacts`` and ``transitions``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.hybrid import HybridSystem, JointCrossing, Mode, Transition

from . import dynamics, guards, impacts
from .contacts import Contact, frame_id
from .joint import resolve
from .model import BridgeData, build_model
from .modes import ModeCatalog, SubsetKey
from .transitions import outgoing


class ContactBridge:
    """Builds a ``legsim.HybridSystem`` from a Pinocchio model and its contacts.

    Parameters
    ----------
    model:
        A Pinocchio model of a planar robot moving in the world (x, z) plane with gravity
        ``model.gravity`` (set it to zero to switch gravity off). It is copied, never changed.
    contacts:
        ``PointContact``, ``JointStop`` and ``SpringLeg`` records with unique names.
    coordinate_names:
        Names of the nv configuration coordinates (default: the joint names).
    velocity_names:
        Names of the nv velocities (default: each coordinate name + ``"d"``).
    mode_names:
        Optional readable names of contact subsets, ``{("left", "right"): "both", (): "aerial"}``;
        other subsets are named by their contacts joined with ``+`` (``"free"`` when empty).
    joint_damping:
        Optional viscous damping per joint name (N m s/rad or N s/m): ``tau -= b v``.
    actuated:
        Joint names driven by the control ``u`` (one entry of u per joint, N m or N). With any,
        the guards that depend on constraint forces (releases, plastic impacts) are declared
        ``guard_args="t,x,u"`` so that the integrator evaluates them with the control at the
        interpolated crossing time.
    name:
        Name of the system.

    Raises
    ------
    ModelError
        naming the contact, frame or joint at fault.
    """

    def __init__(
        self,
        model: pin.Model,
        contacts: Sequence[Contact] = (),
        *,
        coordinate_names: Sequence[str] | None = None,
        velocity_names: Sequence[str] | None = None,
        mode_names: Mapping[SubsetKey, str] | None = None,
        joint_damping: Mapping[str, float] | None = None,
        actuated: Sequence[str] = (),
        name: str = "robot",
    ) -> None:
        self._model = build_model(
            model,
            contacts,
            coordinate_names=coordinate_names,
            velocity_names=velocity_names,
            joint_damping=joint_damping,
            actuated=actuated,
            name=name,
        )
        self._data = BridgeData.create(self._model)
        self._modes = ModeCatalog(self._model, mode_names)
        self._twins: list[Any] = []  # compiled twins, whose evaluations counters() adds

    # -- the robot ------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """Name of the system."""
        return self._model.name

    @property
    def model(self) -> pin.Model:
        """The bridge's own copy of the Pinocchio model, with a ``<leg>_foot`` frame per spring leg."""
        return self._model.pin_model

    @property
    def data(self) -> pin.Data:
        """The one Pinocchio data every evaluation writes (a system built on it is not thread-safe)."""
        return self._data.pin_data

    @property
    def n(self) -> int:
        """Number of configuration coordinates (nq == nv)."""
        return self._model.n

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """Names of the nv configuration coordinates."""
        return self._model.coordinate_names

    @property
    def velocity_names(self) -> tuple[str, ...]:
        """Names of the nv velocities."""
        return self._model.velocity_names

    @property
    def _act_idx(self) -> np.ndarray:
        """Velocity index of each entry of the control u (the robots' tests check the mapping)."""
        return self._model.actuated_idx

    @property
    def actuated_dofs(self) -> np.ndarray:
        """Velocity index of each actuated joint, in the order of the control's entries."""
        return self._model.actuated_idx.copy()

    @property
    def contacts(self) -> tuple[Contact, ...]:
        """The contacts, in declared order."""
        return tuple(self._model.contacts.values())

    # -- modes ----------------------------------------------------------------------------
    def mode_name(self, active: Iterable[str]) -> str:
        """Name of the mode whose active contacts are ``active``."""
        return self._modes.name_of(active)

    def active_contacts(self, mode: str) -> tuple[str, ...]:
        """The active contacts of mode ``mode``, in declared order."""
        return self._modes.active_contacts(mode)

    def state_names(self, mode: str) -> tuple[str, ...]:
        """Coordinate names of mode ``mode``: q, v, then one foothold (m) per active spring leg."""
        return self._modes.spec(mode).names

    # -- dynamics -------------------------------------------------------------------------
    def field(self, mode: str) -> Callable[[float, np.ndarray, Any], np.ndarray]:
        """The vector field ``f(t, x, u) = (v, a)`` of mode ``mode``; the footholds are constant."""
        spec = self._modes.spec(mode)
        model, data = self._model, self._data
        n, dim = model.n, spec.dim

        def f(t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
            a, _ = dynamics.dynamics(model, data, spec, x, u)
            out = np.zeros(dim)
            out[:n] = x[n : 2 * n]
            out[n : 2 * n] = a
            return out

        return f

    def constraint_forces(self, mode: str, x: np.ndarray, u: Any = None) -> dict[str, np.ndarray]:
        """Constraint forces of the active rigid contacts at state x: ``{name: lambda}`` with
        ``lambda = (f_x, f_z)`` (N) for a sticking point contact, ``(f_z,)`` for a frictionless
        one and ``(tau,)`` (N m or N) for a joint stop; the last entry is the normal force, >= 0
        when the contact pushes the robot into its domain."""
        spec = self._modes.spec(mode)
        return dynamics.constraint_forces(self._model, self._data, spec, np.asarray(x, dtype=float), u)

    def leg_forces(self, mode: str, x: np.ndarray) -> dict[str, float]:
        """Axial force (N, > 0 pushing the hip away from the foot) of each active spring leg."""
        return dynamics.leg_forces(self._model, self._data, self._modes.spec(mode), x)

    def impact_velocity(self, rows: Sequence[tuple[str, float]], q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Post-impact velocity (nv,) of the generalised Newton impact.

        ``rows``: ``(contact name, restitution)`` of the contacts constrained at the impact;
        each contact's Jacobian rows J_i get ``J_i v+ = -c_i J_i v``.
        ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)``, ``w = -c J v`` row-wise.
        """
        return impacts.impact_velocity(self._model, self._data, rows, q, v)

    # -- guards ---------------------------------------------------------------------------
    def initial_check(self) -> Callable[[str, np.ndarray, float], str | None]:
        """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x,
        eps)`` names the first inactive joint stop or point contact whose position lies past it
        by more than eps (rad or m), else None."""
        return guards.initial_check(self._model, self._data, lambda mode: self._modes.spec(mode).active)

    def model_info(self, **entries: Any) -> dict[str, Any]:
        """``Model.info`` of a robot built on this bridge: the entries the core and the tools read
        (``guard_units``, ``bridge``, ``initial_check``), then the builder's own ``entries``."""
        return {"guard_units": self.guard_units(), "bridge": self, "initial_check": self.initial_check(), **entries}

    def guard_units(self) -> dict[str, str]:
        """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
        return guards.guard_units(self._model)

    # -- energy and kinematics for pictures -----------------------------------------------
    def energy(self, mode: str, x: np.ndarray) -> float:
        """Total mechanical energy (J): kinetic + gravity (``model.gravity``) + leg springs."""
        spec = self._modes.spec(mode)
        return dynamics.energy(self._model, self._data, spec, np.asarray(x, dtype=float))

    def frame_positions(self, q: np.ndarray, frames: Iterable[str]) -> dict[str, np.ndarray]:
        """World (x, z) positions (m) of the named frames at configuration q."""
        pm, pd = self._model.pin_model, self._data.pin_data
        pin.forwardKinematics(pm, pd, np.asarray(q, dtype=float))
        out = {}
        for fname in frames:
            fid = frame_id(pm, fname, "frame_positions", self.name)
            t = pin.updateFramePlacement(pm, pd, fid).translation
            out[fname] = np.array([t[0], t[2]])
        return out

    def foot_positions(self, mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        """World (x, z) position (m) of every spring leg's foot: the foothold in stance, the
        end of the leg at rest length and flight angle otherwise."""
        spec = self._modes.spec(mode)
        x = np.asarray(x, dtype=float)
        n = self.n
        out = {lg.leg.name: np.array([x[2 * n + i], lg.leg.ground]) for i, lg in enumerate(spec.springs)}
        if spec.flight_legs:
            pos = self.frame_positions(x[:n], [f"{lg.leg.name}_foot" for lg in spec.flight_legs])
            for lg in spec.flight_legs:
                out[lg.leg.name] = pos[f"{lg.leg.name}_foot"]
        return out

    # -- the hybrid system ----------------------------------------------------------------
    def mode(self, mode: str) -> Mode:
        """The legsim ``Mode`` of contact mode ``mode``."""
        spec = self._modes.spec(mode)
        return Mode(spec.dim, self.field(mode), names=spec.names, units=spec.units)

    def expand(self, mode: str) -> tuple[Mode, list[Transition]]:
        """``HybridSystem`` expand callback: the mode and its outgoing transitions."""
        spec = self._modes.spec(mode)
        transitions = outgoing(self._model, self._data, self._modes, spec)
        # numba and the native library load with the first mode
        if self._model.coulomb:
            from .friction_twins import coulomb_twin as make_twin
        else:
            from .twin_build import bridge_twin as make_twin
        twin = make_twin(self._model, self._modes, spec, transitions)
        self.count_twin(twin)
        return dataclasses.replace(self.mode(mode), compiled=twin), transitions

    def count_twin(self, twin: Any) -> None:
        """Report a compiled twin's evaluations (its own counters) in ``counters()``."""
        if twin is not None:
            self._twins.append(twin)

    def system(self, initial_mode: str | None = None, x0: Any = None, *, energy: bool = True) -> HybridSystem:
        """A lazily expanded ``HybridSystem`` of this robot (modes appear as transitions reach
        them). With ``x0`` the initial mode is built and checked at once."""
        initial = None
        if initial_mode is not None:
            self.active_contacts(initial_mode)
            if x0 is not None:
                initial = (initial_mode, x0)
        return HybridSystem(
            {},
            (),
            name=self.name,
            expand=self.expand,
            energy=self.energy if energy else None,
            initial=initial,
            joint=self.joint,
        )

    def joint(self, mode: str, names: tuple[str, ...], x: np.ndarray, rest: bool = False) -> JointCrossing | None:
        """The contacts struck by the transitions ``names`` (crossed in one landing step) at x,
        resolved under one impact law (``joint``; ``rest``: all plastic, their bounces having
        accumulated), or None to take them one after the other."""
        return resolve(self._model, self._data, self._modes, mode, names, x, rest)

    def attach_control(self, preview: Callable[[str, float, np.ndarray], Any] | None) -> None:
        """Tell the bridge the control each mode will get: ``preview(mode, t, x) -> u`` (without
        changing the controller's state). After an impact the bridge then chooses the mode whose
        contact forces are consistent under that control (a controller whose output depends on
        the mode, or on velocities an impact changes, needs this); without it they are taken
        under the control the impact guard was evaluated with."""
        self._data.preview = preview

    def counters(self) -> dict[str, int]:
        """Model-side evaluation counts since construction (or the last ``reset_counters``):
        aba, kkt (constrained solves), jacobians, kinematics (guard passes), spring_forces,
        damping_evals, actuation_evals, impacts, energy_evals, cache_hits."""
        from .twins import add_counts

        counts = dict(self._data.counts)
        for twin in self._twins:  # evaluations on the compiled path
            add_counts(counts, twin)
        return counts

    def reset_counters(self) -> None:
        """Set every counter to zero."""
        from .twins import add_counts

        for k in self._data.counts:
            self._data.counts[k] = 0
        for twin in self._twins:
            add_counts({}, twin, reset=True)
