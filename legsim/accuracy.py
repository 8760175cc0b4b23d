"""How accurate is a run? An estimate every run can state.

The run is repeated with a finer setting (the strip width eps / 10, and the step h / 2 for fixed
steps or the tolerances / 10 for error-controlled ones) and the two are compared: the final state,
the transition times and the sampled trajectory, per coordinate. The relaxed execution converges
at O(eps) + O(h^order) (paper 000), so the refined run is several times closer to the true one,
and the difference estimates the original run's error (its error times 1 - 1/ratio, within a
factor of about 2 of it for ratios of 2 and more).

A gait's final state at a fixed time is the wrong yardstick: a small timing error moves the state
along the orbit, and at a symmetric gait the order of simultaneous events may switch without
changing the motion. So the two runs are also compared *along the orbit*: the states at their
crossings of a Poincare section (a scene's ``[orbit]`` section, e.g. a runner's apex, given as an
``OrbitSection``), else at their entries into a section mode (the run's initial mode, e.g. a
runner's flight), matched in order each with the other run's nearest in time (phase-aligned),
and the times apart reported as the phase error. A section crossed once a stride is the better
yardstick: a brief flight or graze that one run makes and the other does not adds a mode entry,
never a crossing of the apex.
And they are compared in paper 000's relaxed quotient metric (``legsim.metric``): the distance
in M^eps between their plant states at the same times, which holds across different transition
sequences; a controller's memory is compared entry by entry (``legsim.metric.closed_loop``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .crossings import Crossing, returns, takings
from .errors import SimulationError
from .execution import Execution
from .hybrid import HybridSystem
from .methods import Tableau
from .metric import MetricError
from .metric.closed_loop import RunDistance, crossing_distances, run_distance

#: Times at which the two trajectories are compared.
SAMPLES = 2001
#: A coordinate whose size along the run is below this share of the largest coordinate's stays at
#: zero to rounding (a symmetric gait's pitch): it has no size to be relative to.
ZERO_SIZE = 1e-9


@dataclass(frozen=True)
class ErrorEstimate:
    """The estimated error of a run, from its difference with a refined run.

    Attributes
    ----------
    final_state: per coordinate of the final mode, |x - x_refined| at t_end (in the coordinate's
        units); coordinates the refined run's final mode lacks are left out.
    final_state_relative: max over coordinates of that error over the coordinate's size in the run
        (its largest |value| along the refined run); coordinates that stay at zero to rounding
        (below ``ZERO_SIZE`` of the largest size) are left out of it. None when the final modes
        differ.
    transition_times: max |t_k - t_k refined| (s) over the transitions both runs take in the same
        order (None without any); ``transitions_matched`` of them, ``transitions_differ`` when the
        sequences differ in name or count.
    trajectory: per coordinate, max |x(t) - x_refined(t)| over ``SAMPLES`` times where both runs
        are in the same mode; ``mode_mismatch``: the share of those times where they are not.
    refined: the refined run's settings (h, eps, rtol, atol).
    along_orbit: the comparison at matching section crossings (``AlongOrbit``), None when the
        run never re-enters a mode.
    quotient_distance: the two runs' distance in paper 000's relaxed quotient metric
        (``legsim.metric.closed_loop.RunDistance``: the plant states in M^eps at the run's eps,
        the controller's memory per entry); None when it is not defined for them, and then
        ``quotient_distance_note`` says why.
    """

    final_state: dict[str, float]
    final_state_relative: float | None
    transition_times: float | None
    transitions_matched: int
    transitions_differ: bool
    trajectory: dict[str, float]
    mode_mismatch: float
    refined: dict[str, Any] = field(default_factory=dict)
    along_orbit: AlongOrbit | None = None
    quotient_distance: RunDistance | None = None
    quotient_distance_note: str | None = None

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``legsim run --check-accuracy --json``: key ``error_estimate``)."""
        return {
            "final_state": self.final_state,
            "final_state_relative": self.final_state_relative,
            "transition_times": self.transition_times,
            "transitions_matched": self.transitions_matched,
            "transitions_differ": self.transitions_differ,
            "trajectory": self.trajectory,
            "mode_mismatch": self.mode_mismatch,
            "refined": self.refined,
            "along_orbit": None if self.along_orbit is None else self.along_orbit.as_dict(),
            "quotient_distance": None if self.quotient_distance is None else self.quotient_distance.as_dict(),
            "quotient_distance_note": self.quotient_distance_note,
        }


@dataclass(frozen=True)
class OrbitSection:
    """A Poincare section for the along-the-orbit comparison: the crossings of
    ``function(x) = 0`` in ``direction`` (-1: decreasing, +1: increasing, 0: either) in mode
    ``mode``, or, with ``transition``, the takings of that transition into ``mode``. ``label``
    names it in reports (e.g. "zd = 0 (decreasing) in flight"). Crossings count as a return map
    counts them (``legsim.crossings.returns``): ``min_transitions`` segments and ``min_time``
    (s) after the last one, one a segment. A scene's is its ``[orbit]`` section, with that
    section's counting (``legsim.scene.orbit.accuracy_section``)."""

    mode: str
    label: str
    function: Callable[[np.ndarray], float] | None = None
    direction: int = -1
    transition: str | None = None
    min_transitions: int = 1
    min_time: float = 0.0

    def __post_init__(self) -> None:
        if (self.function is None) == (self.transition is None):
            raise SimulationError(f"OrbitSection {self.label!r}: give a function or a transition, not both or neither")
        if self.function is not None and not callable(self.function):
            raise SimulationError(f"OrbitSection {self.label!r}: function must be callable s(x) -> float")
        if self.direction not in (-1, 0, 1):
            raise SimulationError(f"OrbitSection {self.label!r}: direction must be -1, 0 or +1, got {self.direction!r}")
        if self.min_transitions < 0 or not self.min_time >= 0.0:
            raise SimulationError(
                f"OrbitSection {self.label!r}: min_transitions and min_time must be >= 0, got "
                f"{self.min_transitions!r} and {self.min_time!r}"
            )


@dataclass(frozen=True)
class AlongOrbit:
    """A run against its refined repetition at the same section crossings.

    Attributes
    ----------
    section: the mode the section lies in (a mode whose entries are the crossings: the run's
        initial mode, or the mode it enters most often when it never re-enters that one).
    where: what the crossings are: ``"entries into 'flight'"``, ``"crossings of zd = 0
        (decreasing) in flight"`` or ``"takings of heel_strike into stance"``.
    crossings: how many crossings of the two runs are matched: each with the other run's
        nearest in time, in order (``_matched``).
    unmatched: crossings of either run left without a match (an extra graze of one run).
    phase: max |t_k - t_k refined| (s) over those crossings.
    state: per coordinate, max |x_k - x_k refined| over those crossings (for entries and
        takings, the states just after the reset; in the coordinate's units).
    relative: max over coordinates of that error over the coordinate's size along the refined run
        (coordinates at zero to rounding left out, as for ``final_state_relative``).
    quotient: max over those crossings of paper 000's relaxed quotient distance (at the run's
        eps) between the two runs' plant states there, phase-aligned (``legsim.metric.
        closed_loop.crossing_distances``: an explicit path, an upper bound); None without the
        system, or where the metric is not defined (``quotient_note`` says why).
    """

    section: str
    crossings: int
    unmatched: int
    phase: float
    state: dict[str, float]
    relative: float | None
    where: str = ""
    quotient: float | None = None
    quotient_note: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "section": self.section,
            "where": self.where,
            "crossings": self.crossings,
            "unmatched": self.unmatched,
            "phase": self.phase,
            "state": self.state,
            "relative": self.relative,
            "quotient": self.quotient,
            "quotient_note": self.quotient_note,
        }


