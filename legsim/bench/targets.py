"""Speed targets: their verdicts on the rows of one bench run, and the extension of a baseline's
sweep towards a level it never reached.

A target asks that, at error <= level, the baseline family's fastest time over the relaxed
integrator's fastest time be at least ``ratio``. Its verdict is one of:

* ``MET``: both sides reach the level and the measured ratio is at or above the target;
* ``MISSED``: both reach it and the ratio is below the target, or the relaxed integrator never
  reaches the level;
* ``NOT COMPARABLE``: the relaxed integrator reaches the level but the baseline does not (even
  after its sweep was extended), or no baseline run is in the sweep. There is no ratio at the
  level then; the verdict reports the finest error both reach and the ratio there, which says
  how the two compare but does not meet the target.

A target is met only by a ratio measured at its level. Where the baseline never reaches the
level, ``extend_baselines`` first refines the baseline's sweep (Paoli-Schatzman's step halved,
solve_ivp's tolerance divided by 10, for each of its configurations) until a run reaches it,
the error stops falling, the settings leave their range, or the time budget is spent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .cases import RunSpec, Target
from .rows import Row, run_label, time_to_reach

if TYPE_CHECKING:
    from .cases import Case

MET, MISSED, NOT_COMPARABLE = "MET", "MISSED", "NOT COMPARABLE"

#: Most grid points of an extended Paoli-Schatzman run: PS keeps every point, and the error
#: against the reference holds about 80 bytes per point (a 5e7-point run needs ~4 GB; the
#: largest run of the bundled sweeps has 4.2e7).
MAX_PS_POINTS = 50_000_000

#: Finest solve_ivp tolerance of an extension: scipy raises any rtol below 100 machine epsilons
#: to that value, so a finer one would repeat the same run.
MIN_IVP_TOL = 100 * float(np.finfo(float).eps)

#: Extension runs in a row whose error does not fall below the family's best before the
#: family is given up (rounding: Paoli-Schatzman's error rises again below some step).
MAX_NON_IMPROVING = 2

#: Default wall-time budget (s) of the extensions of one bench run: full and quick.
EXTENSION_BUDGET = 60.0
EXTENSION_BUDGET_QUICK = 3.0


@dataclass
class TargetResult:
    """A target judged on the rows of one bench run.

    verdict: ``MET``, ``MISSED`` or ``NOT COMPARABLE`` (module docstring); ``met`` is True,
    False or None for them. relaxed_time, baseline_time (s) and their runs' labels: the fastest
    run of each side with error <= level (None and "" where a side never reaches it). ratio:
    baseline_time / relaxed_time, None unless both reach the level. common_level: the finest
    error both sides reach when one does not reach the level (None otherwise or without runs),
    common_ratio: the ratio of their fastest times at that error. notes: how the rows were read
    (extensions, Zeno continuation, best errors), one sentence each.
    """

    target: Target
    verdict: str
    relaxed_time: float | None
    relaxed_run: str
    baseline_time: float | None
    baseline_run: str
    ratio: float | None
    common_level: float | None = None
    common_ratio: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def met(self) -> bool | None:
        """True for MET, False for MISSED, None when not comparable."""
        return {MET: True, MISSED: False}.get(self.verdict)

    @property
    def note(self) -> str:
        """The notes in one line."""
        return "; ".join(self.notes)


_VARIANTS = {"all": ("plain", "zeno"), "plain": ("plain",), "zeno": ("zeno",)}


def relaxed_variant(row: Row) -> str:
    """``zeno`` for a Zeno-continuation run (method ``relaxed-<name>-zeno``), else ``plain``."""
    return "zeno" if row.method.endswith("-zeno") else "plain"


def _competing(rows: Iterable[Row], tg: Target) -> list[Row]:
    """The target's relaxed runs (its variant) and its baseline's runs."""
    return [
        r
        for r in rows
        if (r.kind == "relaxed" and relaxed_variant(r) in _VARIANTS[tg.relaxed]) or r.kind == tg.baseline
    ]


def _best(rows: Iterable[Row], kind: str) -> Row | None:
    """The run of ``kind`` with the smallest finite error, or None."""
    return min((r for r in rows if r.kind == kind and math.isfinite(r.error)), key=lambda r: r.error, default=None)


def evaluate_targets(
    rows: Sequence[Row], targets: Sequence[Target], notes: Mapping[str, str] | None = None
) -> list[TargetResult]:
    """Each target's verdict on these rows. ``notes``: a line per baseline kind to add to its
    targets' notes (how its sweep was extended)."""
    return [_judge(_competing(rows, tg), tg, (notes or {}).get(tg.baseline, "")) for tg in targets]


