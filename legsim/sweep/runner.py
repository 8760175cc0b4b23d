"""Running a sweep: check it, start the engine, stream the rows to the table, draw the maps."""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa

from ..progress import counting
from .engine import Engine
from .measures import check_coordinates, check_measures, check_windows
from .spec import SweepError, SweepSpec, corners, variation_overrides
from .table import FIGURES, ResultStore, schema, to_table, with_rows_digest
from .tasks import run_batch


@dataclass
class SweepResult:
    """A finished (or resumed) sweep.

    table: every row, sorted by index (``legsim.sweep.table`` lists the columns); results: the
    Parquet file (None without an output folder); figures: kind -> file; computed: rows run this
    time; resumed: rows already done; elapsed_s: wall time of this run once the engine was up
    (s); startup_s: starting or reaching the engine (s); where: the engine.
    """

    spec: SweepSpec
    table: pa.Table
    results: Path | None
    computed: int
    resumed: int
    elapsed_s: float
    where: str
    startup_s: float = 0.0
    figures: dict[str, Path] = field(default_factory=dict)

    def counts(self, column: str) -> dict[str, int]:
        """How many rows hold each value of a column (``task_status``, ``outcome``, ...)."""
        if column not in self.table.column_names:
            return {}
        return dict(Counter(v for v in self.table.column(column).to_pylist() if v is not None))

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary of the sweep (``legsim sweep --json``)."""
        out = {
            "scene": self.spec.scene,
            "variations": len(self.spec),
            "computed": self.computed,
            "resumed": self.resumed,
            "elapsed_s": self.elapsed_s,
            "startup_s": self.startup_s,
            "where": self.where,
            "task_status": self.counts("task_status"),
            "results": None if self.results is None else str(self.results),
            "figures": {k: str(v) for k, v in self.figures.items()},
        }
        for column in ("status", "outcome", "orbit_status", "orbit_stable"):
            if column in self.table.column_names:
                out[column] = {str(k): v for k, v in self.counts(column).items()}
        out["warned"] = {
            column: sum(1 for texts in self.table.column(column).to_pylist() if texts)
            for column in ("warnings", "orbit_warnings")
            if column in self.table.column_names
        }
        return out


def run_sweep(
    spec: SweepSpec,
    *,
    out: str | Path | None = None,
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    in_process: bool = False,
    batch_size: int | None = None,
    progress: bool = False,
    figures: bool = True,
    log: Callable[[str], None] | None = None,
    connect_timeout: float | None = None,
) -> SweepResult:
    """Run every variation of ``spec`` not done yet (see ``legsim.sweep.sweep`` for the arguments)."""
    fixed_point, inputs = check_sweep(spec)
    spec = spec.with_inputs(inputs)
    store = ResultStore(out, spec) if out is not None else None
    with store.claim() if store is not None else contextlib.nullcontext():
        return _run_claimed(
            spec,
            store,
            fixed_point,
            resume,
            figures,
            log,
            progress,
            Engine(workers, scheduler, in_process, batch_size, connect_timeout=connect_timeout),
        )


def _run_claimed(
    spec: SweepSpec,
    store: ResultStore | None,
    fixed_point: dict[str, float] | None,
    resume: bool,
    figures: bool,
    log: Callable[[str], None] | None,
    progress: bool,
    engine: Engine,
) -> SweepResult:
    """``run_sweep`` once its folder (if any) is claimed."""
    done = store.prepare(resume) if store is not None else set()
    todo = [i for i in range(len(spec)) if i not in done]
    rows: list[dict[str, Any]] = []
    start = time.perf_counter()
    if not todo:
        engine = Engine(in_process=True)
    with engine:
        startup = time.perf_counter() - start
        start = time.perf_counter()
        if log is not None:
            log(f"{len(todo)} of {len(spec)} variation(s) to run on {engine.where}")
        if store is not None:
            store.start()
        with counting(len(spec), "sweep", done=len(done), enabled=progress) as advance:

            def on_done(batch: list[Any], results: Any) -> None:
                if isinstance(results, BaseException):
                    results = [failed_row(index, values, results) for index, values in batch]
                if store is not None:
                    store.add(results)
                else:
                    rows.extend(results)
                advance(len(results))

            try:
                engine.run(run_batch, spec, list(spec.items(todo)), on_done)
            finally:
                # Interrupted or not, the rows finished so far make the table.
                table = (
                    store.assemble()
                    if store is not None
                    else with_rows_digest(to_table(sorted(rows, key=_index), schema(spec)))
                )
    result = SweepResult(
        spec,
        table,
        None if store is None else store.results,
        len(todo),
        len(done),
        time.perf_counter() - start,
        engine.where,
        startup,
    )
    if store is not None and figures:
        result.figures = write_figures(result, store.folder, fixed_point)
    return result


def _index(row: dict[str, Any]) -> int:
    return int(row["index"])


def failed_row(index: int, values: dict[str, Any], exc: BaseException) -> dict[str, Any]:
    """The row of a variation whose whole batch failed on its worker (a worker that died)."""
    return {
        "index": index,
        **values,
        "task_status": "error",
        "error": f"the batch failed on its worker: {type(exc).__name__}: {exc}",
    }


def check_sweep(spec: SweepSpec) -> tuple[dict[str, float] | None, list[Path]]:
    """Load the scene at every axis's ends, so that a wrong field or value is reported before
    anything runs. Returns, for a walk, the reference gait of the scene (its fixed point by
    coordinate, None when the walks vary the model, each then finding its own), and the files
    the scene reads (``Scene.input_files``)."""
    base = _checked_base(spec)
    files = base.input_files()
    if spec.run != "walk" or any(not k.startswith("initial.") for k in spec.keys):
        return None, files
    from .tasks import reference_gait

    gait = reference_gait(spec, {})
    if not gait.converged:
        raise SweepError(
            f"{base.path}: the walks need the scene's gait, and its orbit search ended with "
            f"{gait.status}: {gait.message}"
        )
    return dict(zip(gait.state_names, (float(v) for v in gait.fixed_point), strict=True)), files


def _checked_base(spec: SweepSpec) -> Any:
    """The scene of the sweep's first variation (its overrides, then every axis at its first
    value: an override may need an axis's value to be complete, as ``terrain.kind=slope`` needs
    a ``terrain.angle`` axis), every axis's values and the measures checked."""
    from ..scene import load_scene
    from ..scene.orbit import problem_from_scene

    measures = check_measures(spec.measures)
    base = None
    for values in corners(spec):
        corner = load_scene(spec.scene, list(spec.overrides) + variation_overrides(values))
        check_windows(measures, corner.integrator["t0"], corner.integrator["t_final"], corner.path)
        base = corner if base is None else base
    assert base is not None, "corners yields the first variation first"
    if spec.run == "walk" or spec.orbit:
        problem_from_scene(base)  # the [orbit] section is there and valid
    if measures:
        check_coordinates(measures, base.model.system, base.path)
    return base


def write_figures(result: SweepResult, folder: Path, fixed_point: dict[str, float] | None) -> dict[str, Path]:
    """The maps of a sweep over a two-axis grid: the basin of attraction of walks, the stability
    map of orbit searches (``legsim.viz.maps``, found through the ``legsim.writers`` entry
    points); none for other shapes."""
    spec = result.spec
    if len(spec.grid) != 2 or spec.random:
        return {}
    from ..output.files import write_atomic
    from ..output.writers import find_writer

    wanted = [
        kind
        for kind in ("walk", "orbit")
        if (kind == "walk" and spec.run == "walk") or (kind == "orbit" and spec.orbit)
    ]
    written = {}
    info = {"x": spec.grid[0].key, "y": spec.grid[1].key, "fixed_point": fixed_point, "scene": spec.scene}
    for kind in wanted:
        name, filename = FIGURES[kind]
        writer = find_writer(name, f"the {name} figure")

        def write(tmp: Path, writer: Callable[[Any, Any, Path], Any] = writer) -> object:
            return writer(result.table, info, tmp)

        written[name] = write_atomic(folder / filename, write, what=f"--out {name} figure")
    return written
