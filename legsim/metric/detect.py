"""Recognising coordinate guards and affine resets in plain model functions, by probing.

A guard of the form ``max_k s_k (x[i_k] - c_k)`` with distinct coordinates (coordinate
hyperplanes and their conjunctions) is found from its gradients at random points (one nonzero
component each), then made exact: slopes from secants over long steps where one term stays
active, constants snapped to 12 digits, and the candidate checked against the function at
fresh points. An affine reset is found from a central-difference Jacobian, snapped the same
way and checked at fresh points. Exactness matters: projections must land exactly on the
guard. Anything that does not fit, or that fails at a probed point, is "unknown shape" (None),
which the metric handles by local minimisation instead.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..derivatives import gradient, jacobian
from ..errors import ModelError
from .shapes import AffineReset, CoordinateGuard

#: Relative central-difference steps of the probes: small for guard gradients (only which
#: component is nonzero, and a first guess of it, is used), long for reset Jacobians (exact
#: for an affine reset whatever the step, and long steps keep rounding out of it).
GUARD_PROBE_STEP = 1e-6
RESET_PROBE_STEP = 1e-3


class _ProbeFailed(Exception):
    """The model function raised or returned a non-finite value at a probed point."""


def detect_coordinate_guard(guard: Callable, dim: int, center: np.ndarray) -> CoordinateGuard | None:
    """The guard as an exact ``CoordinateGuard`` (declared, or probed around ``center``, shape
    (dim,)), or None when it is not of that form."""
    declared = _declared_coordinate_guard(guard)
    if declared is not None:
        if max(t[0] for t in declared.terms) >= dim:
            raise ModelError(f"{declared!r} refers to coordinate beyond dimension {dim}")
        return declared
    rng = np.random.default_rng(12345)
    found = _probed_terms(guard, dim, center, rng)
    if not found:
        return None
    candidate = _refine_terms(guard, CoordinateGuard(*found), dim, center, rng)
    if candidate is None:
        return None
    for x in probe_points(dim, center, rng, 60):
        g = _safe_float(guard, x)
        if g is None or abs(candidate(x) - g) > 1e-9 * (1.0 + abs(g)):
            return None
    return candidate


def detect_affine_reset(
    reset: Callable | None, n_in: int, n_out: int, center: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A, r)`` with ``reset(x) = A @ x + r`` (A shape (n_out, n_in)), declared or probed
    around ``center``; the identity for no reset; None when the reset is not affine."""
    if reset is None:
        return np.eye(n_in), np.zeros(n_in)
    if isinstance(reset, AffineReset):
        return reset.matrix, reset.offset
    rng = np.random.default_rng(54321)
    x0 = center.copy() if center.shape == (n_in,) else np.zeros(n_in)
    try:
        with np.errstate(all="ignore"):
            r0 = np.asarray(reset(x0), dtype=float)
            A = jacobian(reset, x0, step=RESET_PROBE_STEP, scale=1.0 + float(np.max(np.abs(x0))))
            r = r0 - A @ x0
            if A.shape != (n_out, n_in) or not (np.all(np.isfinite(A)) and np.all(np.isfinite(r))):
                return None
            for x in probe_points(n_in, x0, rng, 24):
                y = np.asarray(reset(x), dtype=float)
                if y.shape != (n_out,) or not np.all(np.isfinite(y)):
                    return None
                if np.max(np.abs(A @ x + r - y)) > 1e-8 * (1.0 + np.max(np.abs(y)) + np.max(np.abs(x))):
                    return None
    except Exception:  # a reset failing at a probe is simply not recognised
        return None
    snap_all = np.vectorize(snap, otypes=[float])
    return snap_all(A), snap_all(r)


