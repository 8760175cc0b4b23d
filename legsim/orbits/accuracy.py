"""How well the return map is resolved at its settings: the floor under an orbit search's residual.

A return map computed by the relaxed integrator is not the hybrid system's: at a state x it is
off by the discretization error (O(h^p) and O(eps) per transition), and as a function of x it
carries noise: rounding, the step that lands in a strip changing with x, and at a symmetric gait
the order of simultaneous events decided by rounding (a jump of O(eps) in the map). Newton's
method can drive the residual of the orbit equations down to that noise and no further; a
residual above it is a point the map itself says is not periodic. Two numbers, both measured at
the search's last point z (``estimate_accuracy``):

* **noise**: the scatter of the orbit equations F under tiny perturbations, from second
  differences ``|F(z + d) + F(z - d) - 2 F(z)| / 2`` along ``NOISE_DIRECTIONS`` fixed
  pseudo-random directions d with ``|d_i| = NOISE_STEP (1 + |z_i|)``. A smooth map's second
  difference is ``d^T F'' d`` ~ 1e-22 |F''| at that step and a kink's at z is (slope jump) |d|
  ~ 1e-11 (1 + |z|) |jump|: what is left is the noise (rounding, and the integrator's discrete
  choices where they change within the probe), and a jump of the map at z. Probes this small
  rarely cross the places where the integrator's choices change, so the estimate is the noise
  at the point, not over the distance Newton's steps cover: where a Newton step fails to lower a
  residual within tol, the noise is measured again with probes the size of that step
  (``legsim.orbits.newton``).
* **refinement**: the max-norm change of F at z when the map is computed at h/2 and eps/2 (and
  rtol, atol / 16 when the steps are error-controlled): the residual a finer integrator would
  report at the same point, a measure of how far the computed map's orbit is from the hybrid
  system's.

The residual the map resolves is ``RESOLVED_FACTOR`` times the noise, and at least the rounding
floor ``ROUNDING * (1 + max |z|)`` (a map reproducible to the last bit still has rounding in
its equations). ``find_orbit`` reports "converged" only at a residual <= tol that is also <= that
level: a point within a loose tol but above what the map resolves is refined further, and
reported as ``stalled`` when Newton's method cannot lower it (``legsim.orbits.newton``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .errors import OrbitError
from .problem import OrbitProblem

#: Pseudo-random directions of the noise estimate (2 returns each).
NOISE_DIRECTIONS = 2
#: Relative size of each component of a noise-probing perturbation: small enough that a
#: smooth map's second difference (~ step^2 |F''|) and a kink's (~ step |slope jump|) stay below
#: the tolerances a search is given (1e-9 for slope jumps up to 10 or so), large enough to move
#: every coordinate by 1e5 roundings.
NOISE_STEP = 1e-11
#: The residual the map resolves, in units of its measured noise: a second difference of
#: independent noise is up to 4 times one evaluation's, and the estimate sees 2 directions.
RESOLVED_FACTOR = 10.0
#: Relative rounding level below which no residual is asked of the map, whatever its noise.
ROUNDING = 1e-13
#: Refined settings' step and strip divisor, and tolerance divisor (error-controlled steps).
REFINE_STEP = 2.0
REFINE_TOLERANCE = 16.0


@dataclass
class MapAccuracy:
    """The return map's resolution at a point (module docstring).

    noise: scatter of the orbit equations under tiny perturbations (max-norm, state units).
    resolved: the residual the map resolves, max(RESOLVED_FACTOR * noise, rounding floor).
    refinement: max-norm change of the orbit equations at the point at the refined settings
        (``refined``, in words); None when the refined map could not be evaluated (``note``).
    """

    noise: float
    resolved: float
    refinement: float | None
    refined: str
    noisiest: str = ""
    note: str = ""
    probe: str = f"{NOISE_STEP:g} (relative)"

    def describe(self) -> str:
        """The noise in words: its size, the probe step and the equation it is largest in."""
        where = f" (largest in the row of {self.noisiest})" if self.noisiest else ""
        if math.isnan(self.noise):  # no probe returned: the notes say why
            text = f"perturbations of {self.probe} measured no noise"
        else:
            text = f"perturbations of {self.probe} change the orbit equations by up to {self.noise:.3g}{where}"
        return text + (f"; {self.note}" if self.note else "")

    def warnings(self, tol: float) -> list[str]:
        """What a converged search says about the map's resolution: a tol tighter than the map
        resolves, and a refined map that moves the residual beyond tol."""
        out = []
        if tol < self.resolved < math.inf:
            out.append(
                f"tol {tol:g} is tighter than the return map resolves here ({self.resolved:.3g}: {self.describe()}): "
                f"the residual's value below that is not resolved, and the fixed point is known to about the noise"
            )
        if self.refinement is not None and self.refinement > tol:
            out.append(
                f"at finer settings ({self.refined}) the orbit equations at this point change by {self.refinement:.3g} "
                f"> tol {tol:g}: the orbit found is the return map's at these settings, and the hybrid system's "
                f"may lie that far from it (refine h and eps)"
            )
        return out

    def to_json(self) -> dict[str, Any]:
        return {
            "noise": _finite(self.noise),
            "resolved": _finite(self.resolved),
            "refinement": _finite(self.refinement),
            "refined": self.refined,
            "noisiest": self.noisiest,
            "note": self.note,
            "probe": self.probe,
        }


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def probe_directions(z: np.ndarray, scale: np.ndarray | None = None) -> list[np.ndarray]:
    """The noise estimate's perturbations, shape (len(z),) each: fixed pseudo-random signs and
    sizes in [0.5, 1] of ``scale`` (default ``NOISE_STEP (1 + |z_i|)``; the same at every call,
    so a search's report is reproducible)."""
    rng = np.random.default_rng(20261128)
    scale = NOISE_STEP * (1.0 + np.abs(z)) if scale is None else np.asarray(scale, dtype=float)
    return [
        scale * rng.choice((-1.0, 1.0), size=z.size) * rng.uniform(0.5, 1.0, size=z.size)
        for _ in range(NOISE_DIRECTIONS)
    ]


def refined_problem(problem: OrbitProblem) -> tuple[OrbitProblem, str]:
    """The problem at the refined settings (h and eps halved; rtol and atol / 16 when set), and
    those settings in words."""
    changes: dict[str, Any] = {"h": problem.h / REFINE_STEP, "eps": problem.eps / REFINE_STEP}
    words = [f"h = {changes['h']:g} s", f"eps = {changes['eps']:g}"]
    for name in ("rtol", "atol"):
        value = getattr(problem, name)
        if value is not None:
            changes[name] = value / REFINE_TOLERANCE
            words.append(f"{name} = {changes[name]:g}")
    return replace(problem, **changes), ", ".join(words)


def estimate_accuracy(
    z: np.ndarray,
    F: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    evaluate_refined: Callable[[np.ndarray], np.ndarray] | None,
    refined: str,
    row_names: Sequence[str] = (),
    scale: np.ndarray | None = None,
) -> MapAccuracy:
    """The map's noise and refinement at the unknowns z (module docstring).

    z: the unknowns, shape (k,); F: the orbit equations there, shape (r,); evaluate(z') -> F(z')
    at the search's settings; evaluate_refined(z) -> F(z) at the refined settings (None: not
    estimated); row_names: what each row of F is (for the message). Either raises
    ``OrbitError`` when the map has no return there; a failed probe counts as infinite noise
    (the map is not even defined next to z)."""
    noise, noisiest, notes, probed = 0.0, "", [], 0
    for d in probe_directions(z, scale):
        try:
            second = 0.5 * np.abs(evaluate(z + d) + evaluate(z - d) - 2.0 * F)
        except OrbitError as exc:
            # A map undefined on one side (a model that refuses those states) has no noise
            # there to measure.
            notes.append(f"a probe of {float(np.max(np.abs(d))):.2g} has no return ({exc.status})")
            continue
        probed += 1
        if second.size and float(np.max(second)) > noise:
            noise = float(np.max(second))
            row = int(np.argmax(second))
            noisiest = row_names[row] if row < len(row_names) else f"row {row}"
    floor = ROUNDING * (1.0 + float(np.max(np.abs(z), initial=0.0)))
    if not probed:
        notes.append("the noise is not known: the tolerance is taken as resolved")
        noise, floor = math.nan, math.inf
    refinement = None
    if evaluate_refined is not None:
        try:
            refinement = float(np.max(np.abs(evaluate_refined(z) - F), initial=0.0))
        except OrbitError as exc:
            notes.append(f"the refined map ({refined}) has no return ({exc.status})")
    resolved = floor if math.isnan(noise) else max(RESOLVED_FACTOR * noise, floor)
    probe = f"{NOISE_STEP:g} (relative)" if scale is None else f"up to {float(np.max(np.abs(scale))):.3g}"
    return MapAccuracy(noise, resolved, refinement, refined, noisiest, "; ".join(notes), probe)
