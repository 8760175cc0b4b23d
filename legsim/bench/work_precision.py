"""Work-precision runs: every configuration of a case timed, its error measured, the results
written as CSV, a figure and a table, and the speed targets checked on the same run.

Error (paper 000 eq. (30)): the largest difference of the position coordinates from the
reference over the method's *own* sample points, i.e. the points it computed (the relaxed
integrator's step and crossing points, solve_ivp's steps and events, the PS grid). rho
(Definition 22) against the reference on a uniform time grid, for the relaxed runs, with the
run's own eps.

Time: wall-clock time of the call that produces the result (``simulate``, ``paoli_schatzman``),
or the integration time solve_ivp reports (``counters["wall_time_s"]``, which leaves out the
assembly of legsim's Execution, to the baseline's advantage); the median over repeats. Each
method is run once untimed first, so compilation and caches never count.
"""

from __future__ import annotations

import csv
import math
import os
import statistics
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..output.files import write_atomic
from ..progress import counting
from ..relaxed.simulate import MAX_STEPS
from ..tables import Table
from .cases import BenchError, Case, RunSpec, make_case, relaxed_method
from .rows import COLUMNS, Row, run_label

if TYPE_CHECKING:
    from .targets import Extension, TargetResult

#: Timed repeats of each run (the median is kept), and with ``quick``.
REPEATS, REPEATS_QUICK = 3, 1
#: Times of the rho grid where the case sets none, and with ``quick``.
RHO_POINTS, RHO_POINTS_QUICK = 400, 40


@dataclass
class BenchResult:
    """One bench run: its rows (the sweep, then any extension runs), the targets' verdicts, the
    extensions of the baselines' sweeps and the files written."""

    case: Case
    rows: list[Row]
    targets: list[TargetResult] = field(default_factory=list)
    csv_path: Path | None = None
    figure_path: Path | None = None
    extensions: list[Extension] = field(default_factory=list)


