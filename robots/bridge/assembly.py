"""``ContactBridge``: the facade that composes the bridge's modules into a ``legsim.HybridSystem``.

It owns a ``BridgeModel`` (fixed) and the ``ModeCatalog``; a mode is built once, on first use:
its parameter array (``params``, ``transitions``) and its ``legsim.Mode`` written as the model
functions of ``dynamics``, ``events`` and ``joint``, which the Python loop and the compiled
kernel both evaluate. What the outputs need besides the flow (constraint forces, energies,
positions of frames and feet) comes from the same compiled functions or from Pinocchio's
kinematics.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from legsim.errors import ModelError
from legsim.hybrid import HybridSystem, Mode, Transition
from legsim.model import ModeFunctions, as_input
from legsim.relaxed import Watch
from legsim.terrain import Terrain

from . import guards, native
from .arcs import CornerArcs, corner_arc_watch, round_drift_watch
from .contacts import Contact, frame_id
from .dynamics import bridge_field, bridge_forces, bridge_spring_forces
from .events import bridge_guards, bridge_reset
from .impacts import newton_impact
from .joint import bridge_joint
from .layout import P_EVENT, P_GUARD, P_JOINT, P_NEVENT, P_NGUARD, P_NJOINT
from .model import build_model
from .modes import ModeCatalog, ModeSpec, SubsetKey
from .params import start
from .placements import Placements
from .range_notes import LegsNote
from .transitions import outgoing

#: What a nan of the model functions means (``ModeFunctions.range_note``), by what the robot has:
#: spring legs (``events.leg_touchdown``, ``events.leg_liftoff``) and rigid contacts (``friction``).
LEGS_PAST_RANGE = (
    "a hip below the ground, or a foot below the ground and moving down after its liftoff (the robot fell)"
)
CONTACTS_PAST_RANGE = (
    "contacts with no consistent outcome (an event that no set of contact statuses resolves, or slipping "
    "contacts without unique forces: Painleve's paradox)"
)
ROUNDS_PAST_RANGE = (
    "a round contact struck into a notch of the terrain or across a pit narrower than itself, pressing on two "
    "points of it at once"
)


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
        Joint names driven by the input ``u`` (one entry of u per joint, N m or N): the modes'
        functions take ``inputs = len(actuated)``, and the guards on constraint forces
        (releases, plastic impacts, friction events) are evaluated under u.
    effort_limits:
        Optional bound on |u| per actuated joint name (N m or N, > 0): the model functions
        saturate each entry of u there (field, guards and resets alike); joints not named are
        not limited.
    name:
        Name of the system.
    terrain:
        Optional ``legsim.terrain.Terrain``: the ground under every point contact (their own
        ``ground`` then stays 0). A flat one is the contacts' ground height; on the others the
        guards read the height under each point and its constraint rows, impacts and friction
        lie along the terrain's local tangent and normal (spring legs need level ground).

    Raises
    ------
    ModelError
        naming the contact, frame or joint at fault, or when the native library is unavailable.
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
        effort_limits: Mapping[str, float] | None = None,
        terrain: Terrain | None = None,
    ) -> None:
        self._model = build_model(
            model,
            contacts,
            coordinate_names=coordinate_names,
            velocity_names=velocity_names,
            joint_damping=joint_damping,
            actuated=actuated,
            name=name,
            effort_limits=effort_limits,
            terrain=terrain,
        )
        self._data = self._model.pin_model.createData()  # kinematics for pictures and checks
        self._modes = ModeCatalog(self._model, mode_names)
        self._placements = Placements(self._model)
        self._past = guards.PastDepths(self._model, self._modes.active_contacts, self._placements)
        self._arcs = CornerArcs(self._model, self._modes.active_contacts, self._placements)
        self._built: dict[str, tuple[Mode, list[Transition]]] = {}

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
    def placements(self) -> Placements:
        """Where the robot's frames are at a run's stored states, one forward-kinematics pass a
        batch for every check that reads them (``PastDepths``, and points added by the robot's
        builder: its links' outlines)."""
        return self._placements

    @property
    def data(self) -> pin.Data:
        """A Pinocchio data of the model, for kinematics outside the model functions."""
        return self._data

    @property
    def handle(self) -> int:
        """The model's handle in the native library (the model functions' Pinocchio)."""
        return self._model.handle

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
    def actuated_dofs(self) -> np.ndarray:
        """Velocity index of each actuated joint, in the order of the input's entries."""
        return self._model.actuated_idx.copy()

    @property
    def effort_limits(self) -> np.ndarray:
        """The bound on |u_i| of each entry of the input (N m or N; inf: none)."""
        return self._model.effort_limits.copy()

    @property
    def actuated_names(self) -> tuple[str, ...]:
        """The actuated joints' coordinate names, in the order of the input's entries."""
        return tuple(self._model.coordinate_names[int(k)] for k in self._model.actuated_idx)

    @property
    def terrain(self) -> np.ndarray | None:
        """The encoding of the terrain under the contacts (``legsim.terrain``), or None on level
        ground (each contact's ``ground``)."""
        return None if self._model.terrain is None else self._model.terrain.copy()

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

    def mode(self, mode: str) -> Mode:
        """The legsim ``Mode`` of contact mode ``mode``, written as the bridge's model functions."""
        return self.expand(mode)[0]

    def expand(self, mode: str) -> tuple[Mode, list[Transition]]:
        """``HybridSystem`` expand callback: the mode and its outgoing transitions (built once)."""
        built = self._built.get(mode)
        if built is None:
            built = self._built[mode] = self._build(mode)
        return built

    def _build(self, mode: str) -> tuple[Mode, list[Transition]]:
        spec = self._modes.spec(mode)
        b = start(self._model, spec)
        out = outgoing(self._model, self._modes, spec, b)
        b.set(P_NGUARD, len(out.records))
        b.set(P_GUARD, b.append(v for rec in out.records for v in rec))
        b.set(P_NEVENT, len(out.events))
        b.set(P_EVENT, b.append(v for rec in out.events for v in rec))
        b.set(P_NJOINT, len(out.joint_records))
        b.set(P_JOINT, b.append(v for rec in out.joint_records for v in rec))
        functions = ModeFunctions(
            bridge_field,
            bridge_guards if out.transitions else None,
            bridge_reset,
            bridge_joint if out.joint_outcomes else None,
            params=b.array(),
            inputs=len(self._model.actuated_idx),
            joint_outcomes=tuple(out.joint_outcomes),
            nan_breaks=True,
            range_note=self._range_note(spec),
            # With friction an event's outcome is the mode whose forces are consistent under the
            # input applied after it, which the controller gives there.
            previewed=self._model.coulomb,
            # Contact forces and slip velocities jump where a sliding point passes a corner of
            # the terrain, or where the controller switches: the event happens at the jump. A
            # spring leg's touchdown guard jumps only where its foot never came out of the
            # ground, which must end the run (``events.leg_touchdown``).
            crosses_jumps=not self._model.legs,
        )
        return Mode(spec.dim, names=spec.names, units=spec.units, functions=functions), out.transitions

    def _range_note(self, spec: ModeSpec) -> str | LegsNote:
        """What a nan of the mode's functions means: the robot's ways past its range, and for a
        spring-legged robot where its legs stood (``range_notes.LegsNote``)."""
        ways = [LEGS_PAST_RANGE] if self._model.legs else []
        ways += [CONTACTS_PAST_RANGE] if self._model.rigid else []
        if self._arcs.rounds:
            ways.append(ROUNDS_PAST_RANGE)
        head = ", or ".join(ways)
        return LegsNote(self._model, self._data, spec, head) if self._model.legs else head

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
            dims=lambda mode: self._modes.spec(mode).dim,
            energy=self.energy if energy else None,
            initial=initial,
        )

    # -- what the outputs read --------------------------------------------------------------
    def field(self, mode: str) -> Callable[[float, np.ndarray, Any], np.ndarray]:
        """The vector field ``f(t, x, u) = (v, a, 0 for the footholds)`` of mode ``mode``."""
        return self.mode(mode).field

    def _params(self, mode: str) -> np.ndarray:
        functions = self.mode(mode).functions
        assert functions is not None
        return functions.params

    def constraint_forces(self, mode: str, x: np.ndarray, u: Any = None) -> dict[str, np.ndarray]:
        """Constraint forces of the active rigid contacts at state x under the input u (the
        field's solve): ``{name: lambda}`` with ``lambda = (f_x, f_z)`` (N) for a sticking or
        slipping point contact (slipping: f_x is the friction force ``-s mu f_z``), ``(f_z,)`` for
        a frictionless one and ``(tau,)`` (N m or N) for a joint stop; the last entry is the
        normal force, >= 0 when the contact pushes the robot into its domain. On a terrain that
        is not level, x and z are the terrain's tangent and normal under the point."""
        spec = self._modes.spec(mode)
        lam = np.empty(max(1, spec.rows))
        x = np.ascontiguousarray(x, dtype=np.float64)
        bridge_forces(0.0, x, as_input(u, len(self._model.actuated_idx)), self._params(mode), lam)
        out, i = {}, 0
        for r, slip in zip(spec.rigid, spec.slips, strict=True):
            rows = spec.rows_of(r, slip)
            out[r.contact.name] = lam[i : i + rows].copy()
            if slip:  # the friction force joins the normal force: (f_x, f_z)
                assert r.mu is not None
                out[r.contact.name] = np.array((-slip * r.mu * lam[i], lam[i]))
            i += rows
        return out

    def leg_forces(self, mode: str, x: np.ndarray) -> dict[str, float]:
        """Axial force (N, > 0 pushing the hip away from the foot) of each stance spring leg."""
        spec = self._modes.spec(mode)
        out = np.empty(len(spec.springs))
        x = np.ascontiguousarray(x, dtype=np.float64)
        bridge_spring_forces(0.0, x, np.zeros(len(self._model.actuated_idx)), self._params(mode), out)
        return {lg.leg.name: float(f) for lg, f in zip(spec.springs, out, strict=True)}

    def impact_velocity(self, rows: Sequence[tuple[str, float]], q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Post-impact velocity (nv,) of the generalised Newton impact of the contacts ``rows``
        (``(contact name, restitution)``): each contact's rows J_i get ``J_i v+ = -c_i J_i v``
        (``impacts.newton_impact``)."""
        for name, _ in rows:
            if name not in self._model.rigid:
                raise ModelError(f"{self.name}: impact_velocity: unknown rigid contact {name!r}")
        x = np.concatenate([np.asarray(q, dtype=float), np.asarray(v, dtype=float)])
        contacts = np.array([self._model.index(name) for name, _ in rows], dtype=np.int64)
        coeff = np.array([c for _, c in rows], dtype=float)
        v_plus, normal = np.empty(self.n), np.empty(len(rows))
        newton_impact(x, self._params(self._modes.name_of(())), contacts, coeff, len(rows), v_plus, normal)
        return v_plus

    def initial_check(self) -> Callable[[str, np.ndarray, float], str | None]:
        """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x,
        eps)`` names the first inactive joint stop or point contact whose position lies past it
        by more than eps (rad or m), else None."""
        return guards.initial_check(self._past)

    def contact_watches(self, eps: float, action: str = "warn") -> list[Watch]:
        """What every run of the robot is checked for: an inactive contact past the ground or its
        stop by more than eps + ``guards.THROUGH_DEPTH`` (``guards.passed_through_watch``; eps the
        run's, in guard units), reported by ``action`` (``guards.ground_watch``), and a round
        contact rolling round a corner of a profile or drifting off it by more than eps +
        ``guards.THROUGH_DEPTH`` (``arcs``)."""
        out = [guards.passed_through_watch(self._past, eps, action)] if self._past.rigid else []
        if self._arcs.rounds:
            out += [corner_arc_watch(self._arcs), round_drift_watch(self._arcs, eps + guards.THROUGH_DEPTH)]
        return out

    def model_info(self, **entries: Any) -> dict[str, Any]:
        """``Model.info`` of a robot built on this bridge: the entries the core and the tools read
        (``guard_units``, ``bridge``, ``initial_check``, ``bare_aba``, ``contact_names``,
        ``active_contacts``, ``watches``: ``contact_watches`` warning, and where it applies
        ``needs_error_control``: ``_step_needs``), then the builder's own ``entries``."""
        return {
            "guard_units": self.guard_units(),
            "bridge": self,
            "initial_check": self.initial_check(),
            "bare_aba": native.bare_aba(self.handle),
            # what a scene's [fall] contacts are checked against (legsim.scene.falls)
            "contact_names": tuple(c.name for c in self.contacts),
            "active_contacts": self.active_contacts,
            "watches": lambda control, eps: self.contact_watches(eps),
            **self._step_needs(),
            **entries,
        }

    def _step_needs(self) -> dict[str, str]:
        """``needs_error_control`` (``legsim.scene.integrator``) where round contacts roll round a
        profile's convex corners: their acceleration jumps at an arc's ends inside a contact mode,
        which fixed steps cross to first order (``arcs``)."""
        if not self._arcs.rounds:
            return {}
        names = [r.contact.name for r in self._arcs.rounds]
        return {
            "needs_error_control": (
                f"round contacts {names} roll round the terrain's convex corners, where their acceleration "
                f"jumps inside a contact mode and fixed steps cross the jump to first order (docs/robots.md, "
                f"'Round contacts on steps and profiles')"
            )
        }

    def guard_units(self) -> dict[str, str]:
        """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
        return guards.guard_units(self._model)

    def energy(self, mode: str, x: np.ndarray) -> float:
        """Total mechanical energy (J): kinetic + gravity (``model.gravity``) + stance leg springs."""
        spec = self._modes.spec(mode)
        x = np.asarray(x, dtype=float)
        pm, pd, n = self._model.pin_model, self._data, self.n
        q, v = x[:n], x[n : 2 * n]
        e = pin.computeKineticEnergy(pm, pd, q, v) + pin.computePotentialEnergy(pm, pd, q)
        pin.forwardKinematics(pm, pd, q)
        for i, lg in enumerate(spec.springs):
            hip = pin.updateFramePlacement(pm, pd, lg.hip_id).translation
            r = float(np.hypot(hip[0] - x[2 * n + i], hip[2] - lg.leg.ground))
            e += 0.5 * lg.leg.stiffness * (lg.leg.rest_length - r) ** 2
        return float(e)

    def frame_positions(self, q: np.ndarray, frames: Iterable[str]) -> dict[str, np.ndarray]:
        """World (x, z) positions (m) of the named frames at configuration q."""
        pm, pd = self._model.pin_model, self._data
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

    def counters(self) -> dict[str, int]:
        """Model-side evaluation counts since construction (or the last ``reset_counters``), of
        every path (the native library counts them): aba, kkt (constrained solves), jacobians,
        kinematics (frame passes of the run, not of its checks: ``placements``), impacts,
        spring_forces, damping_evals, actuation_evals, painleve_sticks. Robots built on one
        Pinocchio model object share them."""
        return native.counts(self._model.handle)

    def reset_counters(self) -> None:
        """Set every counter to zero."""
        native.counts(self._model.handle, reset=True)
