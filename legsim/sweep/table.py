"""The sweep's results on disk: one Parquet row per variation, streamed as batches finish.

Each finished batch is written at once as its own Parquet file in ``DIR/results.parts/``
(atomically: complete or absent), so a sweep killed at any moment loses only the batches still
running; ``DIR/results.parquet`` is assembled from them (and from an earlier table when
resuming), sorted by ``index``, when the sweep ends or is interrupted. ``--resume`` reads the
indices already in either and runs only the others.

Columns (``schema``): ``index``, one column per varied field (named by its dotted path), then
``task_status`` (``done``, ``error``, ``timeout``) and ``error`` (the message, null when done),
the measures' columns (``RUN_COLUMNS``, ``WALK_COLUMNS``, ``ORBIT_COLUMNS``, as asked) and
``wall_time_s`` (the variation's wall time on its worker, s). Every column but
``wall_time_s`` depends only on the sweep's specification: two runs of one sweep, wherever they
ran and however they were batched, give the same table up to that column.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, cast

import pyarrow as pa
import pyarrow.parquet as pq

from ..output.files import write_atomic
from .spec import SweepError, SweepSpec

RESULTS = "results.parquet"
PARTS = "results.parts"
MANIFEST = "sweep.json"

#: Columns that two runs of the same sweep do not share.
TIMING_COLUMNS = ("wall_time_s",)

_F64: pa.DataType = pa.float64()
_I64: pa.DataType = pa.int64()
_STR: pa.DataType = pa.string()
_BOOL: pa.DataType = pa.bool_()
# Lists named as Parquet names them ("element"), so a table read back has this same schema.
_VECTOR: pa.DataType = pa.list_(pa.field("element", pa.float64()))
_TEXTS: pa.DataType = pa.list_(pa.field("element", pa.string()))

BASE_COLUMNS: dict[str, pa.DataType] = {"task_status": _STR, "error": _STR}

#: The run's summary (``legsim.output.summary.run_summary`` keys; ``t_end`` is its ``t_final``,
#: the time reached), ``fell`` (the model broke down: status ``model_breakdown``) and
#: ``warnings`` (each of the run's warnings as "kind: message"; empty when it has none).
RUN_COLUMNS: dict[str, pa.DataType] = {
    "status": _STR,
    "message": _STR,
    "t_end": _F64,
    "final_mode": _STR,
    "final_state": _VECTOR,
    "transitions": _I64,
    "steps": _I64,
    "halvings": _I64,
    "field_evals": _I64,
    "guard_evals": _I64,
    "reset_evals": _I64,
    "energy_initial": _F64,
    "energy_final": _F64,
    "fell": _BOOL,
    "warnings": _TEXTS,
}

#: A walk's verdict (``legsim.sweep.walk``).
WALK_COLUMNS: dict[str, pa.DataType] = {
    "outcome": _STR,
    "walk_steps": _I64,
    "steps_to_gait": _I64,
    "distance_to_gait": _F64,
    "gait_period": _I64,
}

#: The variation's periodic orbit (``legsim.orbits.find_orbit``): multipliers by decreasing
#: modulus as real and imaginary parts; ``orbit_stable`` is null where the return map is not
#: differentiable (``orbit_differentiable`` false), and ``orbit_warnings`` says why.
ORBIT_COLUMNS: dict[str, pa.DataType] = {
    "orbit_status": _STR,
    "orbit_message": _STR,
    "orbit_fixed_point": _VECTOR,
    "orbit_period": _F64,
    "orbit_step_length": _F64,
    "orbit_multipliers_re": _VECTOR,
    "orbit_multipliers_im": _VECTOR,
    "orbit_spectral_radius": _F64,
    "orbit_stable": _BOOL,
    "orbit_differentiable": _BOOL,
    "orbit_warnings": _TEXTS,
    "orbit_residual": _F64,
    "orbit_iterations": _I64,
}


def input_type(values: Sequence[Any]) -> pa.DataType:
    """The Arrow type of a varied field's values."""
    if all(isinstance(v, bool) for v in values):
        return _BOOL
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return _I64
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return _F64
    if all(isinstance(v, str) for v in values):
        return _STR
    raise SweepError(f"the values {list(values)[:5]} mix types; a field is varied over numbers, strings or booleans")


def schema(spec: SweepSpec) -> pa.Schema:
    """The table's columns for this sweep, with its fingerprint in the metadata."""
    fields: list[pa.Field[Any]] = [pa.field("index", _I64, nullable=False)]
    fields += [pa.field(a.key, _F64 if a.is_random else input_type(a.values)) for a in spec.grid + spec.random]
    columns = dict(BASE_COLUMNS)
    if spec.run != "none":
        columns.update(RUN_COLUMNS)
    if spec.run == "walk":
        columns.update(WALK_COLUMNS)
    if spec.orbit:
        columns.update(ORBIT_COLUMNS)
    columns["wall_time_s"] = _F64
    fields += [pa.field(name, kind) for name, kind in columns.items()]
    return pa.schema(fields, metadata={"legsim.sweep": spec.fingerprint()})