# ----------------------------------------------------------------------------------------------
# Errors
# ----------------------------------------------------------------------------------------------
def own_points(execution: Any, positions: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The (times (N,), positions (N, k)) an execution computed: all its segment points."""
    ts = [seg.t for seg in execution.segments]
    xs = [seg.x[:, list(positions)] for seg in execution.segments]
    return np.concatenate(ts), np.concatenate(xs)


def position_error(times: np.ndarray, values: np.ndarray, reference: Callable[[np.ndarray], np.ndarray]) -> float:
    """Eq. (30) of paper 000 over several position coordinates: max_k max_i |z_i(t_k) - x_i(t_k)|."""
    values = np.asarray(values, dtype=float).reshape(len(times), -1)
    exact = np.asarray(reference(np.asarray(times, dtype=float)), dtype=float).reshape(values.shape)
    diff = np.abs(values - exact)
    if not np.all(np.isfinite(diff)):
        return math.inf
    return float(diff.max()) if diff.size else math.inf


def relaxed_rho(case: Case, execution: Any, eps: float, points: int, system: Any = None) -> float:
    """rho^eps (paper 000 Def. 22) against the case's reference on ``points`` uniform times,
    in ``system`` (default: the case's)."""
    if points <= 0 or case.reference_execution is None or execution.status != "finished":
        return math.nan
    from ..metric import MetricError, rho

    times = np.linspace(0.0, case.t_final, points)
    try:
        return rho(system or case.system, execution, case.reference_execution, times, eps)
    except MetricError:
        return math.nan


# ----------------------------------------------------------------------------------------------
# Running one configuration
# ----------------------------------------------------------------------------------------------
def _timed(fn: Callable[[], Any], repeats: int, wall_of: Callable[[Any, float], float]) -> tuple[Any, float, int]:
    """Run fn up to ``repeats`` times (once only when it takes over a second); return the last
    result, the median time and the number of runs."""
    times = []
    result = None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = fn()
        times.append(wall_of(result, time.perf_counter() - start))
        if times[-1] > 1.0:
            break
    return result, float(statistics.median(times)), len(times)


def _ps_forcing(ps: dict[str, float]) -> Callable[[np.ndarray], np.ndarray]:
    amplitude, frequency, inv_m = ps["amplitude"], ps["frequency"], 1.0 / ps["mass"]
    return lambda t: amplitude * inv_m * np.cos(frequency * t)


def run_one(case: Case, spec: RunSpec, repeats: int = 3, rho_points: int = 0) -> Row:
    """Run one configuration of ``case`` and measure it."""
    runners = {"relaxed": _run_relaxed, "solve_ivp": _run_solve_ivp, "ps": _run_ps}
    if spec.kind not in runners:
        raise BenchError(f"unknown run kind {spec.kind!r}")
    return runners[spec.kind](case, spec, repeats, rho_points)


def _row(case: Case, spec: RunSpec, ex: Any, error: float, wall: float, repeats: int, **fields: Any) -> Row:
    """The row of a run of the relaxed integrator or solve_ivp: its settings, ``error`` (inf
    unless it finished), wall time and counters; ``fields`` override the settings' columns."""
    c = ex.counters
    columns: dict[str, Any] = {
        "case": case.name, "method": spec.method, "kind": spec.kind, "h": spec.h, "eps": spec.eps,
        "tol": spec.tol, "max_step": math.nan, "landing": spec.landing, "error": error, "rho": math.nan,
        "wall_s": wall, "repeats": repeats, "steps": int(c["steps"]), "halvings": int(c.get("halvings", 0)),
        "field_evals": int(c["field_evals"]), "guard_evals": int(c["guard_evals"]),
        "transitions": int(c["transitions"]), "status": ex.status,
    }  # fmt: skip
    return Row(**{**columns, **fields})


def _run_relaxed(case: Case, spec: RunSpec, repeats: int, rho_points: int) -> Row:
    from ..relaxed import simulate

    method = relaxed_method(spec.method[len("relaxed-") :])
    tol = None if math.isnan(spec.tol) else spec.tol
    system, control = case.system, case.control
    if spec.zeno:
        if case.zeno_system is None:
            raise BenchError(f"case {case.name} has no Zeno continuation variant (oscillator-ex2 only)")
        system, control = case.zeno_system
    # The sweep's finest fixed steps are meant to be long (Ex.1's Euler at h = 1e-5 is 1.3e7
    # steps): the budget is twice the nominal count, never below simulate's default.
    budget = max(MAX_STEPS, 2 * math.ceil(case.t_final / spec.h))

    def call() -> Any:
        return simulate(system, case.x0, case.mode, case.t_final, spec.h, spec.eps, method, control,
                        max_transitions=case.max_transitions, landing=spec.landing, continuation=spec.zeno,
                        max_steps=budget, rtol=tol, atol=tol)  # fmt: skip

    ex, wall, n = _timed(call, repeats, lambda r, dt: dt)
    if ex.status != "finished":
        return _row(case, spec, ex, math.inf, wall, n)
    error = position_error(*own_points(ex, case.positions), case.reference_positions)
    # rho of a Zeno run is left out (nan): its mode 'stuck' is not a mode of the reference
    # execution, so the metric puts the two infinitely far apart while the mass rests.
    rho_value = math.nan if spec.zeno else relaxed_rho(case, ex, spec.eps, rho_points, system)
    return _row(case, spec, ex, error, wall, n, rho=rho_value)


def _run_solve_ivp(case: Case, spec: RunSpec, repeats: int, rho_points: int) -> Row:
    from ..baselines import simulate_events

    method = spec.method[len("solve_ivp-") :]

    def call() -> Any:
        return simulate_events(case.ivp_system, case.x0, case.mode, case.t_final, method=method, rtol=spec.tol,
                               atol=spec.tol, max_transitions=10_000, max_step=spec.max_step,
                               control=case.control)  # fmt: skip

    ex, wall, n = _timed(call, repeats, lambda r, dt: float(r.counters["wall_time_s"]))
    finished = ex.status == "finished"
    error = position_error(*own_points(ex, case.positions), case.reference_positions) if finished else math.inf
    return _row(case, spec, ex, error, wall, n, h=math.nan, eps=math.nan, max_step=spec.max_step, landing="",
                halvings=0)  # fmt: skip


def _run_ps(case: Case, spec: RunSpec, repeats: int, rho_points: int) -> Row:
    from ..baselines import paoli_schatzman

    if case.ps is None:
        raise BenchError(f"case {case.name} has no Paoli-Schatzman baseline (oscillator cases only)")
    ps = case.ps
    forcing = _ps_forcing(ps)

    def call() -> Any:
        return paoli_schatzman(ps["a"], ps["omega"], ps["c"], ps["x_max"], forcing, ps["x0"], ps["xd0"],
                               case.t_final, spec.h, compiled=True)  # fmt: skip

    (t, z), wall, n = _timed(call, repeats, lambda r, dt: dt)
    error = position_error(t, z[:, None], case.reference_positions)
    return Row(case.name, "ps", "ps", spec.h, math.nan, math.nan, math.nan, "", error, math.nan, wall, n,
               len(t) - 1, 0, len(t), 0, 0, "finished")  # fmt: skip


def warm_up(case: Case, specs: Iterable[RunSpec]) -> None:
    """One short untimed run per method, so that compilation and first-call costs never count."""
    seen = set()
    short = dict(case.__dict__)
    short["t_final"] = min(case.t_final, 0.05)
    tiny = Case(**short)
    for spec in specs:
        if spec.method in seen:
            continue
        seen.add(spec.method)
        h = spec.h if math.isnan(spec.h) else min(spec.h, 0.01)
        try:
            run_one(tiny, replace(spec, h=h), repeats=1)
        except BenchError:
            raise
        except Exception:  # the timed run will report the problem with its own status
            pass


# ----------------------------------------------------------------------------------------------
# Reading the rows
# ----------------------------------------------------------------------------------------------
def mark_pareto(rows: list[Row]) -> None:
    """Set ``pareto = 1`` on the runs no other run beats in both time and error."""
    finite = sorted((r for r in rows if math.isfinite(r.error)), key=lambda r: (r.wall_s, r.error))
    best = math.inf
    for r in rows:
        r.pareto = 0
    for r in finite:
        if r.error < best:
            r.pareto = 1
            best = r.error


def family(row: Row) -> str:
    """``relaxed``, ``ps`` or ``solve_ivp``."""
    return row.kind


# ----------------------------------------------------------------------------------------------
# Output
# ----------------------------------------------------------------------------------------------
def write_csv(rows: Sequence[Row], path: Path) -> Path:
    """One row per run, columns ``COLUMNS``; written completely or not at all."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            for r in rows:
                d = asdict(r)
                w.writerow([_fmt_csv(d[c]) for c in COLUMNS])

    return write_atomic(path, write, what="bench CSV")


def _fmt_csv(v: Any) -> Any:
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return v


def read_rows(path: str | os.PathLike) -> list[Row]:
    """The rows of a CSV written by ``write_csv``."""
    path = Path(path)
    if not path.exists():
        raise BenchError(f"{path}: no such bench CSV (run `legsim bench work-precision` first)")
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        if tuple(reader.fieldnames or ()) != COLUMNS:
            raise BenchError(f"{path}: not a bench CSV (columns {reader.fieldnames}, expected {list(COLUMNS)})")
        return [_parsed_row(path, reader.line_num, line) for line in reader]


def _parsed_row(path: Path, line_number: int, line: dict[str, Any]) -> Row:
    """The Row of one CSV line; BenchError naming the file, line and column of a value that is
    missing or not of the column's type (a truncated or hand-edited file)."""
    values: dict[str, Any] = {}
    for name, kind in Row.__annotations__.items():
        text = line.get(name)
        try:
            if text is None:
                raise ValueError("missing (the line ends early)")
            if kind == "float":
                values[name] = math.nan if text == "" else float(text)
            elif kind == "int":
                values[name] = int(text)
            else:
                values[name] = text
        except ValueError as exc:
            raise BenchError(f"{path}, line {line_number}, column {name}: not a bench value ({exc})") from None
    return Row(**values)


def write_figure(result: BenchResult, path: Path) -> Path:
    """Error against wall time (log-log): each method's runs as points, its own Pareto front as
    a line, the overall Pareto front dashed in black."""
    return plot_rows(result.rows, path, f"{result.case.name}: work-precision", "position error, eq. (30)")


def plot_rows(all_rows: Sequence[Row], path: Path, title: str, ylabel: str) -> Path:
    """The work-precision figure of ``all_rows`` (see ``write_figure``) written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in all_rows if math.isfinite(r.error) and r.error > 0]
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    methods = sorted({r.method for r in rows}, key=lambda m: (not m.startswith("relaxed"), m))
    cmap = plt.get_cmap("tab10")
    for i, m in enumerate(methods):
        pts = sorted((r for r in rows if r.method == m), key=lambda r: r.wall_s)
        color = cmap(i % 10)
        ax.scatter([r.wall_s for r in pts], [r.error for r in pts], s=14, color=color, alpha=0.45)
        front, best = [], math.inf
        for r in pts:
            if r.error < best:
                front.append(r)
                best = r.error
        ax.plot([r.wall_s for r in front], [r.error for r in front], "-o", ms=3.5, color=color, label=m)
    pareto = sorted((r for r in rows if r.pareto), key=lambda r: r.wall_s)
    if pareto:
        ax.step(
            [r.wall_s for r in pareto],
            [r.error for r in pareto],
            where="post",
            color="k",
            ls="--",
            lw=1.2,
            label="Pareto front (all methods)",
        )
        ax.scatter([r.wall_s for r in pareto], [r.error for r in pareto], s=60, facecolors="none", edgecolors="k")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time (s), median of repeats")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    try:
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), what="bench figure")
    finally:
        plt.close(fig)


def rows_table(rows: Sequence[Row]) -> Table:
    """The rows as a table (``legsim.tables``), sorted by method then error; the method names
    and numbers never wrap, the status wraps at spaces."""
    head = (
        "method",
        "h",
        "eps",
        "tol",
        "max_step",
        "error",
        "rho",
        "wall_s",
        "steps",
        "halv",
        "f_evals",
        "trans",
        "status",
        "P",
    )
    body = []
    for r in sorted(rows, key=lambda r: (r.method, -r.error if math.isfinite(r.error) else -math.inf)):
        body.append(
            (
                r.method,
                _g(r.h),
                _g(r.eps),
                _g(r.tol),
                "" if math.isinf(r.max_step) else _g(r.max_step),
                _e(r.error),
                _e(r.rho),
                f"{r.wall_s:.4g}",
                str(r.steps),
                str(r.halvings),
                str(r.field_evals),
                str(r.transitions),
                r.status,
                "*" if r.pareto else "",
            )
        )
    return Table.of(head, body, right=range(1, 12), whole=(*range(0, 12), 13), title="runs")


def format_table(rows: Sequence[Row], width: int | None = None) -> str:
    """The rows as a text table (``rows_table``) within ``width`` characters where its words
    allow (None: one line per row)."""
    return rows_table(rows).text(width)


def _g(v: float) -> str:
    return "" if math.isnan(v) else f"{v:g}"


def _e(v: float) -> str:
    return "" if math.isnan(v) else ("inf" if math.isinf(v) else f"{v:.2e}")


# ----------------------------------------------------------------------------------------------
# The whole bench
# ----------------------------------------------------------------------------------------------
def run_case(
    name: str,
    *,
    quick: bool = False,
    out: str | os.PathLike | None = None,
    repeats: int | None = None,
    rho_points: int | None = None,
    figure: bool = True,
    log: Callable[[str], None] | None = None,
    methods: Sequence[str] | None = None,
    extension_budget: float | None = None,
) -> BenchResult:
    """Run the work-precision sweep of case ``name``, extend the baselines' sweeps where they
    miss a target's level (``legsim.bench.targets.extend_baselines``), judge the targets; write
    ``out/name.csv`` (every run, extensions included) and ``out/name.png`` when ``out`` is given.

    quick: a short run and a small sweep (seconds), for CI. repeats: timed repeats per run
    (median; default ``REPEATS``, ``REPEATS_QUICK`` when quick). rho_points: times of the rho
    grid (default the case's, else ``RHO_POINTS``, ``RHO_POINTS_QUICK`` when quick; 0 skips
    rho). methods: keep only the runs of these CSV method names; a name the case has no run of,
    given with names it has, is an error (a typo must not shrink the sweep unseen).
    extension_budget: wall time (s) the extensions may take (default ``EXTENSION_BUDGET``, or
    ``EXTENSION_BUDGET_QUICK`` when quick; 0 extends nothing).
    """
    from .targets import EXTENSION_BUDGET, EXTENSION_BUDGET_QUICK, evaluate_targets, extend_baselines

    say = log or (lambda s: None)
    case = make_case(name, quick)
    repeats = (REPEATS_QUICK if quick else REPEATS) if repeats is None else int(repeats)
    if rho_points is None:
        rho_points = case.rho_points if case.rho_points is not None else (RHO_POINTS_QUICK if quick else RHO_POINTS)
    rho_points = int(rho_points)
    if extension_budget is None:
        extension_budget = EXTENSION_BUDGET_QUICK if quick else EXTENSION_BUDGET
    if not extension_budget >= 0:
        raise BenchError(f"the extension budget must be >= 0 s, got {extension_budget!r}")
    runs = [r for r in case.runs if methods is None or r.method in methods]
    available = sorted({r.method for r in case.runs})
    unknown = sorted(set(methods or ()) - set(available))
    if runs and unknown:
        raise BenchError(f"case {case.name} has no run of method(s) {unknown}; its methods: {', '.join(available)}")
    say(f"{case.name}: {case.description}")
    say(f"reference: {case.reference_note}")
    warm_up(case, runs)
    rows = []
    # The bar (with its ETA) only when progress is reported at all, and only on a terminal.
    with counting(len(runs), case.name, enabled=log is not None) as advance:
        for i, spec in enumerate(runs, 1):
            row = run_one(case, spec, repeats, rho_points)
            rows.append(row)
            say(f"  [{i}/{len(runs)}] {run_label(row)}: error {_e(row.error)}, {row.wall_s:.4g} s, {row.status}")
            advance(1)
    extensions = extend_baselines(
        case, rows, case.targets, extension_budget, lambda spec: run_one(case, spec, repeats, rho_points), say
    )
    rows += [row for ext in extensions for row in ext.rows]
    mark_pareto(rows)
    notes = {ext.kind: ext.describe() for ext in extensions}
    result = BenchResult(case, rows, evaluate_targets(rows, case.targets, notes), extensions=extensions)
    if out is not None:
        out = Path(out)
        result.csv_path = write_csv(rows, out / f"{case.name}.csv")
        if figure:
            result.figure_path = write_figure(result, out / f"{case.name}.png")
    return result
