"""The quotient distance between two runs of a controlled system.

A run under a ``ControlLaw`` carries the controller's memory in its state: in every mode the
plant's ``dim`` coordinates come first, then the memory's entries. The metric is the one of
paper 000 on the *plant's* hybrid system (its domains, guards and resets), applied to the
plant part of each state; the memory is compared separately, entry by entry in its own units.
Why (docs/metric.md, "Runs of controlled systems"): the quotient glues a guard point p to its
reset image R(p), and the controller's memory is changed only there, by its ``enter`` function
of the entry time and the new plant state; between entries it is constant and has no flow, so
it adds no length to a curve inside a domain, and it is not a function of the plant's guard
point alone (a hopper's touchdown time is the time of the crossing), so it has no place in the
plant's gluing. Two runs whose plant states are close in M^eps enter their modes at close
states and times, which is where their memories are set.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..execution import Samples
from ..hybrid import HybridSystem
from .executions import _strip_taus, distances
from .inputs import DEFAULT_MAX_HOPS, MetricError, check_eps, check_system

#: Evenly spaced sample times of a comparison, before the transition times are added.
SAMPLES = 2001


@dataclass(frozen=True)
class PlantView:
    """An execution seen through its plant coordinates: ``sample`` keeps the first
    ``dims[mode]`` entries of each state (the plant's), dropping the controller's memory.
    ``strips`` and ``transitions`` are the execution's (the metric places strip samples)."""

    execution: Any
    dims: Mapping[str, int]

    @property
    def strips(self) -> Any:
        return getattr(self.execution, "strips", None)

    @property
    def transitions(self) -> Any:
        return getattr(self.execution, "transitions", ())

    def sample(self, times: Any) -> Samples:
        """The execution's samples at ``times`` (s), states cut to the plant's coordinates."""
        full = self.execution.sample(times)
        states = [
            np.asarray(x, dtype=float)[: self.dims[mode]] for mode, x in zip(full.modes, full.states, strict=True)
        ]
        return Samples(full.times, list(full.modes), states, full.in_strip)


def plant_view(system: HybridSystem, execution: Any, label: str = "execution") -> PlantView:
    """``execution`` (anything with ``sample`` and ``segments``) as a ``PlantView`` of ``system``;
    a ``MetricError`` naming the mode when it visits a mode ``system`` lacks or keeps fewer
    coordinates than the plant's."""
    system = check_system(system)
    dims: dict[str, int] = {}
    for segment in getattr(execution, "segments", ()):
        mode = segment.mode
        if mode not in system.modes:
            raise MetricError(
                f"{label} visits mode '{mode}', which {system.name} lacks (modes: {sorted(system.modes)})"
            )
        dims[mode] = system.mode(mode).dim
        width = np.shape(segment.x)[1] if np.ndim(segment.x) == 2 else dims[mode]
        if width < dims[mode]:
            raise MetricError(
                f"{label}: its states in mode '{mode}' have {width} entries, fewer than the plant's {dims[mode]}"
            )
    return PlantView(execution, dims)


@dataclass(frozen=True)
class RunDistance:
    """Two runs of one system compared in the relaxed quotient metric at the same times.

    Attributes
    ----------
    value: max over the sample times of the distance in M^eps between the plant states (rho^eps
        of paper 000 Definition 22 over those times; Euclidean units of the state, e.g. m, rad,
        m/s together, as the paper's domains).
    time: the sample time (s) of that maximum.
    samples: sample times compared: ``SAMPLES`` evenly spaced over the common interval and the
        entry and exit times of every transition of both runs inside it.
    searched: samples where the modes differ or either run is in a strip (a path through the
        transitions searched for); elsewhere the distance is the chord in the common mode.
    memory: per memory entry, max |m_a - m_b| (its own unit) over the samples where both runs
        are in the same mode outside strips; empty without memory.
    eps: the strip width of M^eps (guard units).
    """

    value: float
    time: float
    samples: int
    searched: int
    memory: dict[str, float]
    eps: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "time": self.time,
            "samples": self.samples,
            "searched": self.searched,
            "memory": self.memory,
            "eps": self.eps,
        }


def comparison_times(run: Any, other: Any, samples: int = SAMPLES) -> np.ndarray:
    """``samples`` times evenly spaced over the two runs' common interval, with the entry and
    exit times of every transition of either run inside it (where their modes may differ, and
    the distance peaks); sorted, shape (m,). Empty when the interval is."""
    t0 = max(float(run.t0), float(other.t0))
    t1 = min(float(run.t_end), float(other.t_end))
    if not t1 >= t0:
        return np.empty(0)
    times = [np.linspace(t0, t1, samples)]
    for execution in (run, other):
        for tr in execution.transitions:
            times.append(np.array([tr.time, tr.exit_time]))
    out = np.unique(np.concatenate(times))
    return out[(out >= t0) & (out <= t1)]


