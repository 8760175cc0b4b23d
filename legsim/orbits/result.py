"""What an orbit search reports: its end (``STATUSES``) and the ``OrbitResult``."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .accuracy import MapAccuracy
from .errors import OrbitError
from .piecewise import Verdict

#: Ends of an orbit search.
STATUSES = (
    "converged",
    "no_return",
    "simulation_failed",
    "singular_jacobian",
    "diverged",
    "stalled",
    "max_iterations",
    "map_unresolved",
)


@dataclass
class OrbitResult:
    """The outcome of an orbit search.

    Attributes
    ----------
    status: one of ``STATUSES``; converged: status == "converged"; message: why it stopped.
    mode, state_names: the section's mode and coordinates.
    fixed_point: the last iterate, shape (n,) (the orbit's state on the section when converged).
    parameters: all parameter values, free ones solved.
    period: flow time of one return (s), strips excluded; return_time: relaxed return time (s).
    step_length: the distance covered in one period (m), when defined.
    multipliers: Floquet multipliers (complex, by decreasing modulus), shape (n - 1 - #cyclic,).
    stable: True when every multiplier but the trivial ones has modulus < 1; None when there are
        no multipliers or the return map is not differentiable at the orbit (``differentiable``).
    differentiable: with the finite-difference Jacobian, whether each column's forward and
        backward differences agree (``legsim.orbits.kinks``); None when not checked (saltation
        Jacobian) or when some column could not be (a simulation of its stencil failed; a
        warning names it). When False, ``kinked_coordinates`` names the columns that disagree,
        ``multipliers_forward`` and ``multipliers_backward`` are those of the forward- and
        backward-difference Jacobians (the spread the central ``multipliers`` cannot vouch
        for), and ``warnings`` says so.
    jacobian: the full return-map Jacobian at the fixed point (n, n); section_jacobian: its
        restriction M to the section.
    residual: max-norm of the orbit equations at fixed_point; iterations: Newton iterations.
    history: residual max-norm after each iteration.
    piecewise: where the map is not differentiable, the stability verdict of its piecewise-linear
        derivative (``legsim.orbits.piecewise``), which ``stable`` then reports.
    map_accuracy: what the return map resolves at the first iterate within tol (noise,
        resolved residual, change at refined settings; ``legsim.orbits.accuracy``), or at the
        last iterate of a search that no Newton step advanced (``map_unresolved`` when it
        explains the residual, ``diverged`` when not); None otherwise.
    transitions: names of the transitions of one period.
    evaluations: simulations run.
    memory, memory_names, memory_units: the controller's memory on the orbit (its value at the
        section), shape (m,), with names and units (empty without a controller). The
        multipliers are then those of the augmented map on (x, memory): n - 1 - #cyclic + m of
        them, the state's directions and the controller's together.
    """

    status: str
    message: str
    mode: str
    state_names: tuple[str, ...]
    fixed_point: np.ndarray
    parameters: dict[str, float]
    residual: float
    iterations: int
    history: list[float]
    period: float | None = None
    return_time: float | None = None
    step_length: float | None = None
    multipliers: np.ndarray | None = None
    trivial_multipliers: int = 0
    jacobian: np.ndarray | None = None
    section_jacobian: np.ndarray | None = None
    transitions: list[str] = field(default_factory=list)
    evaluations: int = 0
    jacobian_method: str = "saltation"
    section: str = ""
    free: tuple[str, ...] = ()
    memory: np.ndarray = field(default_factory=lambda: np.empty(0))
    memory_names: tuple[str, ...] = ()
    memory_units: tuple[str, ...] = ()
    differentiable: bool | None = None
    kinked_coordinates: tuple[str, ...] = ()
    multipliers_forward: np.ndarray | None = None
    multipliers_backward: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    map_accuracy: MapAccuracy | None = None
    piecewise: Verdict | None = None

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    @property
    def spectral_radius(self) -> float | None:
        """Largest modulus of the non-trivial multipliers."""
        mu = self.nontrivial_multipliers
        if mu is None:
            return None
        return float(np.max(np.abs(mu))) if mu.size else 0.0

    @property
    def nontrivial_multipliers(self) -> np.ndarray | None:
        """The multipliers without the ``trivial_multipliers`` closest to 1."""
        if self.multipliers is None:
            return None
        mu = self.multipliers
        if self.trivial_multipliers <= 0:
            return mu
        drop = set(np.argsort(np.abs(mu - 1.0))[: self.trivial_multipliers].tolist())
        return np.array([m for i, m in enumerate(mu) if i not in drop], dtype=complex)

    @property
    def stable(self) -> bool | None:
        """From the multipliers; where the map is not differentiable, the piecewise-linear
        verdict's (None when unresolved)."""
        if self.differentiable is False:
            return None if self.piecewise is None else self.piecewise.stable
        rho = self.spectral_radius
        return None if rho is None else rho < 1.0

    def raise_for_status(self) -> OrbitResult:
        """Raise ``OrbitError`` with the message unless the search converged."""
        if not self.converged:
            raise OrbitError(f"orbit search {self.status}: {self.message}", self.status)
        return self

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict (the keys of ``legsim orbit --json``); non-finite numbers become None."""

        def num(v):
            if v is None:
                return None
            v = float(v)
            return v if math.isfinite(v) else None

        return {
            "status": self.status,
            "message": self.message,
            "section": self.section,
            "mode": self.mode,
            "state_names": list(self.state_names),
            "fixed_point": [num(v) for v in self.fixed_point],
            "parameters": {k: num(v) for k, v in self.parameters.items()},
            "free": list(self.free),
            "period": num(self.period),
            "return_time": num(self.return_time),
            "step_length": num(self.step_length),
            "multipliers": _pairs(self.multipliers, num),
            "spectral_radius": num(self.spectral_radius),
            "stable": self.stable,
            "trivial_multipliers": self.trivial_multipliers,
            "residual": num(self.residual),
            "iterations": self.iterations,
            "history": [num(v) for v in self.history],
            "transitions": list(self.transitions),
            "evaluations": self.evaluations,
            "jacobian": self.jacobian_method,
            "memory": {name: num(v) for name, v in zip(self.memory_names, self.memory, strict=True)},
            "memory_units": dict(zip(self.memory_names, self.memory_units, strict=True)),
            "differentiable": self.differentiable,
            "kinked_coordinates": list(self.kinked_coordinates),
            "multipliers_forward": _pairs(self.multipliers_forward, num),
            "multipliers_backward": _pairs(self.multipliers_backward, num),
            "warnings": list(self.warnings),
            "map_accuracy": None if self.map_accuracy is None else self.map_accuracy.to_json(),
            "piecewise": None if self.piecewise is None else self.piecewise.to_json(),
        }


def _pairs(mu: np.ndarray | None, num: Callable[[Any], float | None]) -> list[list[float | None]] | None:
    """Complex multipliers as JSON [re, im] pairs."""
    return None if mu is None else [[num(m.real), num(m.imag)] for m in mu]
