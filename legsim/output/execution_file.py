"""An execution saved to a ``.npz`` file (``save_execution``) and read back (``load_execution``).

The file is a zip of numpy arrays (never pickles) and one JSON document ``meta``. A file may
come from someone else, so loading trusts nothing in it: before any array is allocated its
declared size is checked against the file's size (a 1 MB file of zeros may inflate to 1 GB),
its dtype and shape against the format, and after reading every index against the range it
indexes, every count against the arrays it splits, every time for finiteness and order, and
the pieces against each other (one transition between consecutive segments, each joining the
modes it names). Anything else is a ``SimulationError`` naming the file and what is wrong;
an execution that loads is one ``sample`` can trust.

Arrays (``S`` segments, ``K`` strips, ``T`` transitions; int64 or float64):

* ``seg_mode (S,)`` index into ``meta.modes``; ``seg_len (S,)`` points; ``seg_dim (S,)`` state
  dimension; ``seg_t (sum len)``; ``seg_x``, ``seg_dx (sum len * dim)`` row-major;
* ``strip_mode (K,)``, ``strip_times (K, 4)`` entry, exit, landing time, depth;
  ``strip_dim (K,)``, ``strip_state (sum dim)``;
* ``tr_edge (T, 3)`` source, target, index among the source's transitions; ``tr_times (T, 4)``
  time, landing time, exit time, depth; ``tr_dims (T, 2)``; ``tr_before``, ``tr_after``.
"""

from __future__ import annotations

import io
import json
import math
import os
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..errors import SimulationError
from .files import input_size, write_atomic
from .summary import finite_or_none
from .untrusted import check_list, check_object, load_json

if TYPE_CHECKING:
    from ..execution import Execution

FORMAT = "legsim-execution-1"

#: name -> (dtype kind, shape with -1 for "any length").
ARRAYS: dict[str, tuple[str, tuple[int, ...]]] = {
    "seg_mode": ("i", (-1,)),
    "seg_len": ("i", (-1,)),
    "seg_dim": ("i", (-1,)),
    "seg_t": ("f", (-1,)),
    "seg_x": ("f", (-1,)),
    "seg_dx": ("f", (-1,)),
    "strip_mode": ("i", (-1,)),
    "strip_times": ("f", (-1, 4)),
    "strip_state": ("f", (-1,)),
    "strip_dim": ("i", (-1,)),
    "tr_edge": ("i", (-1, 3)),
    "tr_times": ("f", (-1, 4)),
    "tr_before": ("f", (-1,)),
    "tr_after": ("f", (-1,)),
    "tr_dims": ("i", (-1, 2)),
    "meta": ("U", ()),
}

#: The arrays of a file may take at most this many times the file's size once decompressed
#: (and at least ``MIN_LOAD_BYTES``): legsim's own files inflate 2 to 60 times (a long run
#: resting in one state compresses best), a crafted file of zeros 1000 times.
MAX_INFLATION = 256
MIN_LOAD_BYTES = 64 << 20

META_KEYS = {
    "format": (str,),
    "modes": (list,),
    "strip_names": (list,),
    "tr_names": (list,),
    "status": (str,),
    "message": (str,),
    "t0": (int, float),
    "t_end": (int, float),
    "t_final": (int, float),
    "counters": (dict,),
    "settings": (dict,),
    "state_names": (dict,),
    "system_name": (str,),
    "final_in_strip": (bool,),
}
#: Keys of files written since units and warnings were recorded; older files lack them.
OPTIONAL_META_KEYS = {"state_units": (dict,), "warnings": (list,)}
WARNING_KEYS = {"kind": (str,), "message": (str,), "time": (int, float)}

#: The integrator's counters and settings that summaries print as numbers (or names).
COUNTERS = (
    "steps",
    "halvings",
    "field_evals",
    "guard_evals",
    "reset_evals",
    "strip_time",
    "wall_time_s",
    "error_rejections",
    "transitions",
)
SETTINGS = {"h": (int, float, type(None)), "eps": (int, float, type(None)), "method": (str, type(None))}