def _judge(rows: list[Row], tg: Target, extension_note: str) -> TargetResult:
    rel = time_to_reach(rows, tg.level, "relaxed")
    base = time_to_reach(rows, tg.level, tg.baseline)
    notes = [extension_note]
    if rel is not None and relaxed_variant(rel) == "zeno":
        notes.append(
            "the relaxed run takes the model's Zeno continuation (simulate's default, window = h + eps; the "
            "plain runs pass continuation=False)"
        )
    result = TargetResult(
        tg,
        NOT_COMPARABLE,
        rel.wall_s if rel else None,
        run_label(rel) if rel else "",
        base.wall_s if base else None,
        run_label(base) if base else "",
        None,
    )
    if rel is not None and base is not None:
        result.ratio = base.wall_s / rel.wall_s
        result.verdict = MET if result.ratio >= tg.ratio else MISSED
    else:
        if rel is None:
            result.verdict = MISSED
        notes += _common_level(rows, tg, result)
    result.notes = [n for n in notes if n]
    return result


def _common_level(rows: list[Row], tg: Target, result: TargetResult) -> list[str]:
    """Fill ``common_level`` and ``common_ratio`` (the finest error both sides reach); the notes
    say each side's best error where it misses the level, and the comparison there."""
    said = []
    best = {kind: _best(rows, kind) for kind in ("relaxed", tg.baseline)}
    for kind, row in best.items():
        if row is None:
            said.append(f"no {kind} run finished")
        elif row.error > tg.level:
            said.append(f"{kind} never reaches {tg.level:g}: its best error is {row.error:.3g} ({run_label(row)})")
    best_relaxed, best_baseline = best["relaxed"], best[tg.baseline]
    if best_relaxed is not None and best_baseline is not None:
        level = max(best_relaxed.error, best_baseline.error)
        rel, base = time_to_reach(rows, level, "relaxed"), time_to_reach(rows, level, tg.baseline)
        assert rel is not None and base is not None  # each side's best run reaches the coarser level
        result.common_level, result.common_ratio = level, base.wall_s / rel.wall_s
        said.append(
            f"at {level:.3g}, the finest error both reach: {tg.baseline} {base.wall_s:.4g} s "
            f"({run_label(base)}), relaxed {rel.wall_s:.4g} s ({run_label(rel)}), "
            f"ratio {result.common_ratio:.3g}x"
        )
    return said


def format_targets(results: Sequence[TargetResult]) -> str:
    """One verdict line per target, then its runs and notes, indented."""
    lines = []
    for tr in results:
        lines.append(f"- {tr.target.name}: {verdict_line(tr)}")
        if tr.relaxed_run:
            lines.append(f"    relaxed  {tr.relaxed_time:.4g} s  {tr.relaxed_run}")
        if tr.baseline_run:
            lines.append(f"    baseline {tr.baseline_time:.4g} s  {tr.baseline_run}")
        lines += [f"    {note}" for note in tr.notes]
    return "\n".join(lines)


def verdict_line(tr: TargetResult) -> str:
    """The verdict and the numbers it rests on, e.g. ``MET: 51.6x >= 1x at error <= 1e-06``."""
    tg = tr.target
    if tr.ratio is not None:
        sign = ">=" if tr.verdict == MET else "<"
        return f"{tr.verdict}: {tr.ratio:.3g}x {sign} {tg.ratio:g}x at error <= {tg.level:g}"
    if tr.relaxed_time is None:
        return f"{MISSED}: relaxed never reaches error {tg.level:g}"
    if tr.common_level is None:
        return f"{NOT_COMPARABLE}: no {tg.baseline} run in the sweep finished"
    return (
        f"{NOT_COMPARABLE}: {tg.baseline} never reaches error {tg.level:g}; at {tr.common_level:.3g}, the finest "
        f"error both reach, {tr.common_ratio:.3g}x (target {tg.ratio:g}x at {tg.level:g})"
    )


# ----------------------------------------------------------------------------------------------
# Extending a baseline's sweep
# ----------------------------------------------------------------------------------------------
@dataclass
class Extension:
    """The extension of one baseline kind's sweep towards ``level``: the runs it added and why
    it stopped."""

    kind: str
    level: float
    rows: list[Row] = field(default_factory=list)
    stopped: str = ""

    def describe(self) -> str:
        """One line for the targets' notes."""
        if not self.rows:
            return f"{self.kind} sweep not extended towards {self.level:g}: {self.stopped}"
        return f"{self.kind} sweep extended by {len(self.rows)} run(s) towards {self.level:g}: {self.stopped}"