def refined(settings: dict[str, Any]) -> dict[str, Any]:
    """The refined settings: eps / 10; h / 2 for fixed steps, rtol and atol / 10 with error control."""
    out = dict(settings)
    out["eps"] = settings["eps"] / 10.0
    if settings.get("rtol") is None and settings.get("atol") is None:
        out["h"] = settings["h"] / 2.0
    else:
        out["rtol"] = None if settings.get("rtol") is None else settings["rtol"] / 10.0
        out["atol"] = None if settings.get("atol") is None else settings["atol"] / 10.0
    return out


def compare(
    run: Execution, fine: Execution, system: HybridSystem | None = None, section: str | OrbitSection | None = None
) -> ErrorEstimate:
    """The error estimate of ``run`` against its refined repetition ``fine``; the quotient
    distance needs the ``system`` both ran; ``section`` is where the two are compared along the
    orbit (``along_orbit``)."""
    final, relative = _final_state(run, fine)
    times, matched, differ = _transition_times(run, fine)
    trajectory, mismatch = _trajectory(run, fine)
    settings = {key: fine.settings.get(key) for key in ("h", "eps", "rtol", "atol")}
    orbit = along_orbit(run, fine, section, system)
    distance, note = quotient_distance(system, run, fine)
    return ErrorEstimate(final, relative, times, matched, differ, trajectory, mismatch, settings, orbit, distance, note)


