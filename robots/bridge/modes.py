"""Contact modes: which contacts are active, the mode's name and its state layout.

A mode is a set of active contacts, each an *entry*: the contact's name, or for a contact with
Coulomb friction that slips, its name with the slip direction's suffix (``front>`` slips towards
+x, ``front<`` towards -x; ``front`` alone is stuck). It is named by ``mode_names`` when given
there, ``"free"`` when empty, else by its entries in declared order joined with ``+``. Its state is
``x = (q, v, footholds)``: q and v of size nv, then the foothold x (m) of each active spring leg
in declared order. Modes are resolved into a ``ModeSpec`` on first use, so a robot with many
contacts never enumerates the 2^n subsets.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TypeVar

import pinocchio as pin

from legsim.errors import ModelError

from .contacts import SLIP_SUFFIX, LegFrames, RigidContact
from .layout import S_ABSENT, S_ACTIVE, S_SLIP_NEG, S_SLIP_POS
from .model import BridgeModel

#: A key of ``mode_names``: a subset of contacts (a tuple, a set, ...) or one contact's name.
#: A type variable, not a union: a mapping's key type is invariant, and each caller's dict has its own.
SubsetKey = TypeVar("SubsetKey", bound=Iterable[str])


@dataclass(frozen=True, eq=False)
class ModeSpec:
    """Everything about one mode its parameters are built from, resolved once.

    Attributes
    ----------
    name: the mode's name.
    active: its active contacts, in declared order.
    rigid: the active point contacts and joint stops, in declared order.
    slips: the slip direction of each active rigid contact (0: stuck or without friction), in
        the order of ``rigid``.
    springs: the active (stance) spring legs, in declared order: their footholds are the state's tail.
    flight_legs: the inactive spring legs.
    dim: state dimension, 2 nv + len(springs).
    names, units: the state's coordinate names and units.
    entries: its entries (an active contact's name, with a slipping one's suffix), declared order.
    status: each rigid contact's status (``layout.S_*``), in the model's declared order.
    """

    name: str
    active: tuple[str, ...]
    rigid: tuple[RigidContact, ...]
    slips: tuple[float, ...]
    springs: tuple[LegFrames, ...]
    flight_legs: tuple[LegFrames, ...]
    dim: int
    names: tuple[str, ...]
    units: tuple[str, ...]
    entries: tuple[str, ...]
    status: tuple[float, ...]

    @property
    def slipping(self) -> bool:
        """Whether some contact of the mode slips (its constraint forces then include friction)."""
        return any(self.slips)

    def slip_of(self, contact: str) -> float:
        """The slip direction of the active rigid contact ``contact`` (0: stuck)."""
        return next(s for r, s in zip(self.rigid, self.slips, strict=True) if r.contact.name == contact)

    def rows_of(self, r: RigidContact, slip: float) -> int:
        """Constraint rows of an active rigid contact in this mode (a slipping point: 1)."""
        return 1 if slip else r.rows

    @property
    def rows(self) -> int:
        """The mode's constraint rows."""
        return sum(self.rows_of(r, s) for r, s in zip(self.rigid, self.slips, strict=True))

    def normal_row(self, contact: str) -> int:
        """Index of the active rigid contact's normal row in the stacked constraint rows (its last row)."""
        row, i = -1, 0
        for r, s in zip(self.rigid, self.slips, strict=True):
            i += self.rows_of(r, s)
            if r.contact.name == contact:
                row = i - 1
        return row


