"""Simultaneous-event cases: two guards crossed at the same instant, where a simulator must
choose an order and the result must not depend on the choice more than continuity allows. The
symmetric pronk (both feet at once, paper 000 Fig. 17), the pronk from tiny random pitches, and
the digital controller whose two thresholds are reached at t = ln 2 (paper 000 Fig. 1).
"""

from __future__ import annotations

import math

import numpy as np

from ...execution import Execution
from ...hybrid import HybridSystem
from ...relaxed import simulate
from ..framework import CaseResult, Check, case
from ..invariants import check_order, energies, execution_checks
from ..models import build, model_state, pronk, slip_twin


def pair_checks(ex: Execution, h: float) -> Check:
    """Touchdowns and liftoffs of the two legs come in pairs, the second crossed in the step
    after the first's strip (its crossing time is that strip's exit, within one step h)."""
    trs = ex.transitions
    worst, pairs = 0.0, 0
    ok = len(trs) % 2 == 0 and len(trs) > 0
    for a, b in zip(trs[0::2], trs[1::2], strict=False):
        kind_a, kind_b = a.name.split("_")[0], b.name.split("_")[0]
        if kind_a != kind_b or a.name == b.name:
            ok = False
            break
        pairs += 1
        worst = max(worst, b.time - a.exit_time)
    ok = ok and 0.0 <= worst <= h
    return Check(
        "both legs in the same step",
        ok,
        f"{pairs} pairs; second crossing <= {worst:.2g} s after the first strip's exit (h = {h:g} s)",
    )


@case(
    "simultaneous_pronk",
    "simultaneous",
    "symmetric pronk (paper 000 Fig. 17 left): both feet touch down and lift off together",
)
def _simultaneous_pronk(result: CaseResult, quick: bool) -> None:
    h, eps, T = 1e-3, 1e-2, 2.0
    model = pronk()
    x0 = model_state(model, "aerial")
    slip = slip_twin()
    limit = simulate(slip.system, x0[[0, 1, 3, 4]], "flight", T, h, 1e-9)
    bound = 2 * len(limit.transitions) + 4
    ex = simulate(model.system, x0, "aerial", T, h, eps, max_transitions=10 * bound)
    result.main_run(ex)
    result.add(
        execution_checks(
            model.system,
            ex,
            eps,
            energy="conservative",
            energy_tol=1e-6,
            bound=bound,
            bound_why=f"two per SLIP transition + 4 (the SLIP twin's {len(limit.transitions)} in {T:g} s)",
        )
    )
    result.add(pair_checks(ex, h))
    theta = max(float(np.max(np.abs(seg.x[:, 2]))) for seg in ex.segments)
    result.add(Check("pitch stays zero", theta <= 1e-10, f"max |theta| = {theta:.2g} rad"))
    # Convergence to the SLIP twin as eps shrinks (h fixed, small): paper 000's pronk is the
    # eps -> 0 limit of the relaxed execution.
    hh, T2 = 2.5e-4, 0.5
    ref = simulate(slip.system, x0[[0, 1, 3, 4]], "flight", T2, hh, 1e-9).final_state
    levels = [2e-2, 1e-2, 5e-3] + ([] if quick else [2.5e-3])
    dist = []
    for ee in levels:
        run = simulate(model.system, x0, "aerial", T2, hh, ee)
        dist.append(float(np.linalg.norm(run.final_state[[0, 1, 3, 4]] - ref[:4])))
    result.add(check_order("distance to the SLIP limit -> 0", levels, dist, 0.8, 1.2, "eps (h = 2.5e-4)"))
    E = energies(model.system, ex)[1]
    result.numbers.update({"energy_drift": float(np.max(np.abs(E - E[0]))), "max_theta": theta})
    result.outcome = (
        f"{ex.status}; {len(ex.transitions) // 2} pairs of simultaneous transitions, |theta| <= {theta:.0g}"
    )


@case(
    "simultaneous_runner_random_pitch",
    "simultaneous",
    "pronk from random pitches |theta0| <= 1e-7: both feet reach the ground in the same step",
)
def _simultaneous_random_pitch(result: CaseResult, quick: bool) -> None:
    h, eps, T = 1e-3, 1e-2, 0.95  # one hop: touchdowns, liftoffs, and the next flight
    model = pronk()
    x0 = model_state(model, "aerial")
    rng = np.random.default_rng(7)
    n = 4 if quick else 12
    pitches = rng.uniform(-1e-7, 1e-7, n)
    pitches[0], pitches[1] = abs(pitches[0]), -abs(pitches[1])  # both signs, always
    finals, firsts, main = [], [], None
    for th in pitches:
        x = x0.copy()
        x[2] = th
        ex = simulate(model.system, x, "aerial", T, h, eps, max_transitions=40)
        main = main or ex
        result.add(
            execution_checks(
                model.system,
                ex,
                eps,
                energy="conservative",
                energy_tol=1e-6,
                bound=4,
                bound_why="one hop: two touchdowns, two liftoffs",
            )
        )
        result.add(pair_checks(ex, h))
        finals.append(ex.final_state[:6])
        firsts.append(ex.transitions[0].name if ex.transitions else "")
    # theta > 0 pitches the nose (the right hip) down: the right foot is lower and lands first.
    expected = ["touchdown_right" if th > 0 else "touchdown_left" for th in pitches]
    result.add(
        Check(
            "the lower foot lands first",
            firsts == expected,
            f"{sum(a == b for a, b in zip(firsts, expected, strict=True))}/{len(pitches)} as the sign of theta0 says",
        )
    )
    # Continuity through the corner: whichever foot is taken first, the states after the hop
    # differ by O(|theta_i - theta_j|), with the sensitivity measured at a pitch 100 times larger.
    x = x0.copy()
    x[2] = 1e-5
    far = simulate(model.system, x, "aerial", T, h, eps).final_state[:6]
    lipschitz = float(np.max(np.abs(far - finals[0]))) / abs(1e-5 - pitches[0])
    worst = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            worst = max(
                worst,
                float(np.max(np.abs(finals[i] - finals[j]))) / (10 * lipschitz * abs(pitches[i] - pitches[j]) + 1e-12),
            )
    result.add(
        Check(
            "continuous through the corner",
            worst <= 1.0,
            f"|x_i - x_j| <= 10 L |theta_i - theta_j| + 1e-12, L = {lipschitz:.3g} from theta0 = 1e-5 "
            f"(worst ratio {worst:.2g})",
        )
    )
    corner, worst_corner = _corner_is_the_limit(model.system, x0, pitches[0], lipschitz, T, quick)
    result.add(corner)
    assert main is not None  # set by the loop above, which runs at least once
    result.main_run(main)
    result.numbers.update(
        {"pitches": ", ".join(f"{p:.2g}" for p in pitches), "lipschitz": lipschitz, "corner_ratio_worst": worst_corner}
    )
    result.outcome = f"{len(pitches)} pitches: first touchdown follows the sign of theta0; pairs within one step"