class DamagedFile(ValueError):
    """Something in an execution file is not what the format says (message: what and where)."""


# -- saving --------------------------------------------------------------------------------------
def save_execution(execution: Execution, path: str | os.PathLike[str]) -> Path:
    """Write ``execution`` to the ``.npz`` file ``path`` completely or not at all (OutputError
    naming the file when it cannot be written, or has another suffix)."""
    modes = sorted(
        {s.mode for s in execution.segments}
        | {s.mode for s in execution.strips}
        | {tr.target for tr in execution.transitions}
    )
    payload = _arrays(execution, {m: i for i, m in enumerate(modes)})
    meta = {
        "format": FORMAT,
        "modes": modes,
        "strip_names": [s.name for s in execution.strips],
        "tr_names": [t.name for t in execution.transitions],
        "status": execution.status,
        "message": execution.message,
        "t0": execution.t0,
        "t_end": execution.t_end,
        "t_final": execution.t_final,
        "counters": execution.counters,
        "settings": _jsonable(execution.settings),
        "state_names": {k: list(v) for k, v in execution.state_names.items()},
        "state_units": {k: list(v) for k, v in execution.state_units.items()},
        "warnings": [finite_or_none(w.as_dict()) for w in execution.warnings],
        "system_name": execution.system_name,
        "final_in_strip": execution.final_in_strip,
    }
    payload["meta"] = np.array(json.dumps(_jsonable(meta)))

    def write(tmp: Path) -> None:
        # A file object, because np.savez_compressed appends ".npz" to a name without it.
        with open(tmp, "wb") as fh:
            # numpy's stub types **kwds with its allow_pickle keyword: the arrays are named by payload's keys.
            np.savez_compressed(fh, **payload)  # type: ignore[arg-type]

    return write_atomic(path, write, what="execution file", suffixes=(".npz",))


def _arrays(execution: Execution, index: dict[str, int]) -> dict[str, np.ndarray]:
    segs, strips, trs = execution.segments, execution.strips, execution.transitions
    return {
        "seg_mode": np.array([index[s.mode] for s in segs], dtype=np.int64),
        "seg_len": np.array([len(s.t) for s in segs], dtype=np.int64),
        "seg_dim": np.array([s.x.shape[1] for s in segs], dtype=np.int64),
        "seg_t": np.concatenate([s.t for s in segs]),
        "seg_x": np.concatenate([s.x.ravel() for s in segs]),
        "seg_dx": np.concatenate([s.dx.ravel() for s in segs]),
        "strip_mode": np.array([index[s.mode] for s in strips], dtype=np.int64),
        "strip_times": np.array([[s.time, s.exit_time, s.landing_time, s.depth] for s in strips]).reshape(-1, 4),
        "strip_state": _flat([s.state for s in strips]),
        "strip_dim": np.array([len(s.state) for s in strips], dtype=np.int64),
        "tr_edge": np.array([[index[t.source], index[t.target], t.index] for t in trs], dtype=np.int64).reshape(-1, 3),
        "tr_times": np.array([[t.time, t.landing_time, t.exit_time, t.depth] for t in trs]).reshape(-1, 4),
        "tr_before": _flat([t.state_before for t in trs]),
        "tr_after": _flat([t.state_after for t in trs]),
        "tr_dims": np.array([[len(t.state_before), len(t.state_after)] for t in trs], dtype=np.int64).reshape(-1, 2),
    }


def _flat(arrays: Sequence[np.ndarray]) -> np.ndarray:
    return np.concatenate([np.asarray(a, dtype=float).ravel() for a in arrays]) if arrays else np.empty(0)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return repr(obj)  # strict JSON has no nan or inf: kept readable, as a string
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return repr(obj)


