"""The numerical minimisers behind the distance: SLSQP (smooth problems, with constraints),
golden section (a convex function of one variable), and a log-barrier interior-point method
for a sum of norms of affine maps over a box (convex, with kinks where a norm vanishes)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize


def slsqp(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray]],
    z0: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    constraints: list,
    ftol: float,
    maxiter: int = 200,
    converged: list | None = None,
) -> np.ndarray | None:
    """SLSQP from ``z0`` on ``fun`` (value and gradient) within the bounds ``lb <= z <= ub``
    (infinite entries: unbounded) and scipy-style ``constraints``.

    Returns the final point (shape like z0), or None when it is not finite or a model function
    failed during the search. Appends SLSQP's own success flag to ``converged`` if given.
    """
    bounds = [
        (None if not math.isfinite(lo) else lo, None if not math.isfinite(hi) else hi)
        for lo, hi in zip(lb, ub, strict=True)
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            try:
                res = minimize(
                    fun,
                    z0,
                    jac=True,
                    method="SLSQP",
                    bounds=bounds,
                    constraints=constraints,
                    options={"ftol": ftol, "maxiter": maxiter},
                )
            except Exception:  # a model function failed at a probed point (e.g.
                # a robot whose guard refuses states where the body is below ground): this
                # start yields no path, the others still may.
                return None
    z = np.asarray(res.x, dtype=float)
    if converged is not None:
        converged.append(bool(res.success))
    return z if np.all(np.isfinite(z)) else None


def golden_convex(f: Callable[[float], float], z0: float, f0: float, lo: float, hi: float, tol: float) -> float:
    """Minimise a convex function of one variable on [lo, hi] from z0 with f(z0) = f0.

    The bracket grows from z0 until f rises on each side (by convexity the minimiser is then
    inside), then golden-section search shrinks it to ``tol``: robust at kinks, where the
    minimiser of a sum of norms often sits and where quasi-Newton methods crawl.
    """
    a, b = (_bracket_end(f, z0, f0, direction, limit) for direction, limit in ((-1.0, lo), (1.0, hi)))
    invphi = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - invphi * (b - a), a + invphi * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - invphi * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + invphi * (b - a)
            fd = f(d)
    return c if fc <= fd else d


def _bracket_end(f: Callable[[float], float], z0: float, f0: float, direction: float, limit: float) -> float:
    """Step from z0 towards ``limit`` with growing steps until f exceeds f0 or the limit is met."""
    step = max(1.0, abs(z0), f0)
    end = z0
    while (end - limit) * direction < 0.0:
        end = z0 + direction * step
        end = max(end, limit) if direction < 0 else min(end, limit)
        if end == limit or f(end) > f0 or step > 1e12 * max(1.0, abs(z0), f0):
            break
        step *= 4.0
    return end


def sum_of_norms(
    legs: list[tuple[np.ndarray, np.ndarray]], z0: np.ndarray, lb: np.ndarray, ub: np.ndarray, scale: float
) -> np.ndarray:
    """Minimise sum_k |M_k z - c_k| over the box lb <= z <= ub (convex): a primal log-barrier
    method on the second-order-cone form, minimise sum_k t_k subject to t_k >= |M_k z - c_k|.

    ``legs`` holds the pairs (M_k, c_k), M_k of shape (n_k, q); z0, lb, ub have shape (q,);
    ``scale`` is the size of the problem's coordinates. The barrier
    -log(t_k^2 - |r_k|^2) - log(z - lb) - log(ub - z) keeps the iterates inside, where
    everything is smooth, so legs that shrink to zero length at the minimum (kinks of the sum of
    norms, on which SLSQP stalls short of the minimum) need no special care. Stops when the
    duality gap, (2 K + number of finite bounds) / weight, is below 1e-11 * scale.
    """
    barrier = _ConeBarrier(legs, lb, ub)
    z, t = barrier.start(z0, scale)
    weight = barrier.degree / float(t.sum())
    with np.errstate(all="ignore"):
        while True:
            z, t = barrier.centre(z, t, weight)
            if barrier.degree / weight <= 1e-11 * scale:
                break
            weight *= 50.0
    return np.clip(z, lb, ub)


class _ConeBarrier:
    """weight * sum_k t_k plus the log-barrier of the cones t_k >= |M_k z - c_k| and the box,
    over the unknowns (z, t) (shapes (q,) and (K,))."""

    def __init__(self, legs: list[tuple[np.ndarray, np.ndarray]], lb: np.ndarray, ub: np.ndarray) -> None:
        self.M = np.vstack([m for m, _ in legs])
        self.c = np.concatenate([cc for _, cc in legs])
        sizes = np.array([len(cc) for _, cc in legs])
        self.starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])  # first row of each leg
        self.row_leg = np.repeat(np.arange(len(legs)), sizes)
        self.q, self.K = self.M.shape[1], len(legs)
        self.lb, self.ub = lb, ub
        self.has_lb, self.has_ub = np.isfinite(lb), np.isfinite(ub)
        self.lbz, self.ubz = np.where(self.has_lb, lb, 0.0), np.where(self.has_ub, ub, 0.0)
        self.degree = 2 * self.K + int(self.has_lb.sum()) + int(self.has_ub.sum())

    def start(self, z0: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
        """A strictly feasible start near z0: moved inside the box, each t_k above its norm."""
        width = np.where(self.has_lb & self.has_ub, self.ub - self.lb, np.inf)
        inset = np.minimum(1e-3 * scale, 0.25 * width)
        z = np.clip(z0, np.where(self.has_lb, self.lb + inset, -np.inf), np.where(self.has_ub, self.ub - inset, np.inf))
        r = self.M @ z - self.c
        return z, np.sqrt(np.add.reduceat(r * r, self.starts)) + 1e-2 * scale

    def value(self, z: np.ndarray, t: np.ndarray, weight: float) -> float:
        """The barrier function; inf outside its domain."""
        if t.min() <= 0.0:  # t^2 > |r|^2 holds on the negative nappe of the cone too
            return math.inf
        r = self.M @ z - self.c
        s = t * t - np.add.reduceat(r * r, self.starts)
        if s.min() <= 0.0:
            return math.inf
        dl, du = (z - self.lbz)[self.has_lb], (self.ubz - z)[self.has_ub]
        if (dl.size and dl.min() <= 0.0) or (du.size and du.min() <= 0.0):
            return math.inf
        return weight * float(t.sum()) - float(np.log(s).sum() + np.log(dl).sum() + np.log(du).sum())

    def centre(self, z: np.ndarray, t: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray]:
        """Damped Newton steps (backtracking, at most 30) towards the minimiser for ``weight``."""
        q = self.q
        f = self.value(z, t, weight)
        for _ in range(30):
            step, decrement = self._newton_step(z, t, weight)
            if not decrement > 1e-8:  # centred (the gap bound needs no more)
                break
            alpha = 1.0
            while alpha > 1e-12:
                f_new = self.value(z + alpha * step[:q], t + alpha * step[q:], weight)
                if f_new <= f - 0.25 * alpha * decrement:
                    break
                alpha *= 0.5
            else:
                break
            z, t, f = z + alpha * step[:q], t + alpha * step[q:], f_new
        return z, t

    def _newton_step(self, z: np.ndarray, t: np.ndarray, weight: float) -> tuple[np.ndarray, float]:
        """The Newton step of the barrier at (z, t), shape (q + K,), and its decrement."""
        g, H = self._gradient_and_hessian(z, t, weight)
        n = len(g)
        # A walk can have a flat direction (a reset that forgets a coordinate): damp it, or the
        # iterates drift along it to where rounding eats the digits.
        H[np.arange(n), np.arange(n)] += 1e-12 * float(np.max(np.abs(np.diag(H))))
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            step = -g
        return step, -float(g @ step)

    def _gradient_and_hessian(self, z: np.ndarray, t: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray]:
        M, q = self.M, self.q
        n = q + self.K
        r = M @ z - self.c
        s = t * t - np.add.reduceat(r * r, self.starts)
        a = np.add.reduceat(M * r[:, None], self.starts)  # row k: M_k^T r_k
        inv_s = 1.0 / s
        inv_s2 = inv_s * inv_s
        g = np.empty(n)
        H = np.empty((n, n))
        g[:q] = 2.0 * (a.T @ inv_s)
        g[q:] = weight - 2.0 * t * inv_s
        H[:q, :q] = 4.0 * (a.T * inv_s2) @ a + 2.0 * (M.T * inv_s[self.row_leg]) @ M
        H[:q, q:] = -4.0 * a.T * (t * inv_s2)
        H[q:, :q] = H[:q, q:].T
        H[q:, q:] = np.diag(4.0 * t * t * inv_s2 - 2.0 * inv_s)
        diag = np.arange(q)
        if self.has_lb.any():
            dl = np.where(self.has_lb, z - self.lbz, 1.0)
            g[:q] -= np.where(self.has_lb, 1.0 / dl, 0.0)
            H[diag, diag] += np.where(self.has_lb, 1.0 / (dl * dl), 0.0)
        if self.has_ub.any():
            du = np.where(self.has_ub, self.ubz - z, 1.0)
            g[:q] += np.where(self.has_ub, 1.0 / du, 0.0)
            H[diag, diag] += np.where(self.has_ub, 1.0 / (du * du), 0.0)
        return g, H
