"""Monte Carlo ensembles of sampled executions, each on its own random stream, and their
summary."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..arguments import check_start, check_t_final, positive
from ..bounds import LocalErrorEstimator, ModeFlow
from ..errors import SimulationError
from ..hybrid import HybridSystem
from ..methods import Tableau
from .executions import StochasticExecution, Visit, sample_execution
from .intensity import HAZARD_CAP, MAX_SAMPLES, ControlFn, check_form, check_hazard_cap


@dataclass
class Ensemble:
    """Monte Carlo ensemble of stochastic executions with the settings that made them."""

    executions: list[StochasticExecution]
    settings: dict[str, Any] = field(default_factory=dict)

    def switching_times(self, index: int) -> np.ndarray:
        """The ``index``-th switching time (0-based) of every execution that has one."""
        return np.array([e.times[index] for e in self.executions if len(e.times) > index])

    def summary(self, max_switches: int = 10, max_sequences: int = 10) -> dict[str, Any]:
        """JSON-ready summary: distribution of mode sequences and of switching times."""
        n = len(self.executions)
        counts = Counter(tuple(e.modes) for e in self.executions)
        sequences = [
            {"modes": list(seq), "transitions": len(seq) - 1, "count": c, "fraction": c / n}
            for seq, c in counts.most_common(max_sequences)
        ]
        per_sample = np.array([len(e.times) for e in self.executions])
        switches = []
        for i in range(int(per_sample.max(initial=0))):
            if i >= max_switches:
                break
            ts = self.switching_times(i)
            switches.append(
                {
                    "index": i + 1,
                    "count": len(ts),
                    "mean": float(ts.mean()),
                    "std": float(ts.std()),
                    "min": float(ts.min()),
                    "max": float(ts.max()),
                }
            )
        dwell = [e.dwell_times for e in self.executions if len(e.times)]
        min_dwell = float(min(d.min() for d in dwell)) if dwell else None
        statuses = Counter(e.status for e in self.executions)
        return {
            **self.settings,
            "samples": n,
            "distinct_sequences": len(counts),
            "sequences": sequences,
            "transitions_per_sample": {
                "mean": float(per_sample.mean()),
                "min": int(per_sample.min()),
                "max": int(per_sample.max()),
            },
            "switching_times": switches,
            "min_dwell_time": min_dwell,
            "max_radius": max((e.max_radius for e in self.executions), default=0.0),
            "unresolved": _unresolved(self.executions),
            "statuses": dict(statuses),
        }


def _unresolved(executions: list[StochasticExecution]) -> dict[str, Any] | None:
    """How many executions met an error ball wider than the state, and from when (s); None
    when none did."""
    times = [e.unresolved_from for e in executions if e.unresolved_from is not None]
    return {"executions": len(times), "earliest": min(times)} if times else None


def sample_generator(seed: int | None, index: int) -> np.random.Generator:
    """The random generator of execution ``index`` of an ensemble seeded by ``seed``: child
    ``index`` of ``numpy.random.SeedSequence(seed)`` (independent streams, numpy's way of
    seeding parallel work). ``seed`` None draws fresh entropy: such an ensemble is not
    reproducible, and its executions are drawn from unrelated streams."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(index),)))


def sample_ensemble(
    system: HybridSystem,
    mode: str,
    x0: Any,
    t_final: float,
    h: float,
    method: str | Tableau = "rk4",
    *,
    samples: int = 100,
    seed: int | None = None,
    t0: float = 0.0,
    pair: str | Tableau | None = None,
    control: ControlFn | None = None,
    floor: float = 0.0,
    intensity: str = "hazard",
    max_transitions: int = 1000,
    carry: bool = True,
    hazard_cap: float = HAZARD_CAP,
    progress: Callable[[int, int], None] | None = None,
    indices: Sequence[int] | None = None,
) -> Ensemble:
    """``samples`` independent stochastic executions. Execution k draws from its own numpy
    Generator, ``sample_generator(seed, k)``, so that its draws do not depend on the executions
    before it: any subset (``indices``, e.g. one batch of a Monte Carlo run spread over
    processes, ``legsim.sweep.stochastic``) gives the same executions as the whole ensemble.
    The first visit's numerical flow is computed once and shared, as every sample starts it
    from the same state. ``samples`` is at most ``MAX_SAMPLES``; ``progress(done, total)``,
    when given, is called after each execution."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 1 <= samples <= MAX_SAMPLES:
        raise SimulationError(f"samples must be an integer in [1, {MAX_SAMPLES}], got {samples!r}")
    chosen = range(int(samples)) if indices is None else [int(k) for k in indices]
    if any(not 0 <= k < samples for k in chosen):
        raise SimulationError(f"indices must lie in [0, {samples}), got {list(chosen)[:10]}")
    x = check_start(system, mode, x0)
    h = positive("h", h)
    check_form(intensity)
    cap = check_hazard_cap(hazard_cap)
    t_final = check_t_final(t_final, t0)
    estimator = LocalErrorEstimator(method, pair, floor)
    first = Visit(ModeFlow(system, mode, x, float(t0), h, estimator, control=control, t_end=t_final), intensity, cap)
    runs = []
    for done, k in enumerate(chosen, 1):
        runs.append(
            sample_execution(
                system,
                mode,
                x,
                t_final,
                h,
                method,
                rng=sample_generator(seed, k),
                t0=t0,
                pair=pair,
                control=control,
                floor=floor,
                intensity=intensity,
                max_transitions=max_transitions,
                carry=carry,
                hazard_cap=cap,
                _first=first,
            )
        )
        if progress is not None:
            progress(done, len(chosen))
    settings = {
        "system": system.name,
        "initial_mode": mode,
        "h": h,
        "method": estimator.method.name,
        "pair": estimator.pair.name,
        "floor": estimator.floor,
        "intensity": intensity,
        "carry": carry,
        "hazard_cap": cap,
        "t_final": t_final,
        "seed": seed,
    }
    return Ensemble(runs, settings)
