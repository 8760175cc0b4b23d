"""The sweep's results on disk: one Parquet row per variation, streamed as batches finish.

Each finished batch is written at once as its own Parquet file in ``DIR/results.parts/``
(atomically: complete or absent), so a sweep killed at any moment loses only the batches still
running; ``DIR/results.parquet`` is assembled from them (and from an earlier table when
resuming), sorted by ``index``, when the sweep ends or is interrupted. ``--resume`` reads the
indices already in either and runs only the others.

Columns (``schema``): ``index``, one column per varied field (named by its dotted path), then
``task_status`` (``done``, ``error``, ``timeout``) and ``error`` (the message, null when done),
the measures' columns (``RUN_COLUMNS``, one float column per ``--measure``, ``WALK_COLUMNS``,
``ORBIT_COLUMNS``, as asked) and
``wall_time_s`` (the variation's wall time on its worker, s). Every column but
``wall_time_s`` depends only on the sweep's specification: two runs of one sweep, wherever they
ran and however they were batched, give the same table up to that column.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import stat
import uuid
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..output.arrow_digest import table_digest
from ..output.files import file_kind, write_atomic
from ..output.untrusted import check_object, load_json
from .measures import check_measures
from .spec import SweepError, SweepSpec

RESULTS = "results.parquet"
PARTS = "results.parts"
MANIFEST = "sweep.json"
LOCK = ".sweep.lock"
#: The figure each kind of sweep draws into its folder: (writer's name, file name).
FIGURES = {"walk": ("basin_map", "basin.png"), "orbit": ("stability_map", "stability.png")}
#: The schema metadata keys of a table: the sweep's digest, and the digest of the rows in it.
SWEEP_KEY, ROWS_KEY = b"legsim.sweep", b"legsim.rows"
#: The manifest's format, which ``--resume`` checks first.
MANIFEST_FORMAT = "legsim-sweep-1"
#: Largest manifest read (bytes), as a multiple of the manifest this sweep would write (at least
#: ``MIN_MANIFEST_BYTES``): a manifest of this sweep is that text, byte for byte; one a few times
#: larger is still read, to name what differs from another sweep; a larger one is no manifest of
#: a sweep like this one, and parsing it (a list of 10^8 numbers) would take gigabytes.
MANIFEST_SIZE_FACTOR = 4
MIN_MANIFEST_BYTES = 1 << 16
#: Most bytes one row of a table may take once decompressed (a row holds a few numbers, a
#: state, messages and warnings: a few kilobytes).
MAX_ROW_BYTES = 1 << 20

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
#: the time reached), ``fell`` (status ``fell``: a condition of the scene's ``[fall]`` held; or
#: ``model_breakdown``: the model broke down) and
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
    if spec.measures:
        columns.update({m.column: _F64 for m in check_measures(spec.measures)})
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
    table = with_rows_digest(table.combine_chunks())

    def write(tmp: Path) -> None:
        # Page checksums: a flipped byte in a page is found when --resume reads it back.
        pq.write_table(table, tmp, compression="zstd", write_page_checksum=True)

    return write_atomic(path, write, what=what)


def read_table(path: Path, columns: list[str] | None = None, table_schema: pa.Schema | None = None) -> pa.Table:
    """A table or part, its page checksums verified; SweepError naming the file when pyarrow
    cannot read it."""
    try:
        return pq.read_table(path, columns=columns, schema=table_schema, page_checksum_verification=True)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise SweepError(f"--resume: {path} is damaged or no Parquet table: {_one_line(exc)}") from None


class ResultStore:
    """A sweep's folder: the lock, the manifest, the parts written as batches finish, the final table."""

    def __init__(self, folder: str | Path, spec: SweepSpec) -> None:
        self.folder = Path(folder)
        self.spec = spec
        self.schema = schema(spec)
        self.results = self.folder / RESULTS
        self.parts = self.folder / PARTS
        self.manifest = self.folder / MANIFEST
        self.lock = self.folder / LOCK

    @contextlib.contextmanager
    def claim(self) -> Iterator[None]:
        """Hold the folder for this sweep (module docstring): SweepError at once when another
        sweep holds it. The folder is made if need be, and removed again, with the lock file,
        when the sweep ends having written nothing there (its engine could not start)."""
        if self.folder.exists() and not self.folder.is_dir():
            raise SweepError(f"--out {self.folder}: is {file_kind(self.folder.stat().st_mode)}, not a folder")
        made = [p for p in (self.folder, *self.folder.parents) if not p.exists()]
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SweepError(f"--out {self.folder}: cannot make the folder: {exc.strerror or exc}") from None
        fd = self._lock()
        try:
            yield
        finally:
            with contextlib.suppress(OSError):
                self.lock.unlink()
            os.close(fd)  # releases the lock, after the unlink (module docstring of _lock)
            for folder in made:
                with contextlib.suppress(OSError):
                    folder.rmdir()  # only when empty: the sweep wrote nothing there

    def _lock(self) -> int:
        """The descriptor of the lock file, locked. Its holder removes it before releasing the
        lock, so a sweep that waited on the removed file finds, once it holds the lock, that the
        name now leads elsewhere or nowhere, and tries again on the file there now."""
        for _ in range(20):
            try:
                fd = os.open(self.lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
            except OSError as exc:
                raise SweepError(
                    f"--out {self.folder}: cannot make the lock file {LOCK}: {exc.strerror or exc}"
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise SweepError(f"--out {self.folder}: cannot lock {LOCK}: {exc.strerror or exc}") from None
                raise SweepError(
                    f"--out {self.folder}: another sweep is running in this folder"
                    + (f" (process {holder})" if holder.isdigit() else "")
                    + "; wait for it to end, or choose another --out"
                ) from None
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.lock))
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                return fd
            os.close(fd)
        raise SweepError(f"--out {self.folder}: the lock file {LOCK} keeps being replaced; is a sweep looping on it?")

    def prepare(self, resume: bool) -> set[int]:
        """Check the folder (nothing is written yet; the folder is claimed); the indices
        already done when resuming."""
        existing = self.results.exists() or self.manifest.exists() or self.parts.exists()
        if existing and not resume:
            raise SweepError(
                f"--out {self.folder}: already holds a sweep ({MANIFEST}, {RESULTS} or {PARTS}/); "
                f"continue it with --resume, or choose another folder"
            )
        if not existing:
            self._check_no_figures()
            return set()
        self._check_manifest()
        return self.done_indices()

    def _check_no_figures(self) -> None:
        """SweepError where a folder without a sweep holds a file of a sweep figure's name: it is
        the user's, and the sweep would replace it."""
        held = [name for _, name in FIGURES.values() if os.path.lexists(self.folder / name)]
        if held:
            raise SweepError(
                f"--out {self.folder}: holds {', '.join(held)}, which no sweep of this folder wrote and a sweep "
                f"writes its figure to; move it, or choose another folder"
            )

    def start(self) -> None:
        """Write the manifest (the sweep's specification and its SHA-256) when the folder has none yet."""
        if not self.manifest.exists():
            text = manifest_text(self.spec)
            write_atomic(self.manifest, lambda tmp: tmp.write_bytes(text), what="--out manifest")

    def _check_manifest(self) -> None:
        from ..scene.files import read_input_file

        expected = manifest_text(self.spec)
        bound = max(MIN_MANIFEST_BYTES, MANIFEST_SIZE_FACTOR * len(expected))
        try:
            raw = read_input_file(self.manifest, bound, "manifest of this sweep", SweepError)
        except SweepError as exc:
            raise SweepError(
                f"--resume: {exc}; without it the results in {self.folder} cannot be matched to this sweep"
            ) from None
        if raw == expected:  # this sweep's manifest as this legsim writes it: nothing to parse
            return
        try:
            document = check_object(
                load_json(raw.decode("utf-8")), {"format": (str,), "digest": (str,), "spec": (dict,)}, MANIFEST
            )
            if document["format"] != MANIFEST_FORMAT:
                raise ValueError(f"its format is {document['format']!r:.40}, not {MANIFEST_FORMAT}")
            stored = SweepSpec.from_json(document["spec"])
        except (ValueError, SweepError) as exc:  # UnicodeDecodeError is a ValueError
            raise SweepError(f"--resume: {self.manifest} is not a sweep manifest of this legsim: {exc}") from None
        if stored.fingerprint() != document["digest"]:
            raise SweepError(
                f"--resume: {self.manifest} is damaged: its specification does not match its digest "
                f"{document['digest']!r:.80}"
            )
        if stored.fingerprint() != self.spec.fingerprint():
            old, new = stored.to_json(), self.spec.to_json()
            changed = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
            if changed == ["inputs"] and not stored.inputs:
                raise SweepError(
                    f"--resume: the sweep in {self.folder} was written without the digest of its scene's files, so "
                    f"its rows cannot be matched to the files as they are now; run it again into another --out"
                )
            if changed == ["inputs"]:
                raise SweepError(
                    f"--resume: the scene's files (the scene, its URDF, its terrain CSV) have changed since the sweep "
                    f"in {self.folder} began, so its rows and new ones would not be of one scene; restore them, or "
                    f"choose another --out"
                )
            raise SweepError(
                f"--resume: {self.folder} holds another sweep (differs in {changed}); resume it with "
                f"the same scene, --set, axes and measures, or choose another --out"
            )

    def part_files(self) -> list[Path]:
        return sorted(self.parts.glob("part-*.parquet")) if self.parts.is_dir() else []

    def done_indices(self) -> set[int]:
        """Indices of the rows already on disk (final table and parts), each file checked to
        be this sweep's (module docstring)."""
        if self.parts.exists() and not self.parts.is_dir():
            raise SweepError(f"--resume: {self.parts} is {file_kind(self.parts.stat().st_mode)}, not a folder")
        done: set[int] = set()
        from_parts: set[int] = set()
        for path in ([self.results] if self.results.exists() else []) + self.part_files():
            indices = self._checked_indices(path)
            if path != self.results:
                # Parts never overlap; the final table may share rows with parts that a sweep
                # stopped between writing it and removing them left behind (the same rows).
                overlap = from_parts & indices
                if overlap:
                    raise SweepError(f"--resume: {path} repeats row {min(overlap)} of another part")
                from_parts |= indices
            done |= indices
        return done

    def _checked_indices(self, path: Path) -> set[int]:
        """The indices of a table or part of this sweep; SweepError naming the file when it is
        no regular file, unreadable, of another schema or sweep, or its indices are out of range,
        null or repeated."""
        mode = path.lstat().st_mode
        if not stat.S_ISREG(mode):
            raise SweepError(f"--resume: {path} is {file_kind(mode)}, not a table this sweep wrote")
        try:
            metadata = pq.read_metadata(path)
            found = metadata.schema.to_arrow_schema()
        except (pa.ArrowException, OSError, ValueError) as exc:
            raise SweepError(f"--resume: {path} is damaged or no Parquet table: {_one_line(exc)}") from None
        self._check_size(path, metadata)
        fingerprint = (found.metadata or {}).get(SWEEP_KEY, b"").decode("ascii", "replace")
        if fingerprint != self.spec.fingerprint():
            raise SweepError(
                f"--resume: {path} was not written by this sweep (its sweep digest is {fingerprint[:16] or 'absent'!r})"
            )
        if not found.remove_metadata().equals(self.schema.remove_metadata()):
            wrong = [f.name for f in self.schema if found.get_field_index(f.name) < 0 or found.field(f.name) != f]
            raise SweepError(f"--resume: {path} lacks or changes this sweep's columns {wrong[:5] or found.names[:5]}")
        table = read_table(path, table_schema=self.schema)
        index = table.column("index")
        if index.null_count:
            raise SweepError(f"--resume: {path} has rows without an index")
        values = np.asarray(index.to_numpy(), dtype=np.int64)
        bad = values[(values < 0) | (values >= len(self.spec))]
        if len(bad):
            raise SweepError(f"--resume: {path} has row index {int(bad[0])}, outside 0..{len(self.spec) - 1}")
        unique, counts = np.unique(values, return_counts=True)
        if np.any(counts > 1):
            raise SweepError(f"--resume: {path} repeats row {int(unique[counts > 1][0])}")
        if (found.metadata or {}).get(ROWS_KEY, b"").decode("ascii", "replace") != rows_digest(table):
            raise SweepError(
                f"--resume: {path} was changed after this sweep wrote it: its rows do not match their digest"
            )
        return set(values.tolist())

    def _check_size(self, path: Path, metadata: pq.FileMetaData) -> None:
        """SweepError unless the file's rows, as its footer counts them, fit this sweep: at most
        one per variation and ``MAX_ROW_BYTES`` each once decompressed. Checked before the rows
        are read: a crafted file of a few kilobytes may unpack to gigabytes."""
        if metadata.num_rows > len(self.spec):
            raise SweepError(
                f"--resume: {path} holds {metadata.num_rows} rows, more than this sweep's {len(self.spec)} variations"
            )
        unpacked = sum(metadata.row_group(k).total_byte_size for k in range(metadata.num_row_groups))
        if unpacked > MAX_ROW_BYTES * max(1, metadata.num_rows):
            raise SweepError(
                f"--resume: {path} unpacks to {unpacked} bytes for {metadata.num_rows} rows, more than the "
                f"{MAX_ROW_BYTES} bytes a row of a sweep holds"
            )

    def add(self, rows: list[dict[str, Any]]) -> Path:
        """Write one finished batch's rows as a part file."""
        first = min(row["index"] for row in rows)
        path = self.parts / f"part-{first:010d}-{uuid.uuid4().hex[:8]}.parquet"
        return write_table(path, to_table(rows, self.schema), "sweep results part")

    def assemble(self) -> pa.Table:
        """Merge the final table and the parts into ``results.parquet`` (sorted by index), remove
        the parts; the table."""
        tables = [
            read_table(p, table_schema=self.schema)
            for p in ([self.results] if self.results.exists() else []) + self.part_files()
        ]
        table = pa.concat_tables(tables) if tables else self.schema.empty_table()
        table = with_rows_digest(_first_of_each_index(table.sort_by("index")).combine_chunks())
        write_table(self.results, table, "--out results")
        for path in self.part_files():
            path.unlink()
        if self.parts.is_dir() and not any(self.parts.iterdir()):
            self.parts.rmdir()
        return table


