"""The recorded components of a Rerun file, per entity, as arrow arrays with their row index.

``read_columns`` streams a file with Rerun's own reader (``rerun.chunk.RrdReader``) and keeps
every chunk's components under its entity; ``Columns`` converts them to numbers, strings or
arrays only when asked for, sorted by row (the ``sample`` timeline; -1 for static rows).
"""

from __future__ import annotations

import contextlib
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..trace import RecordingError, concatenated_ranges
from .digest import leading_blocks
from .layout import SAMPLE_TIMELINE, TIMELINE


class Columns:
    """The recorded components, per entity, as arrow arrays with their row index (the
    ``sample`` timeline; -1 for static rows), converted only when asked for."""

    #: Rerun's id of each row, in the order the rows were logged.
    ROW_ID = "rerun.controls.RowId"
    #: Index and bookkeeping columns of a chunk, which are no component.
    SKIP = (ROW_ID, TIMELINE, SAMPLE_TIMELINE, "log_time", "log_tick")

    def __init__(self) -> None:
        self.data: dict[str, dict[str, list[tuple[np.ndarray, Any]]]] = {}
        self.row_ids: dict[str, dict[str, list[Any]]] = {}

    def add(self, entity: str, index: np.ndarray, batch: Any) -> None:
        """Keep the components of an arrow record batch whose rows have the indices ``index``."""
        comps = self.data.setdefault(entity, {})
        ids = self.row_ids.setdefault(entity, {})
        row_id = batch.column(self.ROW_ID) if self.ROW_ID in batch.schema.names else None
        for name in batch.schema.names:
            if name not in self.SKIP:
                comps.setdefault(name, []).append((index, batch.column(name)))
                ids.setdefault(name, []).append(row_id)

    def logged(self, entity: str, component: str) -> tuple[np.ndarray, Any] | None:
        """(sample indices, rows as an arrow list array) of a component in the order they were
        logged (by Rerun's row ids), null rows left out; None when a chunk has no row ids."""
        import pyarrow as pa

        indices, rows, keys = [], [], []
        pieces = self.data.get(entity, {}).get(component, [])
        for (index, column), row_id in zip(pieces, self.row_ids.get(entity, {}).get(component, []), strict=True):
            if row_id is None:
                return None
            valid = column.is_valid()
            keep = np.asarray(valid.to_numpy(zero_copy_only=False), dtype=bool)
            indices.append(index[keep])
            rows.append(column.filter(valid))
            keys.append(_row_id_bytes(row_id)[keep])
        if not rows:
            return np.empty(0, dtype=np.int64), pa.array([], type=pa.list_(pa.null()))
        key = np.concatenate(keys)
        # Row ids are 16 bytes, most significant first: sorted by both halves as big-endian integers.
        order = np.lexsort((key[:, 8:].copy().view(">u8").ravel(), key[:, :8].copy().view(">u8").ravel()))
        joined = pa.concat_arrays([r.cast(rows[0].type) for r in rows]) if len(rows) > 1 else rows[0]
        return np.concatenate(indices)[order], joined.take(pa.array(order))

    def entities(self) -> list[str]:
        return list(self.data)

    def _pieces(self, entity: str, component: str) -> Iterator[tuple[np.ndarray, Any]]:
        """(row indices, arrow column) of each chunk, without the rows where it is null."""
        for index, column in self.data.get(entity, {}).get(component, []):
            valid = column.is_valid()
            yield index[np.asarray(valid.to_numpy(zero_copy_only=False), dtype=bool)], column.filter(valid)

    def numbers(self, entity: str, component: str = "Scalars:scalars") -> tuple[np.ndarray, np.ndarray]:
        """(row indices, values) of a one-number-per-row component, sorted by row."""
        idx_parts, val_parts = [], []
        for index, column in self._pieces(entity, component):
            if len(column) and not np.all(column.value_lengths().to_numpy(zero_copy_only=False) == 1):
                raise ValueError(f"{entity}:{component} holds more than one value per row")
            idx_parts.append(index)
            val_parts.append(np.asarray(column.flatten().to_numpy(zero_copy_only=False), dtype=float))
        if not idx_parts:
            return np.empty(0, dtype=np.int64), np.empty(0)
        idx = np.concatenate(idx_parts)
        vals = np.concatenate(val_parts)
        order = np.argsort(idx, kind="stable")
        return idx[order], vals[order]

    def matrix(self, entity: str, component: str, width: int) -> tuple[np.ndarray, np.ndarray]:
        """(row indices, values (n, width)) of a component of one fixed-size vector per row
        (a translation, a quaternion), sorted by row."""
        idx_parts, val_parts = [], []
        for index, column in self._pieces(entity, component):
            if len(column) and not np.all(column.value_lengths().to_numpy(zero_copy_only=False) == 1):
                raise ValueError(f"{entity}:{component} holds more than one value per row")
            values = np.asarray(column.flatten().flatten().to_numpy(zero_copy_only=False), dtype=float)
            if values.size != width * len(index):
                raise ValueError(f"{entity}:{component} holds vectors of other than {width} numbers")
            idx_parts.append(index)
            val_parts.append(values.reshape(-1, width))
        if not idx_parts:
            return np.empty(0, dtype=np.int64), np.empty((0, width))
        idx = np.concatenate(idx_parts)
        order = np.argsort(idx, kind="stable")
        return idx[order], np.concatenate(val_parts)[order]

    def _sorted_flat(self, entity: str, component: str) -> tuple[np.ndarray, Any, np.ndarray]:
        """(row indices sorted, flat values in that order, row lengths in that order)."""
        import pyarrow as pa

        idx_parts, flat_parts, len_parts = [], [], []
        for index, column in self._pieces(entity, component):
            idx_parts.append(index)
            len_parts.append(np.asarray(column.value_lengths().to_numpy(zero_copy_only=False), dtype=np.int64))
            flat_parts.append(column.flatten())
        if not idx_parts:
            return np.empty(0, dtype=np.int64), [], np.empty(0, dtype=np.int64)
        idx = np.concatenate(idx_parts)
        lengths = np.concatenate(len_parts)
        flat = (
            pa.concat_arrays([f.cast(flat_parts[0].type) for f in flat_parts]) if len(flat_parts) > 1 else flat_parts[0]
        )
        order = np.argsort(idx, kind="stable")
        if np.any(order != np.arange(len(order))):
            offsets = np.cumsum(lengths) - lengths
            flat = flat.take(pa.array(concatenated_ranges(offsets[order], lengths[order])))
            lengths = lengths[order]
        return idx[order], flat, lengths

    def strings(self, entity: str, component: str) -> list[str]:
        """Each row's single string, sorted by row."""
        _, flat, lengths = self._sorted_flat(entity, component)
        if len(lengths) and not np.all(lengths == 1):
            raise ValueError(f"{entity}:{component} holds more than one value per row")
        return [] if not len(lengths) else flat.to_pylist()

    def arrays(self, entity: str, component: str) -> list[np.ndarray]:
        """Each row's values as a float array (rows may differ in length), sorted by row."""
        _, flat, lengths = self._sorted_flat(entity, component)
        if not len(lengths):
            return []
        values = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=float)
        return np.split(values, np.cumsum(lengths)[:-1])

    def rows(self, entity: str, component: str) -> list[tuple[int, list]]:
        """(row index, Python list of the row's values), sorted by row (small entities only)."""
        out: list[tuple[int, list]] = []
        for index, column in self._pieces(entity, component):
            out.extend(zip(index.tolist(), column.to_pylist(), strict=False))
        out.sort(key=lambda r: r[0])
        return out

    def values(self, entity: str, component: str) -> list:
        """Each row's Python list of values, sorted by row (small entities only)."""
        return [r[1] for r in self.rows(entity, component)]


