"""Transitions crossed in the same landing step: resolved together by the model, or one after
the other with the order's effect measured.

A step that lands in several strips at once (a rod landing flat on both ends) has crossed all
their guards within eps of each other. When the system has a ``joint`` function (the Pinocchio
bridge: one impact law for all the contacts that close), the transitions are resolved at once
from the strip point of the first crossing. Otherwise they are taken one after the other (the
next mode is entered inside the next strip and crosses it at once); for two self-transitions of
a mode the run then measures whether their resets commute at the strip point, and warns when the
order changes the state (the outcome would depend on which guard rounding puts first).
"""

from __future__ import annotations

import numpy as np

from ..execution import RunWarning
from ..hybrid import JointCrossing, ModeData

#: Relative difference of the two orders' images above which resets count as not commuting.
COMMUTE_TOL = 1e-9


def joint_name(data: ModeData, crossed: list[int]) -> str:
    """The key under which crossings of this set of transitions are followed (``zeno``)."""
    return "+".join(sorted(data.transitions[e].name for e in crossed))


def joint_crossing(system, data: ModeData, crossed: list[int], q: np.ndarray, rest: bool) -> JointCrossing | None:
    """The model's joint resolution of the transitions ``crossed`` (indices of ``data``'s, the
    first crossed first) at q, or None; ``rest``: their crossings accumulate, take the continuation
    (every striker plastic)."""
    if len(crossed) < 2 or system.joint is None:
        return None
    return system.joint(data.name, tuple(data.transitions[e].name for e in crossed), q, rest)


class OrderWatch:
    """Collects, per pair of self-transitions crossed together, the largest difference between
    their two orders, for one warning per pair."""

    def __init__(self) -> None:
        self._pairs: dict[tuple[str, str, str], list[float]] = {}

    def check(self, data: ModeData, crossed: list[int], q: np.ndarray, t: float) -> None:
        """Compare R_b(R_a(q)) with R_a(R_b(q)) for the first two self-transitions crossed."""
        selfs = [e for e in crossed if data.targets[e] == data.name]
        if len(selfs) < 2:
            return
        a, b = selfs[0], selfs[1]
        ra, rb = data.resets[a], data.resets[b]
        one, other = np.asarray(rb(ra(q.copy())), dtype=float), np.asarray(ra(rb(q.copy())), dtype=float)
        difference = float(np.max(np.abs(one - other))) if one.shape == other.shape else float("inf")
        scale = 1.0 + float(np.max(np.abs(one))) if one.size else 1.0
        if difference > COMMUTE_TOL * scale:
            key = (data.name, data.transitions[a].name, data.transitions[b].name)
            entry = self._pairs.setdefault(key, [t, 0.0, 0])
            entry[1] = max(entry[1], difference)
            entry[2] += 1

    def warnings(self) -> list[RunWarning]:
        out = []
        for (mode, a, b), (t, difference, count) in self._pairs.items():
            message = (
                f"transitions {a} and {b} of mode '{mode}' were crossed in the same step {count} time(s) from "
                f"t={t:.6g} s, and their resets do not commute there: the two orders give states up to "
                f"{difference:.3g} apart, so the result depends on which guard rounding puts first. Remedy: "
                f"resolve them together (HybridSystem(joint=...)), or make the resets commute."
            )
            out.append(
                RunWarning(
                    "non_commuting_resets",
                    message,
                    t,
                    {"mode": mode, "transitions": [a, b], "difference": difference, "count": count},
                )
            )
        return out