def run_distance(
    system: HybridSystem, run: Any, other: Any, eps: float, *, samples: int = SAMPLES, max_hops: int = DEFAULT_MAX_HOPS
) -> RunDistance:
    """The relaxed quotient distance between two executions of ``system`` (plant states; the
    memory compared per entry, module docstring) at ``comparison_times``.

    At each time the distance is the shortest of the chord (in the same mode outside strips)
    and the paths through the guard points and reset images of the crossings the two runs made
    near that time (``_through_crossings``); the metric's search (``legsim.metric.distance``, at
    most ``max_hops`` crossings) runs only where neither joins the two points. Raises
    ``MetricError`` naming what the metric cannot take (a mode the system lacks, a state that is
    not finite, runs without a common interval)."""
    eps = check_eps(eps)
    view_a, view_b = plant_view(system, run, "run"), plant_view(system, other, "other run")
    times = comparison_times(run, other, samples)
    if times.size == 0:
        raise MetricError(f"the runs share no time interval ([{run.t0}, {run.t_end}] and [{other.t0}, {other.t_end}])")
    full_a, full_b = run.sample(times), other.sample(times)
    d, same = _distances_at(system, view_a, view_b, full_a, full_b, eps, max_hops)
    worst = int(np.argmax(d))
    return RunDistance(
        value=float(d[worst]),
        time=float(times[worst]),
        samples=int(times.size),
        searched=int(times.size - len(same)),
        memory=_memory_apart(run, view_a.dims, full_a, full_b, same),
        eps=eps,
    )


def crossing_distances(system: HybridSystem, run: Any, other: Any, pairs: Any, eps: float) -> np.ndarray:
    """The relaxed quotient distance between the plant states of two runs at matched section
    crossings, shape (len(pairs),): ``pairs`` holds (mode, x_run, t_run, x_other, t_other), each
    state the run's at its crossing (plant coordinates first, the memory after them is left
    out). Phase-aligned: the two runs are compared where each crosses, not at one time, so a
    timing error alone adds nothing. Each distance is the shortest explicit path (the chord,
    or chords joined at the crossings either run made near those times, a strip of width eps
    each), an upper bound of the distance; a ``MetricError`` for a state that is not finite."""
    eps = check_eps(eps)
    view_a, view_b = plant_view(system, run, "run"), plant_view(system, other, "other run")
    crossings = [Crossed(view_a), Crossed(view_b)]
    out = np.empty(len(pairs))
    for k, (mode, xa, ta, xb, tb) in enumerate(pairs):
        a = np.asarray(xa, dtype=float)[: view_a.dims[mode]]
        b = np.asarray(xb, dtype=float)[: view_b.dims[mode]]
        _require_finite(a, mode, float(ta))
        _require_finite(b, mode, float(tb))
        # Each run's own crossings near its own time: the union joins the two points either way.
        near = [*crossings[0].near(float(ta)), *crossings[1].near(float(tb))]
        out[k] = _through_crossings([(mode, a, 0.0)], [(mode, b, 0.0)], near, eps)
    return out


def _distances_at(
    system: HybridSystem,
    view_a: PlantView,
    view_b: PlantView,
    full_a: Samples,
    full_b: Samples,
    eps: float,
    max_hops: int,
) -> tuple[np.ndarray, list[int]]:
    """The distance at each sample (shape (n,)), and the samples where both runs are in the
    same mode outside strips."""
    ends_a, ends_b = _anchors(view_a, full_a, eps), _anchors(view_b, full_b, eps)
    crossings = [Crossed(view_a), Crossed(view_b)]
    d = np.empty(len(full_a.times))
    same: list[int] = []
    for i, t in enumerate(full_a.times):
        (mode_a, xa, _), (mode_b, xb, _) = ends_a[i][0], ends_b[i][0]
        if len(ends_a[i]) == 1 and len(ends_b[i]) == 1 and mode_a == mode_b:
            same.append(i)
            d[i] = float(np.linalg.norm(xa - xb))
            if d[i] <= eps:  # no path through a crossing is shorter than its strip
                continue
        # The chord where the modes agree, or a shorter path through crossings (a self-transition
        # such as a ball's bounce joins two far points of one mode).
        near = [c for run in crossings for c in run.near(float(t))]
        d[i] = _through_crossings(ends_a[i], ends_b[i], near, eps)
        if not math.isfinite(d[i]):
            d[i] = distances(system, view_a, view_b, full_a.times[i : i + 1], eps, max_hops=max_hops)[0]
    return d, same


#: A domain point a sample reaches and the length of the way there: (mode, plant state, length).
Anchor = tuple[str, np.ndarray, float]


