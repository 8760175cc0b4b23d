"""Grazing cases: a trajectory that touches a guard without crossing it, or crosses it for a
moment. The circular flow and the plane x1 = 1 (paper 004 Sec. IV-D, Fig. 1), started on a
circle that touches, misses or cuts the plane by a tiny distance.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...execution import Execution
from ...hybrid import HybridSystem
from ...relaxed import simulate
from ..framework import CaseResult, Check, case
from ..invariants import check_order, execution_checks
from ..models import build

OMEGA, WALL, T_FINAL = 1.0, 1.0, 3.0  # rad/s, the plane x1 = WALL, s


def _grazing(result: CaseResult, quick: bool, offsets: Sequence[float], label: str) -> None:
    """The circle of radius 1 + d through (0, 1 + d) touches (d = 0), misses (d < 0) or cuts
    (d > 0) the plane x1 = 1 near t = pi/2; the exact execution switches twice (d > 0: out and
    back, for 2 sqrt(2 d) s) or never. Resets are the identity, so whatever the relaxed execution
    does near the plane its *state* must stay on the circle: the only errors are RK4's and the
    holds in strips (the state stands still for at most h + eps per transition).

    Steps longer than the excursion step over it (no switch, RK4's error); steps that resolve it
    pay the holds, first order in h + eps. Each offset is run on refinements of one kind: with
    d = 1e-6 (an excursion of 2.8e-3 s), h from 1e-2 down with eps = h/10."""
    model = build("circular_flow", {"omega": OMEGA, "wall": WALL})
    main = None
    worst_state, worst_mode, counts = 0.0, 0.0, []
    for d in offsets:
        x0 = np.array([0.0, WALL + d])
        ref = model.reference.with_initial("inside", x0)
        resolving = d >= 1e-7
        if resolving:
            hs = [1e-2, 3e-3, 1e-3] + ([] if quick else [3e-4])
        else:
            hs = [0.1, 0.03, 0.01] + ([] if quick else [0.003])
        errs, switched = [], []
        for h in hs:
            eps = h / 10 if resolving else 1e-3
            ex, err, state_ratio, mode_ratio = _graze(result, model.system, ref, x0, d, h, eps)
            main = main or ex
            counts.append(len(ex.transitions))
            switched.append(len(ex.transitions) > 0)
            errs.append(err)
            worst_state = max(worst_state, state_ratio)
            worst_mode = max(worst_mode, mode_ratio)
        result.numbers[f"error_d{d:g}"] = ", ".join(f"h={h:g}: {e:.2g}" for h, e in zip(hs, errs, strict=True))
        result.add(_converges(d, hs, errs, switched))
    result.add(
        Check(
            "state on the circle",
            worst_state <= 1.0,
            f"state error <= RK4 bound + two holds x speed (worst ratio {worst_state:.2g})",
        )
    )
    result.add(
        Check(
            "modes differ only at the plane",
            worst_mode <= 1.0 + 1e-9,
            f"where the relaxed and exact modes differ the exact x1 is within the state error + |d| of "
            f"the plane (worst ratio {worst_mode:.2g})",
        )
    )
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.outcome = f"{label}; switches per run {counts}"


def _graze(
    result: CaseResult, system: HybridSystem, ref, x0: np.ndarray, d: float, h: float, eps: float
) -> tuple[Execution, float, float, float]:
    """One run from x0 (offset d from tangency) checked against the exact circle: adds its
    execution checks and returns (execution, state error, state error / allowed, worst mode
    mismatch / allowed)."""
    ex = simulate(system, x0, "inside", T_FINAL, h, eps, max_transitions=100)
    # at most two switches (T < 2 pi / omega): the circle meets a line twice
    result.add(execution_checks(system, ex, eps, bound=2, bound_why="a circle meets a line twice"))
    times = np.linspace(0.0, ex.t_end, 601)
    got = ex.sample(times)
    want = ref.sample(times)
    held = sum(tr.exit_time - tr.time for tr in ex.transitions)
    radius = WALL + abs(d)
    rk4 = (OMEGA * h) ** 4 / 120.0 * OMEGA * T_FINAL * radius / h  # global error of RK4 on a rotation
    # a hold lasts at most h + eps, and there are at most two switches
    allowed = rk4 + OMEGA * radius * min(held, 2 * (h + eps)) + 1e-12
    err = float(np.max(np.abs(np.array(got.states) - np.array(want.states))))
    # modes may differ only where the exact state is within the state error of the plane
    near = [abs(float(s[0]) - WALL) for s, a, b in zip(want.states, got.modes, want.modes, strict=False) if a != b]
    mode_ratio = max([0.0] + [n / (err + abs(d) + 1e-15) for n in near])
    return ex, err, err / allowed, mode_ratio


def _converges(d: float, hs: Sequence[float], errs: Sequence[float], switched: Sequence[bool]) -> Check:
    """First order in h where every refinement switches (the holds), RK4's fourth order where none
    does; refinements that disagree on switching fail."""
    if all(switched):
        return check_order(f"converges (d = {d:g})", hs, errs, 0.7, 1.3, "h, eps = h/10")
    if not any(switched):
        return check_order(f"converges (d = {d:g})", hs, errs, 3.5, 4.5, "h, eps = 1e-3")
    return Check(
        f"converges (d = {d:g})",
        False,
        f"some refinements switch and others do not: {dict(zip(hs, switched, strict=True))}",
    )


@case("grazing_tangent", "grazing", "circular flow from (0, 1): touches x1 = 1 at t = pi/2 without crossing")
def _grazing_tangent(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [0.0], "touches")


@case("grazing_inside", "grazing", "circular flow a tiny distance inside tangency (radius 1 - 1e-9, 1 - 1e-6)")
def _grazing_inside(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [-1e-9, -1e-6], "misses")


@case(
    "grazing_outside",
    "grazing",
    "circular flow a tiny distance beyond tangency (radius 1 + 1e-9, 1 + 1e-6): two switches",
)
def _grazing_outside(result: CaseResult, quick: bool) -> None:
    _grazing(result, quick, [1e-9, 1e-6], "cuts")
