"""Resting-contact cases: a ball that comes to rest on the floor and is lifted off by a growing
force u = 3 t N (the suite's lifted ball, ``models.lifted_ball``). Plastic (c = 0), chattering
(c = 0.2, the paper's relaxed execution, ``continuation=False``), and with the default
continuation (c = 0.2: the bounce's continuation ``land`` taken where the bounces accumulate):
each must leave the floor where the force cancels the weight, t* = m g / r.
"""

from __future__ import annotations

import math

import numpy as np

from ...execution import Execution
from ...relaxed import simulate
from ..framework import CaseResult, Check, case
from ..invariants import execution_checks, transition_floor
from ..models import lifted_ball
from ..reference_checks import ball_rest_crossing

G, MASS, LIFT_RATE, Z0 = 9.81, 1.0, 3.0, 0.5  # m/s^2, kg, N/s, m (the drop height)
H, EPS = 1e-3, 1e-4


def _resting(result: CaseResult, quick: bool, c: float, continued: bool) -> None:
    t_star = MASS * G / LIFT_RATE
    T = t_star + 1.0
    system, control = lifted_ball(c, LIFT_RATE, G, MASS)
    ex = simulate(
        system, [Z0, 0.0], "flight", T, H, EPS, control=control, max_transitions=10**6, continuation=continued
    )
    result.main_run(ex)
    bound, why = _transition_bound(c, continued, t_star, T)
    result.add(execution_checks(system, ex, EPS, control=control, energy=None, bound=bound, bound_why=why))
    releases = [tr for tr in ex.transitions if tr.name == "release"]
    if c == 0.0 or continued:
        result.add(_rest_and_release_checks(ex, releases, t_star, T))
    else:
        check, lag = _lift_off_check(ex, t_star, T)
        result.add(check)
        result.numbers["lift_lag"] = lag
    result.numbers["transitions"] = len(ex.transitions)
    # The plain run has no release transition: it leaves the floor when its last strip exit
    # is not followed by another impact.
    if releases:
        how = f"released at {releases[0].time:.6g} s"
    elif ex.transitions:
        how = f"lifts off at {ex.transitions[-1].exit_time:.6g} s (last strip exit)"
    else:
        how = "no impact"
    result.outcome = f"{ex.status}; {len(ex.transitions)} transitions, {how}"


def _transition_bound(c: float, continued: bool, t_star: float, T: float) -> tuple[float, str]:
    """The bound on the transitions of the run to T and how it is derived."""
    if c == 0.0:
        return 2, "a plastic landing and a release"
    if continued:
        # The k-th impact's rebound is at most c^k v1 (the pressing acceleration a = g - rate t
        # falls during each flight, so a ball comes back slower than it left) and its flight at
        # most 2 c^k v1 / a_lo, a_lo the least a over the accumulation (before t* / 2 here): the
        # ball lands at the latest at the crossing ball_rest_crossing says for a_lo, then the release.
        v1 = math.sqrt(2 * G * Z0)
        a_lo = G - LIFT_RATE * (0.5 * t_star)
        bound = ball_rest_crossing(v1, c, a_lo, H + EPS) + 1
        return bound, "1 + ceil(log(2 v1/(a_lo w))/log(1/c)) crossings to the landing, a release"
    floor = transition_floor(H, EPS, accel=G)
    return T / floor + 1, f"T/{floor:.3g} s"


def _rest_and_release_checks(ex: Execution, releases: list, t_star: float, T: float) -> list[Check]:
    """Rests, then the release is located on the force's zero crossing, t* = m g / r, and the
    flight after it is the exact cubic from the strip exit."""
    ok = len(releases) == 1 and abs(releases[0].time - t_star) <= 1e-9
    checks = [
        Check(
            "released at t* = m g / r",
            ok,
            f"release at {releases[0].time if releases else math.nan:.12g} s, t* = {t_star:.12g} s",
        )
    ]
    if releases:
        te = releases[0].exit_time
        times = np.linspace(te, T, 50)
        z = np.array([s[0] for s in ex.sample(times).states])
        k = LIFT_RATE / MASS
        exact = k * ((times - t_star) ** 3 - (te - t_star) ** 3) / 6 - k * (te - t_star) ** 2 * (times - te) / 2
        err = float(np.max(np.abs(z - exact)))
        checks.append(Check("flight after release exact", err <= 1e-9, f"|z - cubic| <= {err:.2g} m"))
    lands = [tr for tr in ex.transitions if tr.name == "land"]
    span = (lands[0].exit_time, releases[0].time) if lands and releases else (0.0, 0.0)
    modes = set(ex.sample(np.linspace(span[0], span[1], 100, endpoint=False)).modes) if span[1] > span[0] else set()
    checks.append(Check("rests on the floor", modes == {"rest"}, f"mode rest on [{span[0]:.4g}, {span[1]:.4g}] s"))
    return checks


def _lift_off_check(ex: Execution, t_star: float, T: float) -> tuple[Check, float]:
    """Plain relaxed: the ball chatters on the floor until the lift nearly cancels its weight,
    then flies off along the exact cubic, shifted by the time d of its last impact from t* and
    started with that impact's rebound w: |z(T) - cubic| <= w (T - t*) + k (T - t*)^2 |d|/2.
    Returns the check and d (s)."""
    last_tr = ex.transitions[-1] if ex.transitions else None
    last = last_tr.exit_time if last_tr else 0.0
    w = abs(float(last_tr.state_after[1])) if last_tr else 0.0
    z_end = float(ex.final_state[0])
    k = LIFT_RATE / MASS
    exact_end = k * (T - t_star) ** 3 / 6
    lag = last - t_star
    allowed = w * (T - t_star) + k * (T - t_star) ** 2 * abs(lag) / 2 + 1e-9
    ok = abs(lag) <= 2 * (H + EPS) and abs(z_end - exact_end) <= allowed
    check = Check(
        "lifts off at t*",
        ok,
        f"last impact's strip exit {lag:+.2g} s from t* = {t_star:.6g} s (within 2 (h + eps)), "
        f"z(T) = {z_end:.6g} m vs the cubic's {exact_end:.6g} (allowed {allowed:.2g})",
    )
    return check, lag


@case(
    "resting_ball_c0",
    "resting",
    "ball, plastic floor (c = 0): rests, then a lift u = 3 t N releases it at t* = m g / 3",
)
def _resting_plastic(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.0, False)


@case(
    "resting_ball_c0.2",
    "resting",
    "ball, c = 0.2, plain relaxed: chatters on the floor until the lift exceeds its weight",
)
def _resting_chatter(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.2, False)


@case(
    "resting_ball_c0.2_continued",
    "resting",
    "ball, c = 0.2, default continuation: rests after the accumulation, released at t* exactly",
)
def _resting_continued(result: CaseResult, quick: bool) -> None:
    _resting(result, quick, 0.2, True)