def _anchors(view: PlantView, full: Samples, eps: float) -> list[list[Anchor]]:
    """For each sample, the domain points it is joined to: itself outside a strip; inside the
    strip of a crossing (guard point q, transverse coordinate tau of paper 000 Fig. 12) q in the
    source mode at length tau and the reset image R(q) in the target mode at length eps - tau."""
    taus = _strip_taus(view.execution, full, eps)
    by_entry = {(tr.name, tr.time): tr for tr in view.transitions}
    starts = np.array([s.time for s in view.strips or ()])
    out: list[list[Anchor]] = []
    for i, (mode, x) in enumerate(zip(full.modes, full.states, strict=True)):
        plant = np.asarray(x, dtype=float)[: view.dims[mode]]
        _require_finite(plant, mode, float(full.times[i]))
        strip_tau = taus[i]
        if strip_tau is None:
            out.append([(mode, plant, 0.0)])
            continue
        strip = view.strips[int(np.searchsorted(starts, full.times[i], side="right")) - 1]
        tau = strip_tau[1]
        anchors: list[Anchor] = [(mode, plant, tau)]
        record = by_entry.get((strip.name, strip.time))
        if record is not None:  # a strip cut short by the end of the run has no reset image
            after = np.asarray(record.state_after, dtype=float)[: view.dims[record.target]]
            anchors.append((record.target, after, max(eps - tau, 0.0)))
        out.append(anchors)
    return out


def _require_finite(x: np.ndarray, mode: str, t: float) -> None:
    if not np.all(np.isfinite(x)):
        raise MetricError(f"the state in mode '{mode}' at t={t:.12g} is not finite: {x.tolist()}")


def _through_crossings(
    ends_a: list[Anchor], ends_b: list[Anchor], near: list[tuple[str, str, np.ndarray, np.ndarray]], eps: float
) -> float:
    """The shortest path between two samples' anchors made of chords inside modes joined at
    the crossings ``near`` (source, target, guard point q, reset image R(q)): those the runs
    made near the samples' times (``Crossed.near``), each usable either way (q and R(q) are
    joined in M^eps by a strip of width eps), by Dijkstra's algorithm over them. An explicit
    connected path, so an upper bound of the distance; ``inf`` when no such path joins them."""
    # Each crossing both ways: (from mode, entry point, to mode, exit point).
    hops = [(s, q, d, r) for s, d, q, r in near] + [(d, r, s, q) for s, d, q, r in near]
    best = math.inf
    for mode_b, xb, lb in ends_b:
        # reach[k]: the shortest length from a's anchors to the exit point of hop k.
        reach = [math.inf] * len(hops)
        heap: list[tuple[float, int]] = []
        for mode_a, xa, la in ends_a:
            if mode_a == mode_b:
                best = min(best, la + lb + float(np.linalg.norm(xa - xb)))
            for k, (frm, entry, _, _) in enumerate(hops):
                if frm == mode_a:
                    length = la + float(np.linalg.norm(xa - entry)) + eps
                    if length < reach[k]:
                        reach[k] = length
                        heapq.heappush(heap, (length, k))
        while heap:
            length, k = heapq.heappop(heap)
            if length > reach[k] or length >= best:
                continue
            _, _, mode, y = hops[k]
            if mode == mode_b:
                best = min(best, length + lb + float(np.linalg.norm(y - xb)))
            for j, (frm, entry, _, _) in enumerate(hops):
                if frm == mode:
                    onward = length + float(np.linalg.norm(y - entry)) + eps
                    if onward < reach[j]:
                        reach[j] = onward
                        heapq.heappush(heap, (onward, j))
    return best


#: Crossings of each run, nearest in time to a sample, tried as its path between two modes.
NEAREST = 3


class Crossed:
    """A run's crossings as (source, target, guard point q, reset image R(q)), plant
    coordinates, with the lookup of those nearest a time."""

    def __init__(self, view: PlantView) -> None:
        self.items = [
            (
                tr.source,
                tr.target,
                np.asarray(tr.state_before, dtype=float)[: view.dims[tr.source]],
                np.asarray(tr.state_after, dtype=float)[: view.dims[tr.target]],
            )
            for tr in view.transitions
            if tr.source in view.dims and tr.target in view.dims
        ]
        self.times = np.array([tr.time for tr in view.transitions if tr.source in view.dims and tr.target in view.dims])

    def near(self, t: float) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
        k = int(np.searchsorted(self.times, t))
        return self.items[max(k - NEAREST, 0) : k + NEAREST]


def _memory_apart(
    run: Any, dims: Mapping[str, int], full_a: Samples, full_b: Samples, same: list[int]
) -> dict[str, float]:
    """Per memory entry (the coordinates after the plant's), max |m_a - m_b| over ``same``."""
    names: Mapping[str, Any] = getattr(run, "state_names", None) or {}
    worst: dict[str, float] = {}
    for i in same:
        mode = full_a.modes[i]
        dim = dims[mode]
        apart = np.abs(np.asarray(full_a.states[i][dim:], dtype=float) - np.asarray(full_b.states[i][dim:]))
        entries = tuple(names.get(mode, ()))[dim:] or tuple(f"memory[{k}]" for k in range(apart.size))
        for name, value in zip(entries, apart, strict=False):
            if math.isfinite(float(value)):
                worst[name] = max(worst.get(name, 0.0), float(value))
    return worst