def quotient_distance(
    system: HybridSystem | None, run: Execution, fine: Execution
) -> tuple[RunDistance | None, str | None]:
    """(the runs' distance in the relaxed quotient metric at the run's eps, None) or (None, why
    it is not defined for them)."""
    return _in_quotient(system, run, lambda system, eps: run_distance(system, run, fine, eps))


def _in_quotient(
    system: HybridSystem | None, run: Execution, measure: Callable[[HybridSystem, float], Any]
) -> tuple[Any, str | None]:
    """(measure(system, eps) at the run's strip width eps, None), or (None, why the quotient
    metric is not defined for the runs: no system, no eps, or the metric's refusal)."""
    if system is None:
        return None, "not computed: the hybrid system the runs simulate was not given"
    eps = run.settings.get("eps")
    if not isinstance(eps, (int, float)) or not eps >= 0:
        return None, f"not defined: the run's strip width eps is {eps!r}"
    try:
        return measure(system, float(eps)), None
    except MetricError as exc:
        return None, f"not defined: {exc}"


def along_orbit(
    run: Execution, fine: Execution, section: str | OrbitSection | None = None, system: HybridSystem | None = None
) -> AlongOrbit | None:
    """``run`` against ``fine`` at their crossings of ``section``: an ``OrbitSection``, or the
    name of a mode whose entries are the crossings (default: the run's initial mode, else the
    mode it enters most often); None without a crossing in both. With the ``system`` both ran,
    the quotient distance at those crossings too."""
    if section is None:
        section = _section_mode(run)
        if section is None:
            return None
    mode = section if isinstance(section, str) else section.mode
    a, b = _crossings(run, section), _crossings(fine, section)
    pairs = _matched(a, b)
    if not pairs:
        return None
    names = run.state_names[mode]
    apart = np.array([np.abs(a[i][1] - b[j][1]) for i, j in pairs]).max(axis=0)
    state = {name: float(value) for name, value in zip(names, apart, strict=True) if math.isfinite(value)}
    phase = max(abs(a[i][0] - b[j][0]) for i, j in pairs)
    sizes = _sizes(fine)
    floor = ZERO_SIZE * max(sizes.values(), default=0.0)
    ratios = [value / sizes[name] for name, value in state.items() if sizes.get(name, 0.0) > floor]
    unmatched = len(a) + len(b) - 2 * len(pairs)
    relative = max(ratios) if ratios else None
    matched = [(mode, a[i][1], a[i][0], b[j][1], b[j][0]) for i, j in pairs]
    quotient, note = _in_quotient(
        system, run, lambda system, eps: float(crossing_distances(system, run, fine, matched, eps).max())
    )
    return AlongOrbit(mode, len(pairs), unmatched, phase, state, relative, _where(section), quotient, note)


def _crossings(execution: Execution, section: str | OrbitSection) -> list[Crossing]:
    if isinstance(section, str):
        return _entries(execution, section)
    if section.transition is not None:
        return takings(execution, section.transition, section.mode)
    assert section.function is not None  # OrbitSection holds one of the two
    found = returns(
        execution, section.mode, section.function, section.direction, section.min_transitions, section.min_time
    )
    return [(t, x) for _, t, x in found]


def _where(section: str | OrbitSection) -> str:
    if isinstance(section, str):
        return f"entries into '{section}'"
    if section.transition is not None:
        return f"takings of {section.transition} into '{section.mode}'"
    return f"crossings of {section.label}"


def _matched(a: list[tuple[float, np.ndarray]], b: list[tuple[float, np.ndarray]]) -> list[tuple[int, int]]:
    """Pairs (i, j) of entries a[i], b[j] nearest in time, in order: an entry one run makes and
    the other does not (a graze one of them takes) is left out rather than shifting every later
    pair by one. Each a[i] takes the nearest b[j] after the last one taken when that b[j] has
    no nearer a[i'] itself."""
    pairs: list[tuple[int, int]] = []
    j = 0
    for i, (t, _) in enumerate(a):
        while j + 1 < len(b) and abs(b[j + 1][0] - t) <= abs(b[j][0] - t):
            j += 1
        if j >= len(b):
            break
        nearest_a = min(range(len(a)), key=lambda k: abs(a[k][0] - b[j][0]))
        if nearest_a == i and (not pairs or pairs[-1][1] < j):
            pairs.append((i, j))
    return pairs