# -- loading -------------------------------------------------------------------------------------
def load_execution(path: str | os.PathLike[str], max_bytes: int | None = None) -> Execution:
    """Read an execution written by ``save_execution``, checking everything (module docstring).

    ``max_bytes`` bounds the decompressed arrays (default ``MAX_INFLATION`` times the file's
    size, at least ``MIN_LOAD_BYTES``). Raises SimulationError naming the file and the fault.
    """
    path = Path(path)
    size = input_size(path, "execution file", SimulationError)
    limit = max(MIN_LOAD_BYTES, MAX_INFLATION * size) if max_bytes is None else int(max_bytes)
    try:
        arrays = _read_arrays(path, limit)
        meta = _meta(str(arrays["meta"][()]))
        return _assemble(arrays, meta)
    except DamagedFile as exc:
        raise SimulationError(f"{path}: damaged legsim execution file: {exc}") from None


def _read_arrays(path: Path, limit: int) -> dict[str, np.ndarray]:
    """Every array of the archive, each checked against ``ARRAYS`` before it is allocated."""
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise SimulationError(f"{path}: not a legsim execution file (not a .npz archive: {exc})") from None
    with archive:
        members = {info.filename.removesuffix(".npy"): info for info in archive.infolist()}
        missing = sorted(set(ARRAYS) - set(members))
        extra = sorted(set(members) - set(ARRAYS))
        if missing or extra:
            raise DamagedFile(f"arrays missing {missing}" if missing else f"unexpected arrays {extra}")
        declared = sum(info.file_size for info in members.values())
        if declared > limit:
            raise DamagedFile(
                f"its arrays would take {declared} bytes decompressed, more than the {limit} allowed "
                f"for a file of {path.stat().st_size} bytes (load_execution(path, max_bytes=...) "
                f"raises the bound)"
            )
        return {name: _read_member(archive, info, name) for name, info in members.items()}


def _read_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, name: str) -> np.ndarray:
    kind, shape = ARRAYS[name]
    try:
        with archive.open(info) as fh:
            header = _header(fh, name)
            dims, fortran, dtype = header
            _check_layout(name, dims, dtype, kind, shape)
            count = math.prod(dims)
            if count * dtype.itemsize > info.file_size:
                raise DamagedFile(f"{name} declares {count} values, more than its {info.file_size} bytes hold")
            out = np.empty(count, dtype=dtype)
            # ZipFile.open returns a ZipExtFile, a BufferedIOBase; typeshed says IO[bytes], without readinto.
            got = cast(io.BufferedIOBase, fh).readinto(out.data.cast("B")) if count else 0
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as exc:
        raise DamagedFile(f"{name} cannot be read ({type(exc).__name__}: {exc})") from None
    if got != count * dtype.itemsize:
        raise DamagedFile(f"{name} is truncated ({got} of {count * dtype.itemsize} bytes)")
    out = out.reshape(dims, order="F" if fortran else "C")
    return out.astype(dtype.newbyteorder("=")) if kind != "U" else out


