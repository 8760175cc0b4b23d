"""The contact-mode bridge: a planar Pinocchio model plus its contacts -> a ``legsim.HybridSystem``.

A *mode* is the set of active contacts. Three kinds of contact are supported:

``PointContact``
    the origin of a Pinocchio frame meets the ground ``z = ground``. Inactive: a touchdown
    guard; active: a rigid (bilateral while active) constraint pinning the point (``x`` and
    ``z``, or ``z`` only when ``tangential=False``) with a release guard on the normal force.
``JointStop``
    a one-dof joint meets a stop at ``position`` (``side="lower"``: domain ``q >= position``,
    ``"upper"``: ``q <= position``). Inactive: an impact guard; active: the joint is held at
    the stop, with a release guard on the stop's generalised force.
``SpringLeg``
    a massless linear spring leg hinged at a frame (the hip). In flight the leg keeps its rest
    length and the angle ``angle`` from the hip frame's ``-z`` axis towards its ``+x`` axis; its
    foot is an extra Pinocchio frame ``<name>_foot``. At touchdown the foot is pinned where it
    meets the ground and its horizontal position (the *foothold*) joins the state; the leg
    pushes on the hip with ``k (l - r)`` (minus ``b dr/dt`` with damping) along the leg; liftoff
    when the leg is back at its rest length, which drops the foothold.

Vector fields
    ``x = (q, v, footholds)`` with ``q`` and ``v`` of size ``nv`` (the bridge needs
    ``model.nq == model.nv``: prismatic and bounded revolute joints, the planar robots' case) and
    one foothold (m) per active spring leg, in the declared order. Modes without rigid
    constraints use the articulated-body algorithm ``pinocchio.aba`` with the applied
    generalised forces (spring legs through their hip Jacobians, joint damping, actuation);
    modes with rigid constraints solve the KKT contact dynamics
    ``M a + b = tau + J^T lambda, J a + dJ/dt v = 0`` through the Schur complement of ABA:
    ``a0 = aba(q, v, tau)``, ``lambda = (J M^-1 J^T)^-1 (-(J a0 + dJ/dt v))``,
    ``a = a0 + M^-1 J^T lambda`` (``M^-1`` by ``pinocchio.computeMinverse``). ``lambda`` is
    exposed by :meth:`ContactBridge.constraint_forces`. Nothing a mode does not need is computed:
    no contact Jacobian in a mode without rigid constraints, no spring force without an active
    leg, no damping term without damping. :meth:`ContactBridge.counters` counts each kind of
    model-side evaluation.

Guards (``>= 0`` inside; the strip width eps is in the guard's unit, see :meth:`guard_units`)
    * touchdown of a point contact: ``max(z - ground, dz/dt)`` (m): the gap, past only when it is
      closing; of a spring-leg foot: ``z - ground`` while descending, ``max(z - ground, dz/dt)``
      while rising (m): the height itself when it matters, and a foot that swung into the ground
      at liftoff stays in flight while it rises but is past by its depth if it turns down
      before coming out (the run then ends with ``halving_exhausted``);
    * impact on a joint stop: ``max(s (q_j - position), s dq_j/dt)`` (rad, or m for a prismatic
      joint), ``s = +1`` for a lower stop and ``-1`` for an upper one;
    * release of a point contact: the normal constraint force ``lambda_z`` (N); of a joint stop:
      the stop's generalised force (N m for a revolute joint, N for a prismatic one);
    * liftoff of a spring leg: ``max(l - r, -dr/dt)`` (m), past once the leg has extended back
      through its rest length.

    Guards that depend on constraint forces (releases, plastic impacts, Zeno continuation) are
    declared on ``(t, x, u)`` when the robot has actuated joints, so that the crossing search
    evaluates them with the control at each interpolated time.

Zeno continuation (``zeno_window``, off by default)
    a contact with c > 0 gets two impact transitions with complementary guards: ``bounce_<c>``
    as without continuation, and ``rest_<c>``, a plastic impact into the constrained mode, taken
    when the rebound would fly shorter than the window (``c v0 < a_n window / 2``) and the contact
    would then push; the release guard leaves it when the force changes sign (docs/stress.md).

Falls
    the models have no body-ground contact: a hip below the ground, or a liftoff that would swing
    a foot into the ground while it moves down, raises ``ModelBreakdown`` (status
    ``model_breakdown``, the execution kept).

Resets
    * impact of a rigid contact with restitution c (generalised Newton impact): with ``J`` the
      Jacobian rows of the contacts that stay active after the impact plus the striking one,
      ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)`` where ``w = -c J v`` on the striking
      contact's rows and 0 on the others; for a joint stop alone this is paper 003 eq. (30).
      ``c = 0`` enters the mode with the contact active; ``c > 0`` bounces back into the same
      mode (possibly Zeno). A plastic impact after which the contact would pull (normal force
      lambda+ < 0 at the post-impact state) separates at once: it is a second transition
      ``graze_<name>`` into the mode without the contact, with guard ``max(gap guard, lambda+)``
      against ``max(gap guard, -lambda+)`` for the sticking one. A point contact may name
      contacts it ``releases`` when it strikes (a walker's stance foot at heel strike): they are
      dropped before the impact is solved; and it may be ``armed`` only in part of the
      configuration space (guard ``max(gap guard, -armed(q, v))``);
    * spring-leg touchdown appends the foothold (the foot's x at the guard point);
    * liftoff and release keep q and v and drop what leaves the state.

Modes are built lazily (``HybridSystem(expand=...)``): only those a transition reaches are
ever constructed, so a model with many contacts never enumerates the 2^n subsets.

The bridge owns one ``pinocchio.Data``: a system built from it is not thread-safe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Literal, Mapping, Sequence

import numpy as np
import pinocchio as pin

from legsim.errors import ModelBreakdown, ModelError
from legsim.hybrid import HybridSystem, Mode, Transition

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED



# ---------------------------------------------------------------------------------------------
# contact descriptions
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PointContact:
    """A point of the robot (the origin of Pinocchio frame ``frame``) against the ground.

    Attributes
    ----------
    name: contact name (used in mode and transition names).
    frame: Pinocchio frame whose origin touches the ground.
    restitution: Newton restitution coefficient c in [0, 1]; 0 sticks (enters the mode with
        the contact active), > 0 bounces.
    ground: ground height (m).
    tangential: True pins the point (no slip, x and z constrained); False constrains z only
        (frictionless sliding).
    releases: names of contacts that become inactive when this one strikes.
    armed: optional ``armed(q, v) -> float``: the touchdown only counts where it is > 0 (for a
        compass gait's swing foot, how far it is ahead of the stance foot, m, so that the scuff
        at mid-swing is not a heel strike); the touchdown guard becomes
        ``max(height, vertical velocity, -armed)``. The point must be above the ground when it
        becomes armed, or the guard jumps past its strip.
    """

    name: str
    frame: str
    restitution: float = 0.0
    ground: float = 0.0
    tangential: bool = True
    releases: tuple[str, ...] = ()
    armed: Callable[[np.ndarray, np.ndarray], float] | None = None


@dataclass(frozen=True)
class JointStop:
    """A mechanical stop on a one-dof joint.

    Attributes
    ----------
    name: contact name.
    joint: Pinocchio joint name (one dof: revolute RX/RY/RZ or prismatic PX/PY/PZ).
    position: stop position (rad or m).
    side: ``"lower"`` (the domain is ``q >= position``) or ``"upper"`` (``q <= position``).
    restitution: Newton restitution coefficient c in [0, 1].
    """

    name: str
    joint: str
    position: float = 0.0
    side: Literal["lower", "upper"] = "lower"
    restitution: float = 0.0


@dataclass(frozen=True)
class SpringLeg:
    """A massless linear spring leg hinged at frame ``frame`` (the hip).

    Attributes
    ----------
    name: contact name.
    frame: hip frame.
    stiffness: k (N/m), > 0.
    rest_length: l (m), > 0.
    angle: leg angle in flight (rad) from the hip frame's -z axis towards its +x axis.
    damping: viscous damping along the leg in stance (N s/m), >= 0; 0 computes no damping term.
    ground: ground height (m).
    """

    name: str
    frame: str
    stiffness: float
    rest_length: float
    angle: float = 0.0
    damping: float = 0.0
    ground: float = 0.0


Contact = PointContact | JointStop | SpringLeg


@dataclass
class _ModeSpec:
    """Everything about one mode the fast paths need, resolved once."""

    name: str
    active: tuple[str, ...]
    rigid: tuple[Any, ...]  # active PointContact/JointStop records (_Rigid)
    springs: tuple[Any, ...]  # active spring legs (_Leg), declared order
    flight_legs: tuple[Any, ...]  # inactive spring legs
    dim: int
    names: tuple[str, ...]
    n_rows: int = 0
    need_fk: bool = False  # some guard needs frame positions and velocities
    stop_dofs: tuple[np.ndarray, np.ndarray] | None = None  # (dofs, signs) when only joint stops are active
    # one-entry caches keyed by the state's bytes
    dyn_key: bytes = b""
    dyn_val: tuple[np.ndarray, np.ndarray] | None = None
    kin_key: bytes = b""
    kin_val: dict[str, float] = field(default_factory=dict)
    post: dict[str, tuple[bytes, float]] = field(default_factory=dict)  # plastic-impact force previews


@dataclass(frozen=True)
class _Rigid:
    contact: PointContact | JointStop
    kind: str  # "point" or "stop"
    frame_id: int = -1
    dof: int = -1
    sign: float = 1.0
    rows: int = 1  # Jacobian rows; the normal row is the last one


@dataclass(frozen=True)
class _Leg:
    leg: SpringLeg
    hip_id: int
    foot_id: int


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
        the guards that depend on constraint forces (releases, plastic impacts, Zeno
        continuation) are declared ``guard_args="t,x,u"`` so that the integrator evaluates them
        with the control at the interpolated crossing time.
    zeno_window:
        Zeno continuation (off with None, the default): for every contact with restitution
        c > 0, an impact whose next flight would be shorter than ``zeno_window`` seconds (its
        post-impact normal speed ``c |v_n|`` below ``a_n zeno_window / 2``, a_n the normal
        acceleration with which the contact presses closed) enters the contact's constrained
        mode through a plastic impact instead of bouncing, provided the contact then pushes
        (normal force > 0); the usual release guard on that force leaves it. Set it to h + eps of
        the run: the least time one relaxed transition takes (a step plus a strip), so only
        flights the integrator could not resolve anyway are skipped.
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
        mode_names: Mapping[Iterable[str], str] | None = None,
        joint_damping: Mapping[str, float] | None = None,
        actuated: Sequence[str] = (),
        zeno_window: float | None = None,
        name: str = "robot",
    ) -> None:
        if not isinstance(model, pin.Model):
            raise ModelError(f"{name}: model must be a pinocchio.Model, got {type(model).__name__}")
        if model.nq != model.nv:
            raise ModelError(
                f"{name}: the bridge needs model.nq == model.nv (prismatic and bounded revolute joints), "
                f"got nq={model.nq}, nv={model.nv}")
        if model.nv < 1:
            raise ModelError(f"{name}: the model has no degree of freedom")
        self.name = name
        self.model = pin.Model(model)  # private copy: foot frames are added to it
        self.n = int(model.nv)
        self._contacts: dict[str, Contact] = {}
        self._order: list[str] = []
        for c in contacts:
            if not isinstance(c, (PointContact, JointStop, SpringLeg)):
                raise ModelError(f"{name}: contacts must be PointContact, JointStop or SpringLeg, got {type(c).__name__}")
            if not isinstance(c.name, str) or not c.name or "+" in c.name:
                raise ModelError(f"{name}: contact names must be non-empty strings without '+', got {c.name!r}")
            if c.name in self._contacts:
                raise ModelError(f"{name}: duplicate contact name '{c.name}'")
            self._contacts[c.name] = c
            self._order.append(c.name)
        self._rigid: dict[str, _Rigid] = {}
        self._legs: dict[str, _Leg] = {}
        for cname in self._order:
            self._resolve(self._contacts[cname])
        self.data = self.model.createData()

        self.coordinate_names = self._names(coordinate_names, "coordinate_names", self._joint_dof_names())
        default_vel = tuple(f"{c}d" for c in self.coordinate_names)
        self.velocity_names = self._names(velocity_names, "velocity_names", default_vel)
        if set(self.coordinate_names) & set(self.velocity_names):
            raise ModelError(f"{name}: coordinate and velocity names overlap: "
                             f"{sorted(set(self.coordinate_names) & set(self.velocity_names))}")

        self._damping_idx = np.zeros(0, dtype=int)
        self._damping_b = np.zeros(0)
        if joint_damping:
            idx, bs = [], []
            for jname, b in joint_damping.items():
                b = _finite(b, f"{name}: joint_damping['{jname}']", low=0.0)
                if b > 0.0:
                    jid = self._joint_id(jname, "joint_damping")
                    j = self.model.joints[jid]
                    idx.extend(range(j.idx_v, j.idx_v + j.nv))
                    bs.extend([b] * j.nv)
            self._damping_idx = np.array(idx, dtype=int)
            self._damping_b = np.array(bs)
        act = []
        for jname in actuated:
            jid = self._joint_id(jname, "actuated")
            j = self.model.joints[jid]
            if j.nv != 1:
                raise ModelError(f"{name}: actuated joint '{jname}' must have one dof, has {j.nv}")
            act.append(j.idx_v)
        self._act_idx = np.array(act, dtype=int)
        # Constraint forces depend on the control only through actuated joints.
        self._timed = bool(act)
        self.zeno_window = None if zeno_window is None else _finite(
            zeno_window, f"{name}: zeno_window (s)", low=0.0, low_open=True)

        self._mode_names: dict[frozenset[str], str] = {}
        self._mode_sets: dict[str, frozenset[str]] = {}
        for key, mname in (mode_names or {}).items():
            subset = frozenset([key] if isinstance(key, str) else key)
            unknown = sorted(subset - set(self._contacts))
            if unknown:
                raise ModelError(f"{name}: mode_names names unknown contact(s) {unknown}; contacts: {self._order}")
            if not isinstance(mname, str) or not mname or mname in self._mode_sets:
                raise ModelError(f"{name}: mode name {mname!r} is empty, not a string or used twice")
            self._mode_names[subset] = mname
            self._mode_sets[mname] = subset
        self._specs: dict[str, _ModeSpec] = {}
        self._counts = {"aba": 0, "kkt": 0, "jacobians": 0, "kinematics": 0, "spring_forces": 0,
                        "damping_evals": 0, "actuation_evals": 0, "impacts": 0, "energy_evals": 0, "cache_hits": 0}

    # -- construction helpers -------------------------------------------------------------
    def _joint_dof_names(self) -> tuple[str, ...]:
        names = []
        for jid in range(1, self.model.njoints):
            j = self.model.joints[jid]
            base = self.model.names[jid]
            names.extend([base] if j.nv == 1 else [f"{base}{i}" for i in range(j.nv)])
        return tuple(names)

    def _names(self, given, label, default) -> tuple[str, ...]:
        names = tuple(default if given is None else (str(s) for s in given))
        if len(names) != self.n or len(set(names)) != len(names):
            raise ModelError(f"{self.name}: {label} must be {self.n} unique names, got {names}")
        return names

    def _joint_id(self, jname: str, where: str) -> int:
        if not isinstance(jname, str) or not self.model.existJointName(jname):
            raise ModelError(f"{self.name}: {where}: unknown joint {jname!r}; joints: {list(self.model.names)[1:]}")
        return int(self.model.getJointId(jname))

    def _frame_id(self, fname: str, where: str) -> int:
        if not isinstance(fname, str) or not self.model.existFrame(fname):
            raise ModelError(f"{self.name}: {where}: unknown frame {fname!r}; frames: "
                             f"{[f.name for f in self.model.frames][1:]}")
        return int(self.model.getFrameId(fname))

    def _resolve(self, c: Contact) -> None:
        where = f"contact '{c.name}'"
        if isinstance(c, SpringLeg):
            _finite(c.stiffness, f"{self.name}: {where}: stiffness", low=0.0, low_open=True)
            _finite(c.rest_length, f"{self.name}: {where}: rest_length", low=0.0, low_open=True)
            _finite(c.angle, f"{self.name}: {where}: angle")
            _finite(c.damping, f"{self.name}: {where}: damping", low=0.0)
            _finite(c.ground, f"{self.name}: {where}: ground")
            hip = self._frame_id(c.frame, where)
            frame = self.model.frames[hip]
            # The flight foot is rigidly attached to the hip's joint: a frame gives its position
            # and velocity from the same kinematics pass as everything else.
            offset = c.rest_length * np.array([math.sin(c.angle), 0.0, -math.cos(c.angle)])
            placement = frame.placement * pin.SE3(np.eye(3), offset)
            foot_name = f"{c.name}_foot"
            if self.model.existFrame(foot_name):
                raise ModelError(f"{self.name}: {where}: the model already has a frame '{foot_name}'")
            foot = self.model.addFrame(pin.Frame(foot_name, frame.parentJoint, placement, pin.FrameType.OP_FRAME),
                                       False)
            self._legs[c.name] = _Leg(c, hip, int(foot))
            return
        _finite(c.restitution, f"{self.name}: {where}: restitution", low=0.0, high=1.0)
        if isinstance(c, PointContact):
            _finite(c.ground, f"{self.name}: {where}: ground")
            fid = self._frame_id(c.frame, where)
            if isinstance(c.releases, str) or not all(isinstance(o, str) for o in c.releases):
                raise ModelError(f"{self.name}: {where}: releases must be a tuple of contact names, "
                                 f"got {c.releases!r}")
            if c.armed is not None and not callable(c.armed):
                raise ModelError(f"{self.name}: {where}: armed must be callable armed(q, v) -> float or None")
            for other in c.releases:
                if other not in self._contacts or other == c.name:
                    raise ModelError(f"{self.name}: {where}: releases unknown contact {other!r} "
                                     f"(contacts: {self._order})")
            self._rigid[c.name] = _Rigid(c, "point", frame_id=fid, rows=2 if c.tangential else 1)
        elif isinstance(c, JointStop):
            _finite(c.position, f"{self.name}: {where}: position")
            if c.side not in ("lower", "upper"):
                raise ModelError(f"{self.name}: {where}: side must be 'lower' or 'upper', got {c.side!r}")
            jid = self._joint_id(c.joint, where)
            j = self.model.joints[jid]
            if j.nv != 1:
                raise ModelError(f"{self.name}: {where}: joint '{c.joint}' has {j.nv} dofs; a stop needs one")
            self._rigid[c.name] = _Rigid(c, "stop", dof=int(j.idx_v), sign=1.0 if c.side == "lower" else -1.0)

    # -- modes ----------------------------------------------------------------------------
    @property
    def contacts(self) -> tuple[Contact, ...]:
        """The contacts, in declared order."""
        return tuple(self._contacts[c] for c in self._order)

    def mode_name(self, active: Iterable[str]) -> str:
        """Name of the mode whose active contacts are ``active``."""
        subset = frozenset(active)
        unknown = sorted(subset - set(self._contacts))
        if unknown:
            raise ModelError(f"{self.name}: unknown contact(s) {unknown}; contacts: {self._order}")
        if subset in self._mode_names:
            return self._mode_names[subset]
        if not subset:
            return "free"
        return "+".join(c for c in self._order if c in subset)

    def active_contacts(self, mode: str) -> tuple[str, ...]:
        """The active contacts of mode ``mode``, in declared order."""
        if mode in self._mode_sets:
            subset = self._mode_sets[mode]
        elif mode == "free":
            subset = frozenset()
        else:
            parts = mode.split("+")
            if any(p not in self._contacts for p in parts) or len(set(parts)) != len(parts):
                raise ModelError(f"{self.name}: '{mode}' is not a mode: name a set of contacts joined by '+' "
                                 f"(contacts: {self._order}) or one of {sorted(self._mode_sets)}")
            subset = frozenset(parts)
        if self.mode_name(subset) != mode:
            raise ModelError(f"{self.name}: mode '{mode}' is called '{self.mode_name(subset)}'")
        return tuple(c for c in self._order if c in subset)

    def _spec(self, mode: str) -> _ModeSpec:
        spec = self._specs.get(mode)
        if spec is None:
            active = self.active_contacts(mode)
            rigid = tuple(self._rigid[c] for c in active if c in self._rigid)
            springs = tuple(self._legs[c] for c in active if c in self._legs)
            flight = tuple(self._legs[c] for c in self._order if c in self._legs and c not in active)
            names = self.coordinate_names + self.velocity_names + tuple(f"{lg.leg.name}_foot_x" for lg in springs)
            need_fk = bool(springs or flight or any(
                r.kind == "point" and r.contact.name not in active for r in self._rigid.values()))
            stop_dofs = None
            if rigid and all(r.kind == "stop" for r in rigid):
                stop_dofs = (np.array([r.dof for r in rigid]), np.array([r.sign for r in rigid]))
            spec = _ModeSpec(mode, active, rigid, springs, flight, 2 * self.n + len(springs), names,
                             n_rows=sum(r.rows for r in rigid), need_fk=need_fk, stop_dofs=stop_dofs)
            self._specs[mode] = spec
        return spec

    def state_names(self, mode: str) -> tuple[str, ...]:
        """Coordinate names of mode ``mode``: q, v, then one foothold (m) per active spring leg."""
        return self._spec(mode).names

    # -- dynamics -------------------------------------------------------------------------
    def _applied(self, spec: _ModeSpec, q: np.ndarray, v: np.ndarray, x: np.ndarray, u: Any) -> np.ndarray:
        """Generalised applied force tau (nv,): spring legs, joint damping, actuation."""
        tau = np.zeros(self.n)
        model, data, c = self.model, self.data, self._counts
        for i, lg in enumerate(spec.springs):
            J = pin.computeFrameJacobian(model, data, q, lg.hip_id, _LWA)[:3:2]  # rows x and z
            c["jacobians"] += 1
            c["spring_forces"] += 1
            p = data.oMf[lg.hip_id].translation
            d = np.array((p[0] - x[2 * self.n + i], p[2] - lg.leg.ground))
            r = math.hypot(d[0], d[1])
            d /= r
            f = lg.leg.stiffness * (lg.leg.rest_length - r)
            if lg.leg.damping > 0.0:
                c["damping_evals"] += 1
                f -= lg.leg.damping * (d @ (J @ v))
            tau += (f * d) @ J
        if self._damping_idx.size:
            c["damping_evals"] += 1
            tau[self._damping_idx] -= self._damping_b * v[self._damping_idx]
        if u is not None:
            tau[self._act_idx] += self._control(u)
            c["actuation_evals"] += 1
        return tau

    def _control(self, u: Any) -> np.ndarray:
        arr = np.asarray(u, dtype=float).reshape(-1)
        if arr.shape != self._act_idx.shape:
            raise ModelError(f"{self.name}: control u has {arr.size} entries, the robot has "
                             f"{self._act_idx.size} actuated joints")
        return arr

    def _constraint_rows(self, spec_rigid: Sequence[_Rigid], q: np.ndarray, v: np.ndarray,
                         drift: bool) -> tuple[np.ndarray, np.ndarray]:
        """Stacked constraint Jacobian (rows, nv) and drift dJ/dt v (rows,); the normal row of
        each contact is its last row and points into the domain (gap increasing)."""
        rows = sum(r.rows for r in spec_rigid)
        J = np.zeros((rows, self.n))
        gamma = np.zeros(rows)
        model, data = self.model, self.data
        i = 0
        need_acc = False
        for r in spec_rigid:
            if r.kind == "stop":
                J[i, r.dof] = r.sign
            else:
                Jf = pin.computeFrameJacobian(model, data, q, r.frame_id, _LWA)
                self._counts["jacobians"] += 1
                if r.rows == 2:
                    J[i] = Jf[0]
                    J[i + 1] = Jf[2]
                else:
                    J[i] = Jf[2]
                need_acc = True
            i += r.rows
        if drift and need_acc:
            pin.forwardKinematics(model, data, q, v, np.zeros(self.n))
            i = 0
            for r in spec_rigid:
                if r.kind == "point":
                    acc = pin.getFrameClassicalAcceleration(model, data, r.frame_id, _LWA).linear
                    if r.rows == 2:
                        gamma[i], gamma[i + 1] = acc[0], acc[2]
                    else:
                        gamma[i] = acc[2]
                i += r.rows
        return J, gamma

    def _dynamics(self, spec: _ModeSpec, x: np.ndarray, u: Any) -> tuple[np.ndarray, np.ndarray]:
        """(acceleration (nv,), constraint forces (rows,)) at x, cached for the last state."""
        # Keyed by the control's value, not its identity: a controller returns a new array at each
        # call, and the guard at a state and the field at the same state must share one solve.
        key = x.tobytes() + _control_key(u)
        if spec.dyn_val is not None and key == spec.dyn_key:
            self._counts["cache_hits"] += 1
            return spec.dyn_val
        n = self.n
        q = x[:n]
        v = x[n:2 * n]
        tau = self._applied(spec, q, v, x, u)
        a = pin.aba(self.model, self.data, q, v, tau).copy()
        self._counts["aba"] += 1
        if spec.rigid:
            self._counts["kkt"] += 1
            Minv = pin.computeMinverse(self.model, self.data, q)
            if spec.stop_dofs is not None and len(spec.stop_dofs[0]) == 1:
                # one joint stop: J = s e_k, the Delassus "matrix" is (M^-1)_kk
                k, s = int(spec.stop_dofs[0][0]), float(spec.stop_dofs[1][0])
                col = Minv[:, k]
                lam = np.array((-s * a[k] / col[k],))
                a -= col * (a[k] / col[k])
                spec.dyn_key, spec.dyn_val = key, (a, lam)
                return a, lam
            if spec.stop_dofs is not None:
                # joint stops only: J selects (signed) dofs, no Jacobian, no drift
                idx, sign = spec.stop_dofs
                MJt = Minv[:, idx] * sign
                A = MJt[idx] * sign[:, None]
                rhs = -a[idx] * sign
            else:
                J, gamma = self._constraint_rows(spec.rigid, q, v, drift=True)
                MJt = Minv @ J.T
                A = J @ MJt
                rhs = -(J @ a + gamma)
            lam = _solve_small(A, rhs)
            a += MJt @ lam
        else:
            lam = np.zeros(0)
        spec.dyn_key, spec.dyn_val = key, (a, lam)
        return a, lam

    def field(self, mode: str) -> Callable[[float, np.ndarray, Any], np.ndarray]:
        """The vector field ``f(t, x, u)`` of mode ``mode``."""
        spec = self._spec(mode)
        n, dim = self.n, spec.dim

        def f(t: float, x: np.ndarray, u: Any = None) -> np.ndarray:
            a, _ = self._dynamics(spec, x, u)
            out = np.zeros(dim)
            out[:n] = x[n:2 * n]
            out[n:2 * n] = a
            return out

        return f

    def constraint_forces(self, mode: str, x: np.ndarray, u: Any = None) -> dict[str, np.ndarray]:
        """Constraint forces of the active rigid contacts at state x: ``{name: lambda}`` with
        ``lambda = (f_x, f_z)`` (N) for a sticking point contact, ``(f_z,)`` for a frictionless
        one and ``(tau,)`` (N m or N) for a joint stop; the last entry is the normal force, >= 0
        when the contact pushes the robot into its domain."""
        spec = self._spec(mode)
        x = np.asarray(x, dtype=float)
        _, lam = self._dynamics(spec, x, u)
        out, i = {}, 0
        for r in spec.rigid:
            out[r.contact.name] = lam[i:i + r.rows].copy()
            i += r.rows
        return out

    def leg_forces(self, mode: str, x: np.ndarray) -> dict[str, float]:
        """Axial force (N, > 0 pushing the hip away from the foot) of each active spring leg."""
        spec = self._spec(mode)
        out = {}
        for i, lg in enumerate(spec.springs):
            r, rdot = self._leg_length(lg, x, i)
            f = lg.leg.stiffness * (lg.leg.rest_length - r)
            if lg.leg.damping > 0.0:
                f -= lg.leg.damping * rdot
            out[lg.leg.name] = f
        return out

    def _leg_length(self, lg: _Leg, x: np.ndarray, i: int) -> tuple[float, float]:
        n = self.n
        pin.forwardKinematics(self.model, self.data, x[:n], x[n:2 * n])
        p = pin.updateFramePlacement(self.model, self.data, lg.hip_id).translation
        vel = pin.getFrameVelocity(self.model, self.data, lg.hip_id, _LWA).linear
        dx = p[0] - x[2 * n + i]
        dz = p[2] - lg.leg.ground
        r = math.hypot(dx, dz)
        return r, (dx * vel[0] + dz * vel[2]) / r

    # -- guards ---------------------------------------------------------------------------
    def _kinematic_guards(self, spec: _ModeSpec, x: np.ndarray) -> dict[str, float]:
        """Values of every position-level guard of the mode at x, from one kinematics pass."""
        key = x.tobytes()
        if key == spec.kin_key:
            return spec.kin_val
        n = self.n
        model, data = self.model, self.data
        out: dict[str, float] = {}
        q, v = x[:n], x[n:2 * n]
        active = spec.active
        if spec.need_fk:
            pin.forwardKinematics(model, data, q, v)
            self._counts["kinematics"] += 1
        for r in self._rigid.values():
            name = r.contact.name
            if name in active:
                continue
            if r.kind == "stop":
                out[name] = max(r.sign * (q[r.dof] - r.contact.position), r.sign * v[r.dof])
            else:
                p = pin.updateFramePlacement(model, data, r.frame_id).translation
                vz = pin.getFrameVelocity(model, data, r.frame_id, _LWA).linear[2]
                g = max(p[2] - r.contact.ground, vz)
                if r.contact.armed is not None:
                    g = max(g, -float(r.contact.armed(q, v)))
                out[name] = g
        for lg in spec.flight_legs:
            p = pin.updateFramePlacement(model, data, lg.foot_id).translation
            vz = pin.getFrameVelocity(model, data, lg.foot_id, _LWA).linear[2]
            z = p[2] - lg.leg.ground
            # "at the ground moving down". A foot below the ground while rising is in flight: near
            # a periodic gait the leg swung forward at liftoff scuffs the ground. One that turns
            # down while still below it is past by its depth, not by its velocity: the guard
            # jumps there, no step can land in the strip, and the run ends (halving_exhausted)
            # instead of pinning a foot that never came out of the ground.
            out[lg.leg.name] = z if vz <= 0.0 else max(z, vz)
            hip_z = pin.updateFramePlacement(model, data, lg.hip_id).translation[2] - lg.leg.ground
            if hip_z < 0.0:
                raise ModelBreakdown(f"{self.name}: the hip of leg '{lg.leg.name}' is {-hip_z:.3g} m below the "
                                     f"ground: the runner fell (the model has no body-ground contact)")
        for i, lg in enumerate(spec.springs):
            p = pin.updateFramePlacement(model, data, lg.hip_id).translation
            vel = pin.getFrameVelocity(model, data, lg.hip_id, _LWA).linear
            dx = p[0] - x[2 * n + i]
            dz = p[2] - lg.leg.ground
            if dz < 0.0:
                raise ModelBreakdown(f"{self.name}: the hip of leg '{lg.leg.name}' is {-dz:.3g} m below the "
                                     f"ground: the runner fell (the model has no body-ground contact)")
            r = math.hypot(dx, dz)
            rdot = (dx * vel[0] + dz * vel[2]) / r
            g = max(lg.leg.rest_length - r, -rdot)
            if g < 0.0:
                # Past liftoff: the leg swings to its flight angle. A foot that would then be below
                # the ground *and* moving down swung into it: the runner fell. (Below the ground but
                # rising is a scuff, which every symmetric running gait grazes, within rounding.)
                foot = pin.updateFramePlacement(model, data, lg.foot_id).translation[2] - lg.leg.ground
                foot_vz = pin.getFrameVelocity(model, data, lg.foot_id, _LWA).linear[2]
                if foot < 0.0 and foot_vz < 0.0:
                    raise ModelBreakdown(
                        f"{self.name}: at liftoff of leg '{lg.leg.name}' its foot, swung to the flight angle, "
                        f"would be {-foot:.3g} m below the ground moving down ({foot_vz:.3g} m/s): "
                        f"the runner fell")
            out[lg.leg.name] = g
        spec.kin_key, spec.kin_val = key, out
        return out

    def _release_guard(self, spec: _ModeSpec, row: int) -> tuple[Callable[..., float], str]:
        """The normal force ``lambda[row]`` (N or N m) as a guard, and its ``guard_args``: on
        (t, x, u) when the robot is actuated, since the force then depends on the control."""
        if self._timed:
            def g_txu(t: float, x: np.ndarray, u: Any) -> float:
                _, lam = self._dynamics(spec, x, u)
                return float(lam[row])
            return g_txu, "t,x,u"

        def g(x: np.ndarray) -> float:
            _, lam = self._dynamics(spec, x, None)
            return float(lam[row])
        return g, "x"

    def _kin_guard(self, spec: _ModeSpec, cname: str) -> Callable[[np.ndarray], float]:
        def g(x: np.ndarray) -> float:
            return self._kinematic_guards(spec, x)[cname]
        return g

    def initial_check(self) -> Callable[[str, np.ndarray, float], str | None]:
        """The scene's initial-state check (``Model.info["initial_check"]``): ``check(mode, x,
        eps)`` names the first inactive joint stop or point contact whose position lies past it
        by more than eps (rad or m), else None. The guards are "and" conditions (past the stop
        AND moving into it), so they count a state deep past a stop but moving away as inside;
        no execution reaches such a state, and a run started there would not be the model's."""
        def check(mode: str, x: np.ndarray, eps: float) -> str | None:
            active = self._spec(mode).active
            n = self.n
            q = np.asarray(x, dtype=float)[:n]
            for r in self._rigid.values():
                c = r.contact
                if c.name in active:
                    continue
                if r.kind == "stop":
                    depth = -r.sign * (q[r.dof] - c.position)
                    if depth > eps:
                        name = self.coordinate_names[r.dof]
                        bound = ">=" if c.side == "lower" else "<="
                        return (f"{name} = {q[r.dof]:g} lies past the {c.side} stop '{c.name}' ({name} {bound} "
                                f"{c.position:g}) by {depth:.3g} > eps = {eps:g} in mode '{mode}' where the "
                                f"stop is inactive")
                else:
                    pin.forwardKinematics(self.model, self.data, q)
                    z = pin.updateFramePlacement(self.model, self.data, r.frame_id).translation[2]
                    depth = c.ground - z
                    if depth > eps:
                        return (f"contact point '{c.name}' (frame '{c.frame}') at height {z:g} m lies below the "
                                f"ground {c.ground:g} m by {depth:.3g} > eps = {eps:g} in mode '{mode}' where "
                                f"the contact is inactive")
            return None

        return check

    def guard_units(self) -> dict[str, str]:
        """Unit of each kind of guard by transition name prefix (eps is measured in these)."""
        units = {}
        for cname in self._order:
            c = self._contacts[cname]
            if isinstance(c, SpringLeg):
                units[f"touchdown_{cname}"] = "m (foot height, while descending)"
                units[f"liftoff_{cname}"] = "m (rest length minus leg length, while extending)"
            elif isinstance(c, PointContact):
                kind = "touchdown" if c.restitution == 0.0 else "bounce"
                units[f"{kind}_{cname}"] = "m (height of the point, while descending)"
                if c.restitution == 0.0:
                    units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                    units[f"liftoff_{cname}"] = "N (normal contact force)"
            else:
                rot = self.model.joints[self._joint_id(c.joint, "stop")].shortname().startswith(("JointModelR",))
                kind = "impact" if c.restitution == 0.0 else "bounce"
                units[f"{kind}_{cname}"] = f"{'rad' if rot else 'm'} (distance to the stop, while approaching)"
                if c.restitution == 0.0:
                    units[f"graze_{cname}"] = units[f"{kind}_{cname}"]
                    units[f"release_{cname}"] = f"{'N m' if rot else 'N'} (stop force)"
        return units

    # -- resets ---------------------------------------------------------------------------
    def _flight_foot(self, lg: _Leg, q: np.ndarray) -> float:
        """x (m) of the flight foot at q: where a touching-down foot is pinned."""
        pin.forwardKinematics(self.model, self.data, q)
        return float(pin.updateFramePlacement(self.model, self.data, lg.foot_id).translation[0])

    def _map_state(self, src: _ModeSpec, dst: _ModeSpec, x: np.ndarray, v_new: np.ndarray | None) -> np.ndarray:
        n = self.n
        out = np.empty(dst.dim)
        out[:n] = x[:n]
        out[n:2 * n] = x[n:2 * n] if v_new is None else v_new
        src_index = {lg.leg.name: i for i, lg in enumerate(src.springs)}
        for i, lg in enumerate(dst.springs):
            j = src_index.get(lg.leg.name)
            out[2 * n + i] = self._flight_foot(lg, x[:n]) if j is None else x[2 * n + j]
        return out

    def impact_velocity(self, rows: Sequence[tuple[str, float]], q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Post-impact velocity (nv,) of the generalised Newton impact.

        ``rows``: ``(contact name, restitution)`` of the contacts constrained at the impact;
        each contact's Jacobian rows J_i get ``J_i v+ = -c_i J_i v``.
        ``v+ = v + M^-1 J^T (J M^-1 J^T)^-1 (w - J v)``, ``w = -c J v`` row-wise.
        """
        self._counts["impacts"] += 1
        rigid = [self._rigid[name] for name, _ in rows]
        J, _ = self._constraint_rows(rigid, q, v, drift=False)
        coeff = np.concatenate([np.full(r.rows, c) for r, (_, c) in zip(rigid, rows)])
        Minv = pin.computeMinverse(self.model, self.data, q)
        MJt = Minv @ J.T
        Jv = J @ v
        return v + MJt @ _solve_small(J @ MJt, -(1.0 + coeff) * Jv)

    def _transitions(self, spec: _ModeSpec) -> list[Transition]:
        out: list[Transition] = []
        active = set(spec.active)
        for cname in self._order:
            c = self._contacts[cname]
            if isinstance(c, SpringLeg):
                if cname in active:
                    dst = self._spec(self.mode_name(active - {cname}))
                    kind = "liftoff"
                else:
                    dst = self._spec(self.mode_name(active | {cname}))
                    kind = "touchdown"
                out.append(Transition(spec.name, dst.name, self._kin_guard(spec, cname),
                                      self._plain_reset(spec, dst), name=f"{kind}_{cname}"))
                continue
            if cname in active:
                row = -1
                i = 0
                for r in spec.rigid:
                    i += r.rows
                    if r.contact.name == cname:
                        row = i - 1  # the normal row is the contact's last row
                dst = self._spec(self.mode_name(active - {cname}))
                kind = "release" if isinstance(c, JointStop) else "liftoff"
                guard, args = self._release_guard(spec, row)
                out.append(Transition(spec.name, dst.name, guard, self._plain_reset(spec, dst),
                                      name=f"{kind}_{cname}", guard_args=args))
                continue
            released = set(getattr(c, "releases", ()))
            staying = (active - released)
            kept = [(r, 0.0) for r in self._order if r in staying and r in self._rigid]
            rows = kept + [(cname, c.restitution)]
            stick = self._spec(self.mode_name(staying | {cname}))
            free = self._spec(self.mode_name(staying))
            args = "t,x,u" if self._timed else "x"
            if c.restitution == 0.0:
                # A plastic impact sticks only if the contact then pushes (lambda > 0); otherwise
                # the contact separates at once. The two cases are two transitions with the same
                # impact law and complementary guards, so no reset lands outside its target.
                kind = "impact" if isinstance(c, JointStop) else "touchdown"
                stick_reset = self._impact_reset(spec, stick, rows)
                out.append(Transition(spec.name, stick.name, self._plastic_guard(spec, cname, stick, stick_reset, 1.0),
                                      stick_reset, name=f"{kind}_{cname}", guard_args=args))
                out.append(Transition(spec.name, free.name, self._plastic_guard(spec, cname, stick, stick_reset, -1.0),
                                      self._impact_reset(spec, free, rows), name=f"graze_{cname}", guard_args=args))
            elif self.zeno_window is not None:
                # Zeno continuation: a bounce whose next flight would be shorter than the window
                # becomes a plastic impact into the constrained mode (when the contact then
                # pushes); the two transitions have complementary guards, as above.
                stick_reset = self._impact_reset(spec, stick, kept + [(cname, 0.0)])
                accumulation = self._accumulation(spec, cname, c.restitution, stick, free, stick_reset)
                out.append(Transition(spec.name, stick.name, self._zeno_guard(spec, cname, accumulation, True),
                                      stick_reset, name=f"rest_{cname}", guard_args=args))
                out.append(Transition(spec.name, free.name, self._zeno_guard(spec, cname, accumulation, False),
                                      self._impact_reset(spec, free, rows), name=f"bounce_{cname}", guard_args=args))
            else:
                out.append(Transition(spec.name, free.name, self._kin_guard(spec, cname),
                                      self._impact_reset(spec, free, rows), name=f"bounce_{cname}"))
        return out

    def _plastic_guard(self, spec: _ModeSpec, cname: str, stick: _ModeSpec, stick_reset, sign: float):
        """``max(gap guard, -sign * lambda+)``: lambda+ is the contact's normal force right after
        the plastic impact, computed only once the gap guard is past (then cached per state and
        control)."""
        def value(x: np.ndarray, u: Any) -> float:
            base = self._kinematic_guards(spec, x)[cname]
            if base >= 0.0:
                return base
            key = x.tobytes() + _control_key(u)
            cached = spec.post.get(cname)
            if cached is not None and cached[0] == key:
                lam = cached[1]
            else:
                lam = float(self.constraint_forces(stick.name, stick_reset(x), u)[cname][-1])
                spec.post[cname] = (key, lam)
            return max(base, -sign * lam)

        if self._timed:
            return lambda t, x, u: value(x, u)
        return lambda x: value(x, None)

    def _accumulation(self, spec: _ModeSpec, cname: str, c: float, stick: _ModeSpec, free: _ModeSpec,
                      stick_reset) -> Callable[[np.ndarray, Any], tuple[float, float, float]]:
        """``(x, u) -> (w, a_n, lambda+)`` for an impact of contact ``cname`` at x past its gap:
        a_n is the normal acceleration with which the contact would press closed after a plastic
        impact (``J_n (a_stuck - a_free)`` at the plastic post-impact state: what the constraint
        force has to cancel), lambda+ its normal force there, and w = c v0 the rebound speed,
        with v0 the approach speed back at the gap's zero, ``v0^2 = v_n^2 - 2 a_n depth``. Taking
        v0 rather than the speed at x makes the decision the same all along a step's way through
        the strip (the approach speeds up by a_n there), so the crossing search never meets a
        guard that switches branch inside the strip. Cached for the last (x, u)."""
        rigid = self._rigid[cname]
        n = self.n
        cache: dict[str, Any] = {"key": None, "value": None}

        def measure(x: np.ndarray, u: Any) -> tuple[float, float, float]:
            key = x.tobytes() + _control_key(u)
            if cache["key"] == key:
                return cache["value"]
            q, v = x[:n], x[n:2 * n]
            J, _ = self._constraint_rows([rigid], q, v, drift=False)
            jn = J[-1]
            if rigid.kind == "stop":
                depth = -rigid.sign * (q[rigid.dof] - rigid.contact.position)
            else:
                depth = rigid.contact.ground - float(self.data.oMf[rigid.frame_id].translation[2])
            after = stick_reset(x)
            a_stuck = self._dynamics(stick, after, u)[0].copy()
            lam_n = float(self.constraint_forces(stick.name, after, u)[cname][-1])
            a_free, _ = self._dynamics(free, after, u)
            a_n = float(jn @ (a_stuck - a_free))
            v_n = min(0.0, float(jn @ v))
            w = c * math.sqrt(max(v_n * v_n - 2.0 * a_n * max(depth, 0.0), 0.0))
            cache["key"], cache["value"] = key, (w, a_n, lam_n)
            return w, a_n, lam_n

        return measure

    def _zeno_guard(self, spec: _ModeSpec, cname: str, accumulation, rest: bool):
        """Guards of the two impacts of a bouncing contact under Zeno continuation. Past the gap
        guard (< 0) the impact *accumulates* when ``min(a_n window / 2 - w, lambda+) > 0`` (the
        next flight would be shorter than the window and the contact would push). The guard of
        the branch taken is the gap guard itself, so the strip keeps the gap's units and a
        bounce is held exactly as without continuation; the other branch's guard is ``-gap``
        (> 0, not past)."""
        window = float(self.zeno_window)  # type: ignore[arg-type]

        def value(x: np.ndarray, u: Any) -> float:
            base = self._kinematic_guards(spec, x)[cname]
            if base >= 0.0:
                return base
            w, a_n, lam = accumulation(x, u)
            accumulating = min(0.5 * a_n * window - w, lam) > 0.0
            return base if accumulating == rest else -base

        if self._timed:
            return lambda t, x, u: value(x, u)
        return lambda x: value(x, None)

    def _plain_reset(self, src: _ModeSpec, dst: _ModeSpec) -> Callable[[np.ndarray], np.ndarray] | None:
        if src.springs == dst.springs:
            return None  # identity: q and v carry over, so do the footholds
        return lambda x: self._map_state(src, dst, x, None)

    def _impact_reset(self, src: _ModeSpec, dst: _ModeSpec, rows) -> Callable[[np.ndarray], np.ndarray]:
        n = self.n

        def reset(x: np.ndarray) -> np.ndarray:
            v_new = self.impact_velocity(rows, x[:n], x[n:2 * n])
            return self._map_state(src, dst, x, v_new)

        return reset

    # -- energy and kinematics for pictures -----------------------------------------------
    def energy(self, mode: str, x: np.ndarray) -> float:
        """Total mechanical energy (J): kinetic + gravity (``model.gravity``) + leg springs."""
        spec = self._spec(mode)
        x = np.asarray(x, dtype=float)
        n = self.n
        self._counts["energy_evals"] += 1
        q, v = x[:n], x[n:2 * n]
        e = pin.computeKineticEnergy(self.model, self.data, q, v) + pin.computePotentialEnergy(self.model, self.data, q)
        for i, lg in enumerate(spec.springs):
            r, _ = self._leg_length(lg, x, i)
            e += 0.5 * lg.leg.stiffness * (lg.leg.rest_length - r) ** 2
        return float(e)

    def frame_positions(self, q: np.ndarray, frames: Iterable[str]) -> dict[str, np.ndarray]:
        """World (x, z) positions (m) of the named frames at configuration q."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        out = {}
        for fname in frames:
            fid = self._frame_id(fname, "frame_positions")
            t = pin.updateFramePlacement(self.model, self.data, fid).translation
            out[fname] = np.array([t[0], t[2]])
        return out

    def foot_positions(self, mode: str, x: np.ndarray) -> dict[str, np.ndarray]:
        """World (x, z) position (m) of every spring leg's foot: the foothold in stance, the
        end of the leg at rest length and flight angle otherwise."""
        spec = self._spec(mode)
        x = np.asarray(x, dtype=float)
        n = self.n
        out = {}
        for i, lg in enumerate(spec.springs):
            out[lg.leg.name] = np.array([x[2 * n + i], lg.leg.ground])
        flight = [lg for lg in spec.flight_legs]
        if flight:
            pos = self.frame_positions(x[:n], [f"{lg.leg.name}_foot" for lg in flight])
            for lg in flight:
                out[lg.leg.name] = pos[f"{lg.leg.name}_foot"]
        return out

    # -- the hybrid system ----------------------------------------------------------------
    def mode(self, mode: str) -> Mode:
        """The legsim ``Mode`` of contact mode ``mode``."""
        spec = self._spec(mode)
        return Mode(spec.dim, self.field(mode), names=spec.names)

    def expand(self, mode: str) -> tuple[Mode, list[Transition]]:
        """``HybridSystem`` expand callback: the mode and its outgoing transitions."""
        spec = self._spec(mode)
        return self.mode(mode), self._transitions(spec)

    def system(self, initial_mode: str | None = None, x0: Any = None, *, energy: bool = True) -> HybridSystem:
        """A lazily expanded ``HybridSystem`` of this robot (modes appear as transitions reach
        them). With ``x0`` the initial mode is built and checked at once."""
        initial = None
        if initial_mode is not None:
            self.active_contacts(initial_mode)
            if x0 is not None:
                initial = (initial_mode, x0)
        return HybridSystem({}, (), name=self.name, expand=self.expand,
                            energy=self.energy if energy else None, initial=initial)

    def counters(self) -> dict[str, int]:
        """Model-side evaluation counts since construction (or the last ``reset_counters``):
        aba, kkt (constrained solves), jacobians, kinematics (guard passes), spring_forces,
        damping_evals, actuation_evals, impacts, energy_evals, cache_hits."""
        return dict(self._counts)

    def reset_counters(self) -> None:
        """Set every counter to zero."""
        for k in self._counts:
            self._counts[k] = 0


def _control_key(u: Any) -> bytes:
    """Bytes identifying a control value, for caches keyed by state and control."""
    if u is None:
        return b""
    return np.asarray(u, dtype=float).tobytes()


def _solve_small(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve A y = b for the small symmetric positive definite Delassus matrix A; one and two
    rows (a stop, a foot) in closed form, where LAPACK's call overhead would dominate."""
    if A.shape[0] == 1:
        return b / A[0, 0]
    if A.shape[0] == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        return np.array(((A[1, 1] * b[0] - A[0, 1] * b[1]) / det, (A[0, 0] * b[1] - A[1, 0] * b[0]) / det))
    return np.linalg.solve(A, b)


def _finite(value: Any, where: str, *, low: float | None = None, high: float | None = None,
            low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ModelError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ModelError(f"{where} must be finite, got {value}")
    if low is not None and (value < low or (low_open and value == low)):
        raise ModelError(f"{where} must be {'>' if low_open else '>='} {low:g}, got {value:g}")
    if high is not None and value > high:
        raise ModelError(f"{where} must be <= {high:g}, got {value:g}")
    return value


def planar_floating_base(model: pin.Model, parent: int = 0, placement: pin.SE3 | None = None,
                         names: tuple[str, str, str] = ("x", "z", "theta")) -> int:
    """Add the planar floating base (PX, PZ, RY joints) of a body moving in the (x, z) plane;
    returns the id of the pitch joint, to which the body's inertia is attached. Positive pitch
    (rotation about +y) turns the body's +x axis downwards (nose down)."""
    jx = model.addJoint(parent, pin.JointModelPX(), placement or pin.SE3.Identity(), names[0])
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), names[1])
    return int(model.addJoint(jz, pin.JointModelRY(), pin.SE3.Identity(), names[2]))


def add_point_frame(model: pin.Model, name: str, joint: int, xyz: Sequence[float]) -> int:
    """Add an operational frame ``name`` at ``xyz`` (m) in joint ``joint``'s frame; returns its id."""
    return int(model.addFrame(pin.Frame(name, joint, pin.SE3(np.eye(3), np.asarray(xyz, dtype=float)),
                                        pin.FrameType.OP_FRAME), False))
