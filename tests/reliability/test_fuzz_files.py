"""Fuzzing the readers of legsim's own files: saved executions (``load_execution``) and
recordings (``legsim replay``), mutated after writing.

Execution files: a saved run with one of its arrays changed (an element set to nan, inf, a
negative or huge value; another dtype or shape; cut short; removed; an array added), its meta
document changed (any key removed or given a value of another type, nested deep, NaN), or its
bytes flipped or cut. ``load_execution`` must raise SimulationError naming the file (the
library's "exit 2") or return an execution that ``sample``, ``summary`` and ``final_state``
serve without an exception (anything else is a "silent wrong result"); nothing else.

Recordings: a recording's legsim/meta document changed the same ways, or one of its sample
columns (mode index, times, strip flags) corrupted; ``legsim replay`` (text and --json) must
exit 0 or 2, never with a traceback, and --json output must be valid JSON.
"""

from __future__ import annotations

import io
import json
import math
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.recordings import run_hopper
from helpers.reliability import FULL, Hang, npz_arrays, record, run_cli, temporaries, watchdog, write_npz
from legsim import load_execution, run_summary, save_execution
from legsim.errors import SimulationError
from legsim.scene import load_scene

FUZZ = settings(
    max_examples=3000 if FULL else 100,
    deadline=None,
    derandomize=not FULL,
    database=None,
    suppress_health_check=list(HealthCheck),
)

JSON_SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=False),
    st.text(max_size=8),
    st.sampled_from(["flight", "finished", "", "\x1b[2J", 1e308]),
)
JSON_VALUES = st.recursive(
    JSON_SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=10,
)
ODD_NUMBERS = [math.nan, math.inf, -math.inf, -1.0, 0.0, 1e300, -1e300, 2.0**63, -(2**62), 7.0, 1e-300]


def json_paths(doc, prefix=()) -> list[tuple]:
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else []
    for key, value in items:
        out.append((*prefix, key))
        out += json_paths(value, (*prefix, key))
    return out


def mutate_json(draw, doc) -> str:
    """``doc`` with one value replaced, removed or nested deep, as JSON text (NaN allowed in)."""
    paths = json_paths(doc)
    action = draw(st.sampled_from(["replace", "replace", "remove", "deep", "nan", "whole"]))
    if action == "whole" or not paths:
        return json.dumps(draw(JSON_VALUES))
    path = draw(st.sampled_from(paths))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if action == "remove":
        parent.pop(path[-1])
    elif action == "deep":
        depth = draw(st.integers(10, 100_000))
        parent[path[-1]] = "DEEP"
        return json.dumps(doc).replace('"DEEP"', "[" * depth + "]" * depth)
    elif action == "nan":
        parent[path[-1]] = "NAN"
        return json.dumps(doc).replace('"NAN"', draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e400"])))
    else:
        parent[path[-1]] = draw(JSON_VALUES)
    return json.dumps(doc)


# -- execution files -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def saved_runs(tmp_path_factory):
    """name -> arrays of saved executions: modes of two dimensions, a run cut in a strip, three modes."""
    folder = tmp_path_factory.mktemp("saved")
    runs = {
        "hopper": run_hopper(t_final=0.8)[1],
        "ball cut in a strip": load_scene("bouncing_ball", ["integrator.max_transitions=6"]).simulate(),
        "digital control": load_scene("digital_control").simulate(),
    }
    return Saved(
        {name: npz_arrays(save_execution(ex, folder / f"{k}.npz")) for k, (name, ex) in enumerate(runs.items())}
    )


class Saved(dict):
    """The saved runs, shown by name only in Hypothesis's reports (their arrays take pages)."""

    def __repr__(self) -> str:
        return f"Saved({sorted(self)})"


def mutate_array(draw, arrays: dict) -> None:
    name = draw(st.sampled_from(sorted(k for k in arrays if k != "meta")))
    value = arrays[name]
    action = draw(st.sampled_from(["element", "element", "element", "dtype", "shape", "cut", "remove", "add"]))
    if action == "element" and value.size and value.dtype.kind in "fiu":
        flat = value.reshape(-1).copy()
        if value.dtype.kind == "f":
            odd = draw(st.sampled_from(ODD_NUMBERS))
        else:  # within the range of an earlier mutation's dtype
            limits = np.iinfo(value.dtype)
            odd = int(np.clip(draw(st.sampled_from([-1, -(2**63), 2**62, 0, 1, 3, 10**6])), limits.min, limits.max))
        flat[draw(st.integers(0, flat.size - 1))] = odd
        arrays[name] = flat.reshape(value.shape)
    elif action == "dtype":
        with warnings.catch_warnings():  # nan cast to int, complex to real: what a crafted file may hold
            warnings.simplefilter("ignore")
            arrays[name] = value.astype(
                draw(st.sampled_from([np.float32, np.int32, np.float64, np.int64, np.uint8, np.complex128, object]))
            )
    elif action == "shape":
        arrays[name] = value.reshape(-1) if value.ndim > 1 else value.reshape(1, -1)
    elif action == "cut":
        arrays[name] = value[: draw(st.integers(0, max(0, len(value) - 1)))] if value.ndim else value
    elif action == "remove":
        del arrays[name]
    else:
        arrays[draw(st.sampled_from(["extra", "seg_x2"]))] = np.zeros(draw(st.integers(0, 5)))


@st.composite
def damaged_files(draw, saved):
    """(arrays, meta text or None, byte edits) of one mutated execution file."""
    base = saved[draw(st.sampled_from(sorted(saved)))]
    arrays = {k: (v.copy() if isinstance(v, np.ndarray) else json.loads(json.dumps(v))) for k, v in base.items()}
    how = draw(st.sampled_from(["arrays", "arrays", "meta", "meta", "bytes"]))
    text, edits = None, []
    if how == "arrays":
        for _ in range(draw(st.integers(1, 3))):
            mutate_array(draw, arrays)
    elif how == "meta":
        text = mutate_json(draw, arrays["meta"])
    else:
        edits = draw(st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255), st.booleans()), min_size=1, max_size=6))
    return arrays, text, edits