def _section_mode(run: Execution) -> str | None:
    entered: dict[str, int] = {}
    for seg in run.segments[1:]:
        entered[seg.mode] = entered.get(seg.mode, 0) + 1
    if not entered:
        return None
    first = run.segments[0].mode
    return first if first in entered else max(entered, key=entered.__getitem__)


def _entries(execution: Execution, mode: str) -> list[tuple[float, np.ndarray]]:
    """(time, state) at each entry into ``mode`` after the start: a segment's first point."""
    return [(float(seg.t[0]), seg.x[0]) for seg in execution.segments[1:] if seg.mode == mode and len(seg.t)]


def check_accuracy(
    system: HybridSystem,
    x0: Any,
    mode: str,
    t_final: float,
    h: float,
    eps: float,
    method: str | Tableau = "rk4",
    control: Callable[[float, np.ndarray], Any] | None = None,
    *,
    section: str | OrbitSection | None = None,
    **options: Any,
) -> tuple[Execution, ErrorEstimate]:
    """``simulate`` with these arguments, and the estimate of its error from a refined run (see
    ``refined``); ``section``: where the two are compared along the orbit (``along_orbit``).
    Returns (the execution, its ``ErrorEstimate``)."""
    from .relaxed import simulate

    run = simulate(system, x0, mode, t_final, h, eps, method, control, **options)
    fine_settings = refined({"h": h, "eps": eps, "rtol": options.get("rtol"), "atol": options.get("atol")})
    fine_options = {**options, "rtol": fine_settings["rtol"], "atol": fine_settings["atol"]}
    fine = simulate(
        system, x0, mode, t_final, fine_settings["h"], fine_settings["eps"], method, control, **fine_options
    )
    return run, compare(run, fine, system, section)


def _final_state(run: Execution, fine: Execution) -> tuple[dict[str, float], float | None]:
    names = run.state_names.get(run.final_mode, ())
    fine_names = fine.state_names.get(fine.final_mode, ())
    x, xf = run.final_state, fine.final_state
    index = {name: i for i, name in enumerate(fine_names)}
    out = {name: abs(float(x[i]) - float(xf[index[name]])) for i, name in enumerate(names) if name in index}
    if run.final_mode != fine.final_mode or not out:
        return out, None
    sizes = _sizes(fine)
    floor = ZERO_SIZE * max(sizes.values(), default=0.0)
    ratios = [value / sizes[name] for name, value in out.items() if sizes.get(name, 0.0) > floor]
    return out, (max(ratios) if ratios else None)


def _sizes(execution: Execution) -> dict[str, float]:
    """Each coordinate's largest |value| along the run (its size, for relative errors)."""
    sizes: dict[str, float] = {}
    for seg in execution.segments:
        finite = np.where(np.isfinite(seg.x), np.abs(seg.x), 0.0).max(axis=0)
        for name, value in zip(execution.state_names[seg.mode], finite, strict=True):
            sizes[name] = max(sizes.get(name, 0.0), float(value))
    return sizes


def _transition_times(run: Execution, fine: Execution) -> tuple[float | None, int, bool]:
    matched, worst = 0, 0.0
    # The runs may take different numbers of transitions: compare the common prefix, then say so.
    for a, b in zip(run.transitions, fine.transitions, strict=False):
        if a.name != b.name:
            break
        matched += 1
        worst = max(worst, abs(a.time - b.time))
    differ = matched != len(run.transitions) or len(run.transitions) != len(fine.transitions)
    return (worst if matched else None), matched, differ


def _trajectory(run: Execution, fine: Execution) -> tuple[dict[str, float], float]:
    t_end = min(run.t_end, fine.t_end)
    if not t_end > run.t0:
        return {}, 0.0
    times = np.linspace(run.t0, t_end, SAMPLES)
    a, b = run.sample(times), fine.sample(times)
    worst: dict[str, float] = {}
    mismatched = 0
    for mode_a, mode_b, xa, xb in zip(a.modes, b.modes, a.states, b.states, strict=True):
        if mode_a != mode_b:
            mismatched += 1
            continue
        for name, va, vb in zip(run.state_names[mode_a], xa, xb, strict=True):
            difference = abs(float(va) - float(vb))
            if not math.isnan(difference):
                worst[name] = max(worst.get(name, 0.0), difference)
    return worst, mismatched / len(times)