def levels_to_extend(rows: Sequence[Row], targets: Sequence[Target]) -> dict[str, float]:
    """For each baseline kind, the finest target level the relaxed runs reach and it does not."""
    levels: dict[str, float] = {}
    for tg in targets:
        competing = _competing(rows, tg)
        if time_to_reach(competing, tg.level, "relaxed") is None or time_to_reach(competing, tg.level, tg.baseline):
            continue
        if any(r.kind == tg.baseline for r in rows):
            levels[tg.baseline] = min(tg.level, levels.get(tg.baseline, math.inf))
    return levels


def finer(case: Case, row: Row) -> RunSpec | str:
    """The next finer configuration of a baseline run (PS: h / 2; solve_ivp: tol / 10 with its
    method and max_step), or why there is none."""
    if row.kind == "ps":
        h = row.h / 2
        if case.t_final / h > MAX_PS_POINTS:
            return f"h = {h:g} s would take {case.t_final / h:.2g} PS points, more than {MAX_PS_POINTS:.0e}"
        return RunSpec("ps", "ps", h)
    if row.kind == "solve_ivp":
        tol = row.tol / 10
        if tol < MIN_IVP_TOL:
            return f"tolerances below {MIN_IVP_TOL:.2g} are raised to it by scipy"
        return RunSpec("solve_ivp", row.method, math.nan, math.nan, tol, "", row.max_step)
    return f"no finer setting for a {row.kind} run"


def _families(rows: Sequence[Row], kind: str) -> list[list[Row]]:
    """The runs of a baseline kind grouped by configuration family, finest run last: PS over its
    step; solve_ivp by (method, max_step) over its tolerance."""
    groups: dict[tuple, list[Row]] = {}
    for r in rows:
        if r.kind == kind:
            groups.setdefault((r.method,) if kind == "ps" else (r.method, r.max_step), []).append(r)
    knob = (lambda r: -r.h) if kind == "ps" else (lambda r: -r.tol)
    return [sorted(group, key=knob) for group in groups.values()]


def extend_baselines(
    case: Case,
    rows: Sequence[Row],
    targets: Sequence[Target],
    budget: float,
    run: Callable[[RunSpec], Row],
    say: Callable[[str], None] = lambda s: None,
) -> list[Extension]:
    """Refine each baseline's sweep (``finer``) towards the finest level it misses and the relaxed
    runs reach (``levels_to_extend``), family by family, until a run reaches it, the family's
    error has not fallen for ``MAX_NON_IMPROVING`` runs, no finer setting exists, or the next run
    (guessed to cost twice the last) would pass ``budget`` seconds of wall time in all (0: no
    extension). ``run(spec) -> Row`` runs and measures one configuration."""
    if budget <= 0:
        return []
    extensions = []
    start = time.perf_counter()
    for kind, level in levels_to_extend(rows, targets).items():
        ext = Extension(kind, level)
        reasons = []
        for group in _families(rows, kind):
            best = min(r.error for r in group)
            left = budget - (time.perf_counter() - start)
            reasons.append(_extend_family(case, group[-1], best, ext, left, run, say))
            if reasons[-1] == "reached":
                break
        ext.stopped = _why(ext, reasons, budget)
        extensions.append(ext)
    return extensions


def _extend_family(
    case: Case,
    row: Row,
    best: float,
    ext: Extension,
    budget: float,
    run: Callable[[RunSpec], Row],
    say: Callable[[str], None],
) -> str:
    """Refine one family from its finest run ``row``; the runs go to ``ext.rows``. Returns why it
    stopped: ``reached``, ``budget``, ``floor`` (the error stopped falling) or the reason
    ``finer`` gives."""
    spent, last_cost, misses = 0.0, row.wall_s, 0
    while True:
        spec = finer(case, row)
        if isinstance(spec, str):
            return spec
        if spent + 2 * last_cost > budget:
            return "budget"
        began = time.perf_counter()
        row = run(spec)
        last_cost = time.perf_counter() - began
        spent += last_cost
        ext.rows.append(row)
        say(f"  [extension] {run_label(row)}: error {row.error:.2e}, {row.wall_s:.4g} s, {row.status}")
        if row.error <= ext.level:
            return "reached"
        misses = 0 if row.error < best else misses + 1
        best = min(best, row.error)
        if misses >= MAX_NON_IMPROVING:
            return "floor"


def _why(ext: Extension, reasons: list[str], budget: float) -> str:
    if "reached" in reasons:
        return f"reached it ({next(r for r in ext.rows if r.error <= ext.level).error:.3g})"
    said = {
        "budget": f"the time budget of {budget:g} s is spent",
        "floor": f"the error stopped falling ({MAX_NON_IMPROVING} finer runs without improvement)",
    }
    unique = list(dict.fromkeys(said.get(r, r) for r in reasons))
    return "not reached: " + "; ".join(unique)
