"""Distances between executions: the metric at each sample time, its supremum rho^eps (paper 000
Definition 22), the position-only error of eq. (30), and a trajectory-space comparison.

An execution is anything with ``sample(times) -> Samples`` (modes, states, optionally
in_strip): a legsim ``Execution``, whose samples inside a strip are placed in that strip with
the transverse coordinate of paper 000 Fig. 12, or an analytic reference.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..hybrid import HybridSystem
from .inputs import (
    DEFAULT_MAX_HOPS,
    HybridPoint,
    MetricError,
    check_eps,
    check_hops,
    check_point,
    check_system,
    check_times,
)
from .search import path_between


def distances(
    system: HybridSystem,
    execution_a: Any,
    execution_b: Any,
    times: Any,
    eps: float,
    *,
    max_hops: int = DEFAULT_MAX_HOPS,
) -> np.ndarray:
    """``distance`` between the two executions at each of ``times`` (s); shape (len(times),).

    Each execution is anything with ``sample(times) -> Samples`` (modes, states, optionally
    in_strip): a legsim ``Execution`` (whose strip samples are placed in their strip with the
    transverse coordinate of paper 000 Fig. 12) or an analytic reference.
    """
    system = check_system(system)
    eps = check_eps(eps)
    max_hops = check_hops(max_hops)
    t = check_times(times)
    pa = _points(system, execution_a, t, eps, "execution_a")
    pb = _points(system, execution_b, t, eps, "execution_b")
    out = np.empty(len(t))
    for i, (p, q) in enumerate(zip(pa, pb, strict=True)):
        if p.strip is None and q.strip is None and p.mode == q.mode:
            d0 = float(np.linalg.norm(p.x - q.x))
            if d0 <= eps or max_hops == 0:  # no crossing can be shorter than one strip width
                out[i] = d0
                continue
        out[i] = path_between(system, p, q, eps, max_hops).length
    return out


def rho(
    system: HybridSystem,
    execution_a: Any,
    execution_b: Any,
    times: Any,
    eps: float,
    *,
    max_hops: int = DEFAULT_MAX_HOPS,
) -> float:
    """rho^eps of paper 000 Definition 22: the supremum over ``times`` (s) of the relaxed
    quotient distance between the two executions (each anything with ``sample(times)``).

    The supremum is taken over the given sample times; pass times dense enough for the
    execution's time scale (and include the transition times if the extremum matters).
    """
    return float(np.max(distances(system, execution_a, execution_b, times, eps, max_hops=max_hops)))


def trajectory_space_distance(execution_a: Any, execution_b: Any, times: Any) -> float:
    """A trajectory-space comparison that charges mode mismatch, for contrast with ``rho``.

    sup over ``times`` of ``|x_a(t) - x_b(t)| + [mode_a(t) != mode_b(t)]``: the discrete
    metric on modes plus the Euclidean one on states, the form of the trajectory metrics paper
    000 cites ([1]-[4]), which separate states in different modes by at least 1. No time
    reparametrisation is minimised over: a Skorohod time change can shrink the Euclidean part
    but cannot align two different mode sequences (0->1->3 against 0->2->3), so the charge of
    1 stays. States of different dimensions are infinitely far apart.
    """
    t = check_times(times)
    sa = _sample(execution_a, t, "execution_a")
    sb = _sample(execution_b, t, "execution_b")
    worst = 0.0
    for ma, xa, mb, xb in zip(sa.modes, sa.states, sb.modes, sb.states, strict=True):
        xa, xb = np.asarray(xa, dtype=float), np.asarray(xb, dtype=float)
        if xa.shape != xb.shape:
            return math.inf
        worst = max(worst, float(np.linalg.norm(xa - xb)) + (0.0 if ma == mb else 1.0))
    return worst


def position_error(simulated: Any, reference: Any, times: Any, *, coordinate: int | str = 0) -> float:
    """Position-only error of paper 000 eq. (30): ``max_k |z_pos(t_k) - x(t_k)|``.

    Parameters
    ----------
    simulated: positions at ``times`` (array of shape (len(times),)), e.g. from a method that
        computes positions only (Paoli-Schatzman), or anything with ``sample(times)``.
    reference: anything with ``sample(times)``, or a callable ``reference(times) -> positions``.
    times: the sample times t_k (s), inside both executions' intervals.
    coordinate: index of the position in the state, or its name (looked up in the
        ``state_names`` of whichever argument has them, per mode).
    """
    t = check_times(times)
    names = next(
        (
            n
            for n in (getattr(simulated, "state_names", None), getattr(reference, "state_names", None))
            if isinstance(n, dict)
        ),
        None,
    )
    zs = _positions(simulated, t, coordinate, "simulated", names)
    xs = _positions(reference, t, coordinate, "reference", names)
    return float(np.max(np.abs(zs - xs)))


def _sample(execution: Any, times: np.ndarray, label: str) -> Any:
    """``execution.sample(times)``, checked to give one mode and one state per time."""
    sample = getattr(execution, "sample", None)
    if not callable(sample):
        raise MetricError(
            f"{label} must have a sample(times) -> Samples method "
            f"(a legsim Execution or a reference), got {type(execution).__name__}"
        )
    samples = sample(times)
    modes, states = getattr(samples, "modes", None), getattr(samples, "states", None)
    if modes is None or states is None or len(modes) != len(times) or len(states) != len(times):
        raise MetricError(f"{label}.sample(times) must return Samples with one mode and state per time")
    return samples


def _points(system: HybridSystem, execution: Any, times: np.ndarray, eps: float, label: str) -> list[HybridPoint]:
    """The execution's samples as points of M^eps (strip samples in their strip)."""
    samples = _sample(execution, times, label)
    taus = _strip_taus(execution, samples, eps)
    points = []
    for i, (mode, x) in enumerate(zip(samples.modes, samples.states, strict=True)):
        where = f"{label} at t={times[i]:.12g}"
        tau = taus[i]
        point = (mode, x) if tau is None else (mode, x, *tau)
        points.append(check_point(system, point, eps, where))
    return points