class ModeCatalog:
    """Mode names <-> sets of active entries, and each mode's ``ModeSpec``, built on first use.

    ``mode_names``: optional readable names of entry subsets, ``{("left", "right"): "both", (): "aerial"}``
    (a single entry may be given by its name).
    """

    def __init__(self, model: BridgeModel, mode_names: Mapping[SubsetKey, str] | None = None) -> None:
        self._model = model
        self._names: dict[frozenset[str], str] = {}
        self._sets: dict[str, frozenset[str]] = {}
        self._specs: dict[str, ModeSpec] = {}
        # a mode's entries by name and an entry's parse, once each: a robot with many contacts
        # names its modes' targets hundreds of thousands of times while building them
        self._entries: dict[str, tuple[str, ...]] = {}
        self._parsed: dict[str, tuple[str, float] | None] = {}
        for key, mname in (mode_names or {}).items():
            subset: frozenset[str] = frozenset([key]) if isinstance(key, str) else frozenset(key)
            unknown = sorted(e for e in subset if self._parse(e) is None)
            if unknown:
                raise ModelError(
                    f"{model.name}: mode_names names unknown contact(s) {unknown}; contacts: {model.order}"
                )
            if not isinstance(mname, str) or not mname or mname in self._sets:
                raise ModelError(f"{model.name}: mode name {mname!r} is empty, not a string or used twice")
            self._names[subset] = mname
            self._sets[mname] = subset

    def _parse(self, entry: str) -> tuple[str, float] | None:
        """(contact, slip direction) of an entry, or None when it names no contact (or a slip of a
        contact without friction)."""
        if entry not in self._parsed:
            self._parsed[entry] = self._parse_entry(entry)
        return self._parsed[entry]

    def _parse_entry(self, entry: str) -> tuple[str, float] | None:
        contacts = self._model.contacts
        if entry in contacts:
            return entry, 0.0
        for s, suffix in SLIP_SUFFIX.items():
            if entry.endswith(suffix) and getattr(contacts.get(entry[:-1]), "friction", None) is not None:
                return entry[:-1], s
        return None

    def _check(self, subset: frozenset[str]) -> None:
        model = self._model
        parsed = [self._parse(e) for e in subset]
        unknown = sorted(e for e, p in zip(subset, parsed, strict=True) if p is None)
        if unknown:
            raise ModelError(f"{model.name}: unknown contact(s) {unknown}; contacts: {model.order}")
        names = [p[0] for p in parsed if p is not None]
        if len(set(names)) != len(names):
            raise ModelError(f"{model.name}: a contact is named twice in {sorted(subset)}")

    def name_of(self, active: Iterable[str]) -> str:
        """Name of the mode whose active entries are ``active``."""
        subset = frozenset(active)
        self._check(subset)
        if subset in self._names:
            return self._names[subset]
        if not subset:
            return "free"
        return "+".join(self.ordered(subset))

    def ordered(self, entries: Iterable[str]) -> tuple[str, ...]:
        """``entries`` in the declared order of their contacts."""
        rank = {c: i for i, c in enumerate(self._model.contacts)}
        return tuple(sorted(entries, key=lambda e: rank[self._parse(e)[0]]))  # type: ignore[index]

    def entries(self, mode: str) -> tuple[str, ...]:
        """The active entries of mode ``mode``, in declared order; ``ModelError`` if ``mode``
        names no mode or a mode by another name than its own."""
        if mode not in self._entries:
            self._entries[mode] = self._entries_of(mode)
        return self._entries[mode]

    def _entries_of(self, mode: str) -> tuple[str, ...]:
        model = self._model
        if mode in self._sets:
            subset = self._sets[mode]
        elif mode == "free":
            subset = frozenset()
        else:
            parts = mode.split("+")
            if any(self._parse(p) is None for p in parts) or len(set(parts)) != len(parts):
                raise ModelError(
                    f"{model.name}: '{mode}' is not a mode: name a set of contacts joined by '+' "
                    f"(contacts: {model.order}) or one of {sorted(self._sets)}"
                )
            subset = frozenset(parts)
        if self.name_of(subset) != mode:
            raise ModelError(f"{model.name}: mode '{mode}' is called '{self.name_of(subset)}'")
        return self.ordered(subset)

    def active_contacts(self, mode: str) -> tuple[str, ...]:
        """The active contacts of mode ``mode`` (without slip suffixes), in declared order."""
        return tuple(self._parse(e)[0] for e in self.entries(mode))  # type: ignore[index]

    def spec(self, mode: str) -> ModeSpec:
        """The ``ModeSpec`` of mode ``mode`` (resolved on first use)."""
        spec = self._specs.get(mode)
        if spec is None:
            entries = self.entries(mode)
            slips = dict(self._parse(e) for e in entries)  # type: ignore[misc]
            spec = self._specs[mode] = build_spec(self._model, mode, tuple(slips), slips, entries)
        return spec


def build_spec(
    model: BridgeModel,
    mode: str,
    active: tuple[str, ...],
    slips: Mapping[str, float] | None = None,
    entries: tuple[str, ...] | None = None,
) -> ModeSpec:
    """The ``ModeSpec`` of mode ``mode`` with active contacts ``active`` (declared order);
    ``slips``: the slip direction of each slipping contact (absent or 0: stuck)."""
    slips = slips or {}
    rigid = tuple(model.rigid[c] for c in active if c in model.rigid)
    springs = tuple(model.legs[c] for c in active if c in model.legs)
    flight = tuple(lg for c, lg in model.legs.items() if c not in active)
    names = model.coordinate_names + model.velocity_names + tuple(f"{lg.leg.name}_foot_x" for lg in springs)
    positions = dof_units(model.pin_model)
    units = positions + tuple(f"{u}/s" for u in positions) + ("m",) * len(springs)
    status = tuple(
        float(
            S_ABSENT
            if c not in active
            else S_ACTIVE
            if not slips.get(c)
            else S_SLIP_POS
            if slips[c] > 0
            else S_SLIP_NEG
        )
        for c in model.rigid
    )
    return ModeSpec(
        mode,
        active,
        rigid,
        tuple(float(slips.get(r.contact.name, 0.0)) for r in rigid),
        springs,
        flight,
        2 * model.n + len(springs),
        names,
        units,
        active if entries is None else entries,
        status,
    )


def dof_units(pin_model: pin.Model) -> tuple[str, ...]:
    """The unit of each configuration coordinate: ``"m"`` for a prismatic joint, ``"rad"`` for
    a revolute one (composite joints by their parts), ``""`` for any other kind."""

    def of(joint) -> list[str]:
        kind = joint.shortname()
        if kind == "JointModelComposite":
            return [u for part in joint.extract().joints for u in of(part)]
        unit = "m" if kind.startswith("JointModelP") else "rad" if kind.startswith("JointModelR") else ""
        return [unit] * joint.nv

    return tuple(u for joint in pin_model.joints[1:] for u in of(joint))