def write_damaged(path: Path, arrays: dict, text: str | None, edits: list) -> None:
    try:
        write_npz(path, arrays, text)
    except (ValueError, TypeError):  # numpy cannot write this mutation (e.g. a complex meta)
        write_npz(path, {k: v for k, v in arrays.items() if k != "meta"}, "{}")
    data = bytearray(path.read_bytes())
    for where, byte, cut in edits:
        at = min(int(where * len(data)), len(data) - 1)
        if cut:
            del data[at:]
            if not data:
                break
        else:
            data[at] = byte
    path.write_bytes(bytes(data))


def load_outcome(path: Path) -> tuple[str, str]:
    """(outcome, detail) of ``load_execution`` on ``path``, then of using what it returned."""
    try:
        with watchdog(60):
            ex = load_execution(path)
    except Hang as exc:
        return "hangs", str(exc)
    except SimulationError as exc:
        ok = str(exc).startswith(f"{path}: ")
        return ("clear errors (exit 2)", "") if ok else ("tracebacks", f"unnamed: {exc}")
    except Exception as exc:
        return "tracebacks", f"{type(exc).__name__}: {exc}"
    try:
        times = np.linspace(ex.t0, ex.t_end, 41)
        sampled = ex.sample(times)
        for mode, state in zip(sampled.modes, sampled.states, strict=True):
            assert len(state) == len(ex.state_names[mode])
        assert len(ex.final_state) == len(ex.state_names[ex.final_mode])
        json.dumps(run_summary(ex), allow_nan=False)
    except Exception as exc:
        return "silent wrong results", f"loaded, then {type(exc).__name__}: {exc}"
    return "ran (exit 0 or 3)", ""


def test_fuzzed_execution_files_load_or_are_refused(saved_runs):
    @FUZZ
    @given(damaged_files(saved_runs))
    def check(case):
        with tempfile.TemporaryDirectory(prefix="legsim-fuzz-") as folder:
            path = Path(folder) / "run.npz"
            write_damaged(path, *case)
            before = path.read_bytes()
            outcome, detail = load_outcome(path)
            if path.read_bytes() != before:
                outcome = "files lost or changed"
            if temporaries(Path(folder)):
                outcome = "temporaries left"
        record("execution files (load_execution)", outcome)
        assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), detail

    check()


# -- recordings ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """(path, the legsim/meta document) of a recorded hopper."""
    from legsim.output.rrd import read_rrd, write_rrd

    model, ex = run_hopper(t_final=0.8)
    path = write_rrd(ex, None, tmp_path_factory.mktemp("rrd") / "hopper.rrd", model=model)
    return path, read_rrd(path)["meta"]


class Corrupted:
    """The columns of a recording with its meta text replaced and one number column changed."""

    def __init__(self, columns, meta_text: str, column: tuple[str, int, float] | None) -> None:
        self.real, self.meta_text, self.column = columns, meta_text, column

    def __getattr__(self, name):
        return getattr(self.real, name)

    def values(self, entity, component):
        if entity == "/legsim/meta":
            return [[self.meta_text]]
        return self.real.values(entity, component)

    def numbers(self, entity, component="Scalars:scalars"):
        rows, values = self.real.numbers(entity, component)
        if self.column and entity == self.column[0] and len(values):
            values = values.copy()
            values[self.column[1] % len(values)] = self.column[2]
        return rows, values


@st.composite
def damaged_recordings(draw, meta):
    doc = json.loads(json.dumps(meta))
    text = json.dumps(doc)
    column = None
    if draw(st.booleans()):
        text = mutate_json(draw, doc)
    else:
        entity = draw(st.sampled_from(["/mode/index", "/samples/t", "/strip/active", "/mode", "/frames/t"]))
        column = (entity, draw(st.integers(0, 10**6)), draw(st.sampled_from([*ODD_NUMBERS, 0.5, 2.0, 1000000000.0])))
    return text, column, draw(st.sampled_from(["text", "--json"]))


def test_fuzzed_recordings_replay_or_are_refused(recording, monkeypatch):
    import legsim.output.rrd.read as reader

    path, meta = recording
    real_read = reader.read_columns

    @FUZZ
    @given(damaged_recordings(meta))
    def check(case):
        text, column, mode = case
        monkeypatch.setattr(
            reader, "read_columns", lambda p, sealed=None: Corrupted(real_read(p, sealed), text, column)
        )
        try:
            with watchdog(60):
                code, out, err = run_cli("replay", path, *([mode] if mode == "--json" else []))
            outcome, detail = "ran (exit 0 or 3)" if code == 0 else "clear errors (exit 2)", err
            if code not in (0, 2) or "Traceback" in err or "internal error" in err:
                outcome = "tracebacks"
            elif code == 0 and mode == "--json":
                json.load(io.StringIO(out))
        except Hang as exc:
            outcome, detail = "hangs", str(exc)
        except ValueError as exc:
            outcome, detail = "silent wrong results", f"--json printed no JSON: {exc}"
        record("recordings (legsim replay)", outcome)
        assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), detail

    check()