def to_table(rows: Iterable[dict[str, Any]], table_schema: pa.Schema) -> pa.Table:
    """Rows (dicts; missing keys are nulls) as a table of the sweep's schema."""
    names = set(table_schema.names)
    return pa.Table.from_pylist([{k: v for k, v in row.items() if k in names} for row in rows], schema=table_schema)


def write_table(path: Path, table: pa.Table, what: str) -> Path:
    """Write ``table`` to ``path`` atomically, with fixed settings and as one chunk per column,
    so that the same rows give the same bytes however they were batched."""
    table = table.combine_chunks()
    return write_atomic(path, lambda tmp: pq.write_table(table, tmp, compression="zstd"), what=what)


class ResultStore:
    """A sweep's folder: the manifest, the parts written as batches finish, the final table."""

    def __init__(self, folder: str | Path, spec: SweepSpec) -> None:
        self.folder = Path(folder)
        self.spec = spec
        self.schema = schema(spec)
        self.results = self.folder / RESULTS
        self.parts = self.folder / PARTS
        self.manifest = self.folder / MANIFEST

    def prepare(self, resume: bool) -> set[int]:
        """Check the folder (nothing is written yet); the indices already done when resuming."""
        existing = self.results.exists() or self.manifest.exists() or self.parts.exists()
        if existing and not resume:
            raise SweepError(
                f"--out {self.folder}: already holds a sweep ({MANIFEST}, {RESULTS} or {PARTS}/); "
                f"continue it with --resume, or choose another folder"
            )
        if self.folder.exists() and not self.folder.is_dir():
            raise SweepError(f"--out {self.folder}: is a file, not a folder")
        if not existing:
            return set()
        self._check_manifest()
        return self.done_indices()

    def start(self) -> None:
        """Write the manifest (the sweep's specification) when the folder has none yet."""
        import json

        if not self.manifest.exists():
            text = json.dumps(self.spec.to_json(), indent=2, sort_keys=True, allow_nan=True) + "\n"
            write_atomic(self.manifest, lambda tmp: tmp.write_text(text), what="--out manifest")

    def _check_manifest(self) -> None:
        import json

        from .spec import SweepSpec

        try:
            stored = SweepSpec.from_json(json.loads(self.manifest.read_text()))
        except FileNotFoundError:
            raise SweepError(
                f"--resume: {self.manifest} is missing, so the results in {self.folder} cannot be matched to this sweep"
            ) from None
        except (ValueError, KeyError, TypeError) as exc:
            raise SweepError(f"--resume: {self.manifest} is not a sweep manifest: {exc}") from exc
        if stored.fingerprint() != self.spec.fingerprint():
            changed = sorted(k for k, v in stored.to_json().items() if self.spec.to_json().get(k) != v)
            raise SweepError(
                f"--resume: {self.folder} holds another sweep (differs in {changed}); resume it with "
                f"the same scene, --set, axes and measures, or choose another --out"
            )

    def part_files(self) -> list[Path]:
        return sorted(self.parts.glob("part-*.parquet")) if self.parts.is_dir() else []

    def done_indices(self) -> set[int]:
        """Indices of the rows already on disk (final table and parts)."""
        done: set[int] = set()
        for path in ([self.results] if self.results.exists() else []) + self.part_files():
            # The index column is not nullable (``schema``): its values are ints.
            done.update(cast(list[int], pq.read_table(path, columns=["index"]).column("index").to_pylist()))
        return done

    def add(self, rows: list[dict[str, Any]]) -> Path:
        """Write one finished batch's rows as a part file."""
        first = min(row["index"] for row in rows)
        path = self.parts / f"part-{first:010d}-{uuid.uuid4().hex[:8]}.parquet"
        return write_table(path, to_table(rows, self.schema), "sweep results part")

    def assemble(self) -> pa.Table:
        """Merge the final table and the parts into ``results.parquet`` (sorted by index), remove
        the parts; the table."""
        tables = [
            pq.read_table(p, schema=self.schema)
            for p in ([self.results] if self.results.exists() else []) + self.part_files()
        ]
        table = pa.concat_tables(tables) if tables else self.schema.empty_table()
        table = _first_of_each_index(table.sort_by("index"))
        write_table(self.results, table, "--out results")
        for path in self.part_files():
            path.unlink()
        if self.parts.is_dir() and not any(self.parts.iterdir()):
            self.parts.rmdir()
        return table


def _first_of_each_index(table: pa.Table) -> pa.Table:
    """One row per index (a sweep stopped between writing the table and removing the parts it
    merged leaves both on disk; their rows are the same)."""
    import numpy as np

    index = table.column("index").to_numpy()
    keep = np.ones(len(index), dtype=bool)
    keep[1:] = index[1:] != index[:-1]
    return table if keep.all() else table.filter(pa.array(keep))