def _corner_is_the_limit(
    system: HybridSystem, x0: np.ndarray, pitch: float, lipschitz: float, T: float, quick: bool
) -> tuple[Check, float]:
    """The symmetric start (exactly on the corner) is the limit of its pitched neighbours at every
    h and eps: its second leg's guard is within rounding of zero when its mode is entered,
    which counts as on the guard, so the crossing is found by the next step exactly as for a
    pitch of 1e-9 (no O(h) jump decided by the last bits of the strip point). Returns the check
    and its worst ratio."""
    levels = [(1e-3, 1e-2), (5e-4, 5e-3), (2.5e-4, 2.5e-3)] + ([] if quick else [(1.25e-4, 1.25e-3)])
    ratios = []
    for hh, ee in levels:
        sym = simulate(system, x0, "aerial", T, hh, ee).final_state[:6]
        x = x0.copy()
        x[2] = pitch
        jump = float(np.max(np.abs(simulate(system, x, "aerial", T, hh, ee).final_state[:6] - sym)))
        ratios.append(jump / (10 * lipschitz * abs(pitch) + 1e-12))
    check = Check(
        "the corner is the limit of its neighbours",
        max(ratios) <= 1.0,
        f"|x(theta0 = 0) - x(theta0 = {pitch:.2g})| <= 10 L |theta0| + 1e-12 at h = "
        f"{', '.join(f'{lv[0]:g}' for lv in levels)} (eps = 10 h); worst ratio {max(ratios):.2g}",
    )
    return check, max(ratios)


@case(
    "simultaneous_digital_control",
    "simultaneous",
    "digital control (paper 000 Fig. 1): both thresholds at t = ln 2; neighbours take 0->2->3 and 0->1->3",
)
def _simultaneous_digital(result: CaseResult, quick: bool) -> None:
    model = build("digital_control", {}, {"boost": {"setpoint": 2.0}})
    ref0 = model.reference
    T, delta = 3.0, 1e-6
    starts = {
        "x": np.array([-1.0, -1.0]),
        "y_delta": np.array([-1.0 - delta, -1.0]),
        "z_delta": np.array([-1.0, -1.0 - delta]),
    }
    paths = {}
    main = None
    levels = [(1e-2, 1e-4), (5e-3, 5e-5), (2.5e-3, 2.5e-5)] + ([] if quick else [(1.25e-3, 1.25e-5)])
    errors = []
    for label, x0 in starts.items():
        ref = ref0.with_initial("0", x0)
        for k, (h, eps) in enumerate(levels):
            ex = simulate(model.system, x0, "0", T, h, eps, max_transitions=10)
            main = main or ex
            result.add(
                execution_checks(
                    model.system, ex, eps, bound=2, bound_why="each threshold is crossed once; mode 3 has no guard"
                )
            )
            if k == 0:
                paths[label] = "->".join(ex.mode_sequence)
            # Autonomous fields and identity resets: the relaxed execution is the exact one
            # paused in its strips, so its state at T is the exact state at T minus the time held.
            held = sum(tr.exit_time - tr.time for tr in ex.transitions)
            warp = float(np.max(np.abs(ex.final_state - ref.state(T - held))))
            result.add(
                Check(
                    f"exact up to the holds ({label}, h={h:g})",
                    warp <= 1e-9,
                    f"|x(T) - x_exact(T - held)| = {warp:.2g} (held {held:.3g} s)",
                )
            )
            if label == "x":
                errors.append(float(np.max(np.abs(ex.final_state - ref.state(T)))))
    ok = paths == {"x": "0->1->3", "y_delta": "0->2->3", "z_delta": "0->1->3"}
    result.add(Check("paths", ok, f"{paths} (x takes the first listed guard on the tie; y crosses xi2 first)"))
    assert main is not None  # set by the loop above, which runs at least once
    t_cross = [tr.time for tr in main.transitions]
    ok = abs(t_cross[0] - math.log(2.0)) <= 1e-9 and t_cross[1] == main.transitions[0].exit_time
    result.add(
        Check(
            "both thresholds at ln 2",
            ok,
            f"first crossing at {t_cross[0]:.12g} s (ln 2 = {math.log(2):.12g}), the second at the first strip's exit",
        )
    )
    result.add(check_order("x(T) -> exact", [lv[0] for lv in levels], errors, 0.8, 1.2, "h (eps = h/100)"))
    result.main_run(main)
    result.outcome = f"paths {paths['x']} (x), {paths['y_delta']} (y), {paths['z_delta']} (z)"