def _row_id_bytes(row_id: Any) -> np.ndarray:
    """A fixed-size-binary(16) arrow array of row ids as bytes (n, 16)."""
    data = np.frombuffer(row_id.buffers()[1], dtype=np.uint8)
    return data[row_id.offset * 16 : (row_id.offset + len(row_id)) * 16].reshape(-1, 16)


def read_columns(path: Path, sealed: int | None = None) -> Columns:
    """Every chunk of the Rerun file ``path`` on the sample timeline, or static, read from its
    first ``sealed`` bytes only when given (those a seal vouches for: ``digest.check_file``);
    RecordingError naming the file when Rerun cannot read it."""
    try:
        with _decodable(path, sealed) as readable:
            return _columns(_chunks(readable))
    except RecordingError:
        raise
    except Exception as exc:  # rerun raises its own error types for foreign or truncated files
        raise RecordingError(f"{path}: not a readable Rerun recording ({type(exc).__name__}: {exc})") from exc
    except BaseException as exc:
        # A panic in Rerun's decoder reaches Python as pyo3's PanicException, a BaseException.
        if type(exc).__name__ != "PanicException":
            raise
        raise RecordingError(f"{path}: not a readable Rerun recording (its decoder failed: {exc})") from None


def _columns(chunks: list[Any]) -> Columns:
    out = Columns()
    for chunk in chunks:
        batch = chunk.to_record_batch()
        index = _row_index(chunk, batch)
        if index is not None:
            out.add(chunk.entity_path, index, batch)
    return out


def _chunks(path: Path) -> list[Any]:
    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        # A file without Rerun's footer (a damaged one, or the sealed bytes alone) draws a
        # warning about it; the sealed bytes hold all legsim reads.
        warnings.simplefilter("ignore")
        return list(RrdReader(path).stream())


@contextlib.contextmanager
def _decodable(path: Path, sealed: int | None) -> Iterator[Path]:
    """``path`` itself, or a temporary copy of its first ``sealed`` bytes: what follows the seal
    (its own message, the blueprint, Rerun's footer) is covered by no hash, and Rerun's decoder
    aborts the whole process on some damaged arrow messages, so it never sees those bytes."""
    if sealed is None or sealed >= path.stat().st_size:
        yield path
        return
    with contextlib.ExitStack() as stack:
        try:
            folder = stack.enter_context(tempfile.TemporaryDirectory(prefix="legsim-read-"))
            copy = Path(folder) / path.name
            with open(copy, "wb") as target:
                for block in leading_blocks(path, sealed):
                    target.write(block)
        except OSError as exc:
            raise RecordingError(
                f"{path}: cannot copy its sealed part to a temporary folder for Rerun's reader "
                f"({tempfile.gettempdir()}): {exc.strerror or exc}"
            ) from None
        yield copy


def _row_index(chunk: Any, batch: Any) -> np.ndarray | None:
    """The rows' indices on the sample timeline (-1 for static rows); None for a chunk off it
    (Rerun's own bookkeeping)."""
    if chunk.is_static:
        return np.full(batch.num_rows, -1, dtype=np.int64)
    if SAMPLE_TIMELINE in batch.schema.names:
        return np.asarray(batch.column(SAMPLE_TIMELINE).to_numpy(zero_copy_only=False), dtype=np.int64)
    return None