def probe_points(dim: int, center: np.ndarray, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` random points, shape (count, dim), at three scales alternately around
    ``center`` and around the origin, so that conjunction terms active only far from the query
    point (the far side of a stop) are met too."""
    scale = 1.0 + float(np.max(np.abs(center))) if center.size else 1.0
    out = []
    for k in range(count):
        c = center if k % 2 == 0 else np.zeros(dim)
        s = scale * (0.1, 1.0, 10.0)[k % 3]
        out.append(c + s * rng.standard_normal(dim))
    return np.array(out)


def snap(value: float) -> float:
    """Round a probed constant to 12 significant digits when that changes it by rounding error
    only, so that 0.9 or 14 come out exact (the probes see them to about 1e-13)."""
    rounded = float(f"{value:.12g}")
    return rounded if abs(rounded - value) <= 1e-11 * (1.0 + abs(value)) else value


def _declared_coordinate_guard(guard: Callable) -> CoordinateGuard | None:
    if isinstance(guard, CoordinateGuard):
        return guard
    terms = getattr(guard, "coordinate_terms", None)
    return None if terms is None else CoordinateGuard(*terms)


def _safe_float(fn: Callable, x: np.ndarray) -> float | None:
    try:
        with np.errstate(all="ignore"):
            v = float(np.asarray(fn(x), dtype=float).reshape(()))
    except Exception:  # any failure of the model function means "no value here"
        return None
    return v if math.isfinite(v) else None


def _probe_gradient(guard: Callable, x: np.ndarray) -> np.ndarray | None:
    def value(p: np.ndarray) -> float:
        v = _safe_float(guard, p)
        if v is None:
            raise _ProbeFailed
        return v

    try:
        return gradient(value, x, step=GUARD_PROBE_STEP, scale=1.0 + float(np.max(np.abs(x))))
    except _ProbeFailed:
        return None


def _probed_terms(
    guard: Callable, dim: int, center: np.ndarray, rng: np.random.Generator
) -> list[tuple[int, float, float]] | None:
    """First guesses of the terms (index, scale, value), one per probe whose gradient has a
    single nonzero component; None when the probes contradict a coordinate guard."""
    found: list[tuple[int, float, float]] = []
    mixed = 0
    for x in probe_points(dim, center, rng, 30):
        g = _safe_float(guard, x)
        if g is None:
            return None
        grad = _probe_gradient(guard, x)
        if grad is None:
            return None
        big = np.abs(grad) > 1e-7 * max(1.0, float(np.max(np.abs(grad))))
        if np.count_nonzero(big) != 1:
            mixed += 1  # a kink between the two probes, or not a coordinate guard at all
            if mixed > 3:
                return None
            continue
        i = int(np.argmax(big))
        s = float(grad[i])
        if not _merge_term(found, (i, s, float(x[i] - g / s))):
            return None
    return found


def _merge_term(found: list[tuple[int, float, float]], term: tuple[int, float, float]) -> bool:
    """Add a probed term unless already known; False when it contradicts a known one (the same
    coordinate with a different slope or offset, or with the opposite sign)."""
    i, s, c = term
    for j, s2, c2 in found:
        if j == i and math.copysign(1.0, s2) == math.copysign(1.0, s):
            return abs(s2 - s) <= 1e-5 * abs(s) and abs(c2 - c) <= 1e-5 * (1.0 + abs(c))
    if any(j == i for j, _, _ in found):
        return False
    found.append(term)
    return True


def _refine_terms(
    guard: Callable, candidate: CoordinateGuard, dim: int, center: np.ndarray, rng: np.random.Generator
) -> CoordinateGuard | None:
    """Exact slopes from secants over long steps where one term stays active (the guard is
    affine there), then the offset from one value: finite differences alone give 1e-10."""
    terms = []
    points = probe_points(dim, center, rng, 60)
    for k, (i, s, c) in enumerate(candidate.terms):
        for x in points:
            values = [s2 * (x[j] - c2) for j, s2, c2 in candidate.terms]
            others = max((v for m, v in enumerate(values) if m != k), default=-math.inf)
            margin = values[k] - others
            if margin <= 0.0:
                continue
            delta = min(0.25 * margin / abs(s), 1e-2 * (1.0 + abs(float(x[i]))))
            e = np.zeros(dim)
            e[i] = delta
            gp, g0, gm = _safe_float(guard, x + e), _safe_float(guard, x), _safe_float(guard, x - e)
            if gp is None or g0 is None or gm is None:
                return None
            s_exact = snap((gp - gm) / (2 * delta))
            if s_exact == 0.0:
                return None
            terms.append((i, s_exact, snap(float(x[i]) - g0 / s_exact)))
            break
        else:
            terms.append((i, snap(s), snap(c)))
    return CoordinateGuard(*terms)