def _header(fh: Any, name: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    from numpy.lib import format as npy

    try:
        version = npy.read_magic(fh)
        if version == (1, 0):
            return npy.read_array_header_1_0(fh)
        if version == (2, 0):
            return npy.read_array_header_2_0(fh)
        raise DamagedFile(f"{name} has an unknown .npy version {version}")
    except (ValueError, SyntaxError, TypeError) as exc:
        raise DamagedFile(f"{name} has no valid .npy header ({exc})") from None


def _check_layout(name: str, dims: tuple[int, ...], dtype: np.dtype, kind: str, shape: tuple[int, ...]) -> None:
    sizes = {"i": (8,), "f": (8,), "U": None}[kind]
    wrong_size = not dtype.itemsize or (sizes is not None and dtype.itemsize not in sizes)
    if dtype.hasobject or dtype.kind != kind or wrong_size:
        expected = {"i": "int64", "f": "float64", "U": "a string"}[kind]
        raise DamagedFile(f"{name} has dtype {dtype}, expected {expected}")
    if len(dims) != len(shape) or any(want not in (-1, got) or got < 0 for want, got in zip(shape, dims, strict=True)):
        raise DamagedFile(f"{name} has shape {dims}, expected {tuple('N' if d == -1 else d for d in shape)}")


def _meta(text: str) -> dict[str, Any]:
    try:
        meta = load_json(text)
    except ValueError as exc:
        raise DamagedFile(f"meta is not a JSON document: {exc}") from None
    try:
        check_object(meta, META_KEYS, "meta", optional=OPTIONAL_META_KEYS)
        if meta["format"] != FORMAT:
            raise DamagedFile(f"unknown execution format {meta['format']!r} (expected {FORMAT})")
        for key in ("modes", "strip_names", "tr_names"):
            check_list(meta[key], (str,), f"meta.{key}")
        for mode, names in meta["state_names"].items():
            check_list(names, (str,), f"meta.state_names.{mode}")
        for mode, units in meta.get("state_units", {}).items():
            check_list(units, (str,), f"meta.state_units.{mode}")
        for k, warning in enumerate(check_list(meta.get("warnings", []), (dict,), "meta.warnings")):
            check_object(warning, WARNING_KEYS, f"meta.warnings[{k}]")
        check_object(meta["counters"], {}, "meta.counters", optional=dict.fromkeys(COUNTERS, (int, float)))
        check_object(meta["settings"], {}, "meta.settings", optional=SETTINGS)
    except ValueError as exc:
        raise DamagedFile(str(exc)) from None
    from ..execution import STATUSES

    if meta["status"] not in STATUSES:
        raise DamagedFile(f"meta.status {meta['status']!r} is not one of {list(STATUSES)}")
    if len(set(meta["modes"])) != len(meta["modes"]) or not meta["modes"]:
        raise DamagedFile(f"meta.modes {meta['modes']!r} must name each mode once")
    for key in ("t0", "t_end", "t_final"):
        meta[key] = float(meta[key])
    if not (meta["t0"] <= meta["t_end"] <= meta["t_final"]):
        raise DamagedFile(
            f"meta times t0 = {meta['t0']}, t_end = {meta['t_end']}, t_final = {meta['t_final']} are not in order"
        )
    return meta


def _assemble(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> Execution:
    from ..execution import Execution

    dims = _mode_dims(meta)
    # A run that diverged stored the states it reached, which may overflow; any other may not.
    finite = meta["status"] != "non_finite"
    segs = _segments(arrays, meta["modes"], dims, finite)
    strip_list = _strips(arrays, meta, dims, finite)
    trs = _transitions(arrays, meta, dims, finite)
    _check_pieces(segs, strip_list, trs, meta)
    return Execution(
        status=meta["status"],
        message=meta["message"],
        segments=segs,
        strips=strip_list,
        transitions=trs,
        t0=meta["t0"],
        t_end=meta["t_end"],
        t_final=meta["t_final"],
        counters=meta["counters"],
        settings=meta["settings"],
        state_names={k: tuple(v) for k, v in meta["state_names"].items()},
        state_units={k: tuple(v) for k, v in meta.get("state_units", {}).items()},
        warnings=[_warning(w) for w in meta.get("warnings", [])],
        system_name=meta["system_name"],
        final_in_strip=meta["final_in_strip"],
    )


def _warning(doc: dict[str, Any]) -> Any:
    from ..execution import RunWarning

    details = {k: v for k, v in doc.items() if k not in WARNING_KEYS}
    return RunWarning(doc["kind"], doc["message"], float(doc["time"]), details)


def _mode_dims(meta: dict[str, Any]) -> list[int]:
    """The state dimension of each mode of ``meta.modes`` (its number of coordinate names)."""
    missing = [m for m in meta["modes"] if m not in meta["state_names"]]
    if missing:
        raise DamagedFile(f"meta.state_names lacks the mode(s) {missing}")
    dims = [len(meta["state_names"][m]) for m in meta["modes"]]
    if min(dims) < 1:
        raise DamagedFile("meta.state_names gives a mode no coordinates")
    return dims


# -- the pieces, checked -------------------------------------------------------------------------
def _indices(values: np.ndarray, n: int, name: str) -> np.ndarray:
    """``values`` as indices into a list of ``n``: a negative one would wrap around silently."""
    bad = np.flatnonzero((values < 0) | (values >= n))
    if bad.size:
        raise DamagedFile(f"{name}[{bad[0]}] = {values[bad[0]]} is not an index into the {n} modes")
    return values


def _rows(name: str, got: int, want: int, of: str) -> None:
    if got != want:
        raise DamagedFile(f"{name} has {got} rows for {want} {of}")


def _pieces_of(flat: np.ndarray, sizes: np.ndarray, name: str, finite: bool) -> list[np.ndarray]:
    """``flat`` split into consecutive pieces of ``sizes`` (which must use all of it)."""
    if np.any(sizes > len(flat)) or int(sizes.sum()) != len(flat):
        raise DamagedFile(
            f"{name} holds {len(flat)} values, but the counts that split it add up to "
            f"{int(sizes.sum()) if np.all(sizes <= len(flat)) else 'more'}"
        )
    if finite and not np.all(np.isfinite(flat)):
        raise DamagedFile(f"{name} holds values that are not finite (only a run that stopped non_finite may)")
    return np.split(flat, np.cumsum(sizes)[:-1]) if len(sizes) else []


def _finite_times(times: np.ndarray, name: str) -> None:
    if not np.all(np.isfinite(times)):
        raise DamagedFile(f"{name} holds times that are not finite")


def _segments(arrays: dict[str, np.ndarray], modes: list[str], dims: list[int], finite: bool) -> list:
    from ..execution import Segment

    index = _indices(arrays["seg_mode"], len(modes), "seg_mode")
    if not len(index):
        raise DamagedFile("no segments (an execution has at least one)")
    for name in ("seg_len", "seg_dim"):
        _rows(name, len(arrays[name]), len(index), "segments")
    lengths, seg_dims = arrays["seg_len"], arrays["seg_dim"]
    if np.any(lengths < 1):
        raise DamagedFile(f"seg_len[{np.flatnonzero(lengths < 1)[0]}] < 1 (a segment has at least one point)")
    wrong = np.flatnonzero(seg_dims != np.asarray(dims)[index])
    if wrong.size:
        k = wrong[0]
        raise DamagedFile(
            f"seg_dim[{k}] = {seg_dims[k]}, but mode '{modes[index[k]]}' has {dims[index[k]]} coordinates"
        )
    _finite_times(arrays["seg_t"], "seg_t")
    times = _pieces_of(arrays["seg_t"], lengths, "seg_t", True)
    steps = np.diff(arrays["seg_t"])
    steps[np.cumsum(lengths)[:-1] - 1] = 1.0  # from one segment's end to the next one's start: not a step
    if np.any(steps <= 0):
        k = int(np.searchsorted(np.cumsum(lengths), np.flatnonzero(steps <= 0)[0], side="right"))
        raise DamagedFile(f"the times of segment {k} do not increase")
    sizes = lengths * seg_dims
    xs = _pieces_of(arrays["seg_x"], sizes, "seg_x", finite)
    dxs = _pieces_of(arrays["seg_dx"], sizes, "seg_dx", finite)
    return [
        Segment(modes[m], t, x.reshape(len(t), d), dx.reshape(len(t), d))
        for m, t, x, dx, d in zip(index, times, xs, dxs, seg_dims, strict=True)
    ]


def _strips(arrays: dict[str, np.ndarray], meta: dict[str, Any], dims: list[int], finite: bool) -> list:
    from ..execution import Strip

    modes = meta["modes"]
    index = _indices(arrays["strip_mode"], len(modes), "strip_mode")
    for name in ("strip_times", "strip_dim"):
        _rows(name, len(arrays[name]), len(index), "strips")
    _rows("meta.strip_names", len(meta["strip_names"]), len(index), "strips")
    if np.any(arrays["strip_dim"] != np.asarray(dims, dtype=np.int64)[index]):
        raise DamagedFile("strip_dim does not match the dimensions of the strips' modes")
    times = arrays["strip_times"]
    _finite_times(times, "strip_times")
    if np.any(times[:, 3] < 0) or np.any(times[:, 1] < times[:, 0]):
        raise DamagedFile("strip_times has a negative depth or an exit before its entry")
    states = _pieces_of(arrays["strip_state"], arrays["strip_dim"], "strip_state", finite)
    return [
        Strip(modes[m], name, float(t0), float(t1), state, float(landing), float(depth))
        for m, name, (t0, t1, landing, depth), state in zip(index, meta["strip_names"], times, states, strict=True)
    ]


def _transitions(arrays: dict[str, np.ndarray], meta: dict[str, Any], dims: list[int], finite: bool) -> list:
    from ..execution import TransitionRecord

    modes, edges = meta["modes"], arrays["tr_edge"]
    _indices(edges[:, :2].ravel(), len(modes), "tr_edge")
    if np.any(edges[:, 2] < 0):
        raise DamagedFile("tr_edge holds a negative transition index")
    for name in ("tr_times", "tr_dims"):
        _rows(name, len(arrays[name]), len(edges), "transitions")
    _rows("meta.tr_names", len(meta["tr_names"]), len(edges), "transitions")
    mode_dims = np.asarray(dims, dtype=np.int64)
    if np.any(arrays["tr_dims"] != mode_dims[edges[:, :2]]):
        raise DamagedFile("tr_dims does not match the dimensions of the transitions' modes")
    times = arrays["tr_times"]
    _finite_times(times, "tr_times")
    if np.any(times[:, 3] < 0) or np.any(np.diff(times[:, :3], axis=1) < 0):
        raise DamagedFile("tr_times has a negative depth or times out of order (time <= landing <= exit)")
    before = _pieces_of(arrays["tr_before"], arrays["tr_dims"][:, 0], "tr_before", finite)
    after = _pieces_of(arrays["tr_after"], arrays["tr_dims"][:, 1], "tr_after", finite)
    return [
        TransitionRecord(name, modes[s], modes[g], int(i), float(tm), float(tl), float(te), b, a, float(depth))
        for name, (s, g, i), (tm, tl, te, depth), b, a in zip(
            meta["tr_names"], edges, times, before, after, strict=True
        )
    ]


def _check_pieces(segs: list, strips: list, trs: list, meta: dict[str, Any]) -> None:
    """Segments, strips and transitions fit together: a transition joins each two consecutive
    segments from the first's mode to the second's, the strip between them is held in the first's
    mode, and the pieces follow each other in time inside [t0, t_end]."""
    if len(trs) != len(segs) - 1 or len(strips) not in (len(segs) - 1, len(segs)):
        raise DamagedFile(
            f"{len(segs)} segments need {len(segs) - 1} transitions and as many strips (one more "
            f"when the run ended in one), got {len(trs)} and {len(strips)}"
        )
    if meta["final_in_strip"] != (len(strips) == len(segs)):
        raise DamagedFile("meta.final_in_strip does not match the number of strips")
    for k, tr in enumerate(trs):
        if (tr.source, tr.target) != (segs[k].mode, segs[k + 1].mode) or strips[k].name != tr.name:
            raise DamagedFile(
                f"transition {k} ({tr.name}: {tr.source} -> {tr.target}) does not join segments "
                f"{k} ({segs[k].mode}) and {k + 1} ({segs[k + 1].mode}) through its strip"
            )
    # A run that did not end in a strip has one segment more than strips.
    if any(strip.mode != seg.mode for strip, seg in zip(strips, segs, strict=False)):
        raise DamagedFile("a strip is held in another mode than the segment it ends")
    starts = [
        t for k, seg in enumerate(segs) for t in ((seg.t_start, strips[k].time) if k < len(strips) else (seg.t_start,))
    ]
    tol = 1e-9 * max(1.0, abs(meta["t0"]), abs(meta["t_end"]))
    if np.any(np.diff(starts) < 0) or starts[0] < meta["t0"] - tol or max(starts) > meta["t_end"] + tol:
        raise DamagedFile(
            f"segments and strips do not follow each other in time inside [t0, t_end] = [{meta['t0']}, {meta['t_end']}]"
        )
    if max(seg.t_end for seg in segs) > meta["t_end"] + tol:
        raise DamagedFile(f"a segment runs past t_end = {meta['t_end']}")