def _strip_taus(execution: Any, samples: Any, eps: float) -> list[tuple[str, float] | None]:
    """For each sample inside a strip: (transition name, tau); None for the others."""
    n = len(samples.times)
    out: list[tuple[str, float] | None] = [None] * n
    in_strip = getattr(samples, "in_strip", None)
    strips = getattr(execution, "strips", None)
    if in_strip is None or strips is None or not np.any(in_strip):
        return out
    records = {(tr.name, tr.time): tr for tr in getattr(execution, "transitions", ())}
    starts = np.array([s.time for s in strips])
    for i in np.nonzero(in_strip)[0]:
        t = float(samples.times[i])
        k = int(np.searchsorted(starts, t, side="right")) - 1
        if k < 0:
            continue
        strip = strips[k]
        tau = _strip_tau(records.get((strip.name, strip.time)), strip.time, t)
        out[i] = (strip.name, min(max(tau, 0.0), eps))
    return out


def _strip_tau(record: Any, entry_time: float, t: float) -> float:
    """The transverse coordinate at time t (s) of a strip entered at ``entry_time``: from 0 at
    the entry linearly to the landing depth at the landing time, then at unit rate to eps at
    the exit, as in paper 000 Fig. 12 step 12 (a curve continuous in M^eps at both ends).
    Without a transition record (the run ended inside this strip, so its landing was not kept)
    the time spent in the strip."""
    if record is None:
        return t - entry_time
    if t > record.landing_time:
        return record.depth + (t - record.landing_time)
    span = record.landing_time - record.time
    return record.depth if span <= 0 else record.depth * (t - record.time) / span


def _positions(
    obj: Any, t: np.ndarray, coordinate: int | str, label: str, names: dict[str, Sequence[str]] | None
) -> np.ndarray:
    """Positions (shape (len(t),)) from an execution, a callable of the times, or an array."""
    if hasattr(obj, "sample") and callable(obj.sample):
        samples = _sample(obj, t, label)
        out = np.empty(len(t))
        for i, (mode, x) in enumerate(zip(samples.modes, samples.states, strict=True)):
            x = np.asarray(x, dtype=float)
            out[i] = x[_coordinate_index(coordinate, mode, len(x), label, names)]
        return out
    values = obj(t) if callable(obj) else obj
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise MetricError(f"{label} positions must be numbers: {exc}") from None
    if arr.shape != t.shape:
        raise MetricError(f"{label} gives {arr.size} positions for {t.size} times")
    if not np.all(np.isfinite(arr)):
        raise MetricError(f"{label} positions must be finite")
    return arr


def _coordinate_index(
    coordinate: int | str, mode: str, dim: int, label: str, names: dict[str, Sequence[str]] | None
) -> int:
    """The index of ``coordinate`` (an index, or a name looked up in ``names[mode]``) in a
    state of dimension ``dim``."""
    index = coordinate
    if isinstance(coordinate, str):
        mode_names = tuple(names.get(mode, ())) if isinstance(names, dict) else ()
        if coordinate not in mode_names:
            raise MetricError(
                f"{label}: no coordinate named '{coordinate}' in mode '{mode}' (names: {mode_names or 'unknown'})"
            )
        index = mode_names.index(coordinate)
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not -dim <= index < dim:
        raise MetricError(f"{label}: coordinate {coordinate!r} is not an index of the {dim}-d state in mode '{mode}'")
    return index
