"""The pieces of a return map where more than two event orders meet at an orbit, found by
sampling, and a verdict on them.

``piecewise.pieces_at_orbit`` reads two pieces off the difference stencil: it works where two
orders meet on one hyperplane. At a gait where several pairs of events are simultaneous (a pronk
in place: which foot lands first, which slips first, which lifts off first) several boundaries
cross at the orbit and a coordinate's stencil sees only some of the regions between them. Each
region is still a cone on which the return map's Bouligand derivative is one linear map
(Burden, Revzen, Sastry and Koditschek, SIAM J. Appl. Dyn. Syst. 2016), and the pieces are
found from the map itself:

1. **Regions.** ``SAMPLES`` random perturbations within the stencil's scale (each coordinate up
   to its difference step d_j), each return's event order naming its region.
2. **A point inside each region.** The mean of a region's sampled directions lies inside it (a
   cone is convex); the map is evaluated there to confirm its order.
3. **Each piece.** The central-difference Jacobian at that point, with steps ``INNER`` d_j small
   against its distance to the region's boundaries: every evaluation of the stencil must take the
   region's order, else the piece is not resolved.
4. **A check.** ``CHECKS`` fresh perturbations: each must fall in a region already found, and its
   return must be the region's piece applied to it (to ``PREDICTION_TOL`` of its size). A region
   or a piece the samples missed fails this check and leaves the verdict unresolved.

The verdict is one of two sufficient conditions, without modelling the regions' boundaries:

* **stable**: one quadratic norm in which every piece contracts (a common quadratic Lyapunov
  function, ``piecewise.contraction``): whatever regions a perturbation visits, it shrinks by that
  factor at every return. Ignoring the regions only makes the test stricter.
* **unstable**: a piece with a real multiplier > 1 whose eigenvector (or its negative) lies in
  the piece's own region (its return takes the region's order and grows by the multiplier): that
  ray grows without leaving its region.
* **unresolved** otherwise, saying which failed.

A cone thinner than about one in ``SAMPLES + CHECKS`` of the directions can go unseen by both
the samples and the check; the verdict's details give the number of samples in each region, so
a region seen only a few times shows how thin the sampling was.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .piecewise import Verdict, contraction

#: Random perturbations that find the regions, and the fresh ones that check the pieces.
SAMPLES = 48
CHECKS = 16
#: A piece's difference steps, as a share of the sampling scale (d_j): the point inside the
#: region lies at about that scale from the orbit, so its stencil stays inside the region.
INNER = (1e-2, 1e-3)
#: A checked perturbation's return may differ from its piece's prediction by this share of its
#: size (the pieces' differences carry O(d) curvature and the map's noise over d).
PREDICTION_TOL = 0.05
#: A piece's eigenvalue counts as real when its imaginary part is below this.
REAL_TOL = 1e-9

#: z (augmented state, shape (N,)) -> (the augmented return, shape (N,); its event order).
Evaluate = Callable[[np.ndarray], tuple[np.ndarray, tuple[str, ...]]]


@dataclass(frozen=True)
class SampledPiece:
    """One region's piece: its event ``order`` and the Jacobian ``A`` (N, N) of the augmented
    map there."""

    order: tuple[str, ...]
    A: np.ndarray


class PieceSampler:
    """The return map's pieces around an orbit ``start`` (augmented, (N,)) whose base return is
    ``base`` (N,), perturbing ``columns`` by up to ``steps`` (N,) each; ``central`` (N, N) the
    orbit's central-difference Jacobian, whose other columns (cyclic, held) every piece shares;
    ``seed`` the random perturbations', ``samples`` and ``checks`` how many find the regions and
    check the pieces."""

    def __init__(
        self,
        evaluate: Evaluate,
        start: np.ndarray,
        base: np.ndarray,
        columns: Sequence[int],
        steps: np.ndarray,
        central: np.ndarray,
        seed: int = 0,
        samples: int = SAMPLES,
        checks: int = CHECKS,
    ) -> None:
        self.evaluate = evaluate
        self.start, self.base = start, base
        self.columns = list(columns)
        self.steps = steps
        self.central = central
        self.rng = np.random.default_rng(seed)
        self.samples, self.checks = samples, checks

    def direction(self) -> np.ndarray:
        """A random perturbation (N,): each column up to its step, the largest exactly."""
        r = self.rng.standard_normal(len(self.columns))
        out = np.zeros_like(self.start)
        out[self.columns] = self.steps[self.columns] * r / np.max(np.abs(r))
        return out

    def regions(self) -> dict[tuple[str, ...], list[np.ndarray]]:
        """``samples`` random perturbations (N,) by the event order of their returns."""
        found: dict[tuple[str, ...], list[np.ndarray]] = {}
        for _ in range(self.samples):
            delta = self.direction()
            found.setdefault(self.evaluate(self.start + delta)[1], []).append(delta)
        return found

    def piece(self, order: tuple[str, ...], deltas: list[np.ndarray]) -> SampledPiece | str:
        """The piece of the region of ``order`` from its sampled perturbations, or why not."""
        # each sample reaches the box of the steps (``direction``); their mean is scaled back to it
        inside = np.mean(deltas, axis=0)
        inside /= np.max(np.abs(inside[self.columns] / self.steps[self.columns]))
        point = self.start + inside
        if self.evaluate(point)[1] != order:
            return f"the mean of the region's {len(deltas)} samples lies outside it"
        for share in INNER:
            A = self._jacobian(point, order, share)
            if A is not None:
                return SampledPiece(order, A)
        return (
            f"its difference stencils (steps {INNER[-1]:g} of the sampling scale) leave the region "
            f"({len(deltas)} samples): it is too thin to difference"
        )

    def _jacobian(self, point: np.ndarray, order: tuple[str, ...], share: float) -> np.ndarray | None:
        """Central differences at ``point`` with steps ``share`` d_j, None when an evaluation
        leaves the region of ``order``."""
        A = self.central.copy()
        for j in self.columns:
            d = share * self.steps[j]
            sides = []
            for sign in (1.0, -1.0):
                z = point.copy()
                z[j] += sign * d
                end, at = self.evaluate(z)
                if at != order:
                    return None
                sides.append(end)
            A[:, j] = (sides[0] - sides[1]) / (2 * d)
        return A

    def check(self, pieces: dict[tuple[str, ...], SampledPiece]) -> str | None:
        """None when ``checks`` fresh perturbations each fall in a found region and return as
        its piece predicts; else what failed."""
        for _ in range(self.checks):
            delta = self.direction()
            end, order = self.evaluate(self.start + delta)
            piece = pieces.get(order)
            if piece is None:
                return f"a fresh perturbation took an event order no sample had ({', '.join(order)})"
            moved, predicted = end - self.base, piece.A @ delta
            if np.max(np.abs(moved - predicted)) > PREDICTION_TOL * np.max(np.abs(moved)):
                return (
                    f"a fresh perturbation's return differs from its piece's prediction by "
                    f"{np.max(np.abs(moved - predicted)):.3g} (its size {np.max(np.abs(moved)):.3g})"
                )
        return None

    def growing_ray(self, piece: SampledPiece) -> float | None:
        """The piece's real multiplier > 1 whose eigenvector's ray stays in the region: from the
        orbit along it (or its negative) the return takes the region's order and grows by the
        multiplier (to ``PREDICTION_TOL``); None if there is none."""
        values, vectors = np.linalg.eig(piece.A)
        for value, vector in zip(values, vectors.T, strict=True):
            if abs(value.imag) > REAL_TOL or value.real <= 1.0 + PREDICTION_TOL:
                continue
            for sign in (1.0, -1.0):
                ray = sign * vector.real
                scale = np.max(np.abs(ray[self.columns] / self.steps[self.columns]))
                if scale == 0.0:
                    continue
                delta = ray / scale
                end, order = self.evaluate(self.start + delta)
                grown = end - self.base
                off = np.max(np.abs(grown - value.real * delta))
                if order == piece.order and off <= PREDICTION_TOL * np.max(np.abs(grown)):
                    return float(value.real)
        return None


def sampled_verdict(sampler: PieceSampler, project: Callable[[list[np.ndarray]], list[np.ndarray] | str]) -> Verdict:
    """The verdict on the pieces ``sampler`` finds (module docstring). ``project`` maps the
    pieces' augmented matrices onto the section without the trivial multipliers (or says why it
    cannot)."""
    regions = sampler.regions()
    pieces: dict[tuple[str, ...], SampledPiece] = {}
    for order, deltas in regions.items():
        found = sampler.piece(order, deltas)
        if isinstance(found, str):
            return Verdict("unresolved", f"the region of the order ({', '.join(order)}): {found}", {})
        pieces[order] = found
    counts = {"; ".join(order): len(deltas) for order, deltas in regions.items()}
    failed = sampler.check(pieces)
    if failed is not None:
        return Verdict("unresolved", f"the {len(pieces)} sampled pieces do not hold: {failed}", {"samples": counts})
    matrices = project([p.A for p in pieces.values()])
    if isinstance(matrices, str):
        return Verdict("unresolved", matrices, {"samples": counts})
    details: dict[str, object] = {
        "samples": counts,
        "piece_radii": [float(np.max(np.abs(np.linalg.eigvals(M)))) if M.size else 0.0 for M in matrices],
    }
    factor, L = contraction(matrices)
    if factor < 1.0:
        details.update({"length": 1, "factor": factor, "P": (L.T @ L).tolist()})
        return Verdict(
            "stable",
            f"all {len(pieces)} pieces (one per event order, {sum(counts.values())} sampled perturbations) contract "
            f"every perturbation by at least {factor:.6g} in one quadratic norm, whatever regions it visits",
            details,
        )
    for piece in pieces.values():
        grows = sampler.growing_ray(piece)
        if grows is not None:
            details.update({"sequence": ["; ".join(piece.order)], "growth": grows})
            return Verdict(
                "unstable",
                f"the piece of the order ({', '.join(piece.order)}) has a multiplier {grows:.6g} whose ray stays in "
                f"its own region",
                details,
            )
    return Verdict(
        "unresolved",
        f"no quadratic norm found in which all {len(pieces)} pieces contract (best {factor:.6g}), and no piece "
        f"has a growing ray inside its own region",
        details,
    )