def manifest_text(spec: SweepSpec) -> bytes:
    """The manifest of ``spec`` (UTF-8 JSON): its format, its specification and their SHA-256."""
    document = {"format": MANIFEST_FORMAT, "digest": spec.fingerprint(), "spec": spec.to_json()}
    return (json.dumps(document, indent=2, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")


def with_rows_digest(table: pa.Table) -> pa.Table:
    """``table`` with the digest of its rows in its metadata: --resume takes only rows as this
    sweep wrote them, and a table in memory is the table on disk, metadata included."""
    return table.replace_schema_metadata(
        {**(table.schema.metadata or {}), ROWS_KEY: rows_digest(table).encode("ascii")}
    )


def rows_digest(table: pa.Table) -> str:
    """The SHA-256 of a table's rows but for their timing columns, which two runs of one sweep do
    not share (``TIMING_COLUMNS``): the same rows have the same digest wherever they ran."""
    return table_digest(table.drop_columns([c for c in TIMING_COLUMNS if c in table.column_names]))


def _one_line(exc: BaseException) -> str:
    """pyarrow's message on one line (it may end in, or hold, line breaks)."""
    return " ".join(str(exc).split())


def _first_of_each_index(table: pa.Table) -> pa.Table:
    """One row per index (a sweep stopped between writing the table and removing the parts it
    merged leaves both on disk; their rows are the same)."""
    index = table.column("index").to_numpy()
    keep = np.ones(len(index), dtype=bool)
    keep[1:] = index[1:] != index[:-1]
    return table if keep.all() else table.filter(pa.array(keep))
