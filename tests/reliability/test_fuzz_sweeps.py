"""Fuzzing sweeps: their specifications (``legsim sweep`` options) and the tables and manifests
``--resume`` reads, run in-process (bouncing balls of 0.05 s, a watchdog for hangs).

* **specifications**: zero to three ``--grid`` axes (ranges and lists, with counts from 0 to
  10^30, numbers that are nan, inf or text, keys that are no field), ``--random`` axes with
  ``--samples`` and ``--seed`` of any text, ``--set``, ``--walk``, ``--orbit``, ``--no-run``,
  ``--timeout``, ``--batch``, and ``--scheduler`` addresses that are malformed or refused. Grids
  are small (at most 81 variations) or absurd (10^8 and more), so that every input ends in
  seconds. Allowed: exit 0, 2 or 3 with no traceback; exit 2 within a few seconds and without
  writing the folder for absurd grids; a table (exit 0 or 3) with one row per variation, indices
  0..n-1, each range axis's column holding its evenly spaced values, every row ``done`` for
  exit 0.
* **tables and manifests**: a finished 12-row sweep's folder with ``sweep.json`` edited
  (values of any type, keys removed, nesting 100,000 deep, text cut or flipped),
  ``results.parquet`` damaged (bytes flipped, cut, columns dropped, renamed or retyped, indices
  out of range, repeated or negative, rows removed, metadata changed, a FIFO in its place),
  parts added (copies, foreign tables, garbage) or a stale lock file left, then ``--resume``.
  Allowed: exit 2 with one error line, or exit 0 with the sweep's own table (rows removed are
  computed again); anything else is a "silent wrong result" (data corruption).

The short forms run in CI; the ``slow``-marked long forms draw new inputs (``-m slow`` or
``LEGSIM_FULL=1``). Run without xdist to print the outcome counts (docs/reliability.md).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.fuzz import VALUES
from helpers.peers import closed_port
from helpers.reliability import FULL, Hang, record, run_cli, temporaries, watchdog
from legsim.sweep.table import TIMING_COLUMNS

BALL = ["sweep", "bouncing_ball", "--set", "integrator.t_final=0.05", "--quiet", "--json"]
HANG_SECONDS = 120
SPECS, TABLES = "sweep specifications (legsim sweep)", "sweep tables and manifests (--resume)"


def fuzz_settings(examples: int, long: bool) -> settings:
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=not long,
        # a failure of the random long form prints the blob that replays it (@reproduce_failure)
        print_blob=long,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


# -- specifications -------------------------------------------------------------------------------
KEYS = ["initial.state.z", "initial.state.zd", "effects.floor.restitution", "integrator.h", "robot.parameters.g",
        "x", "initial.state.z.x", "a..b", " ", "integrator.method"]  # fmt: skip
ENDS = ["0.5", "2", "-1", "0", "1e-3", "nan", "inf", "1e400", "x", "", "true", '"a"']
GOOD_ENDS = ["0.5", "1", "1.5", "2"]
SMALL_COUNTS, HUGE_COUNTS = ["1", "2", "3"], ["100000000", "1000000000", "1e30", "123456789012345678901234567890"]
BAD_COUNTS = ["0", "-1", "1.5", "x", "", "nan"]
LITERALS = ["0.5", "1", "2", "-3", "nan", "inf", "true", '"rk4"', '"dopri5"', "x", "[1, 2]", "{ a = 1 }", "1e400", ""]


@st.composite
def grid_option(draw) -> tuple[str, int | None, tuple | None]:
    """(--grid text, its count when it is well formed and small (None otherwise), (lo, hi, n) of a range)."""
    key = draw(st.sampled_from(KEYS[:3] * 4 + KEYS))
    if draw(st.booleans()):
        low, high = draw(st.sampled_from(GOOD_ENDS * 3 + ENDS)), draw(st.sampled_from(GOOD_ENDS * 3 + ENDS))
        kind = draw(st.sampled_from(["small", "small", "small", "huge", "bad"]))
        n = draw(st.sampled_from({"small": SMALL_COUNTS, "huge": HUGE_COUNTS, "bad": BAD_COUNTS}[kind]))
        count = int(n) if kind == "small" else None
        return f"{key}={low}:{high}:{n}", count, (low, high, int(n)) if kind == "small" else None
    values = draw(st.lists(st.sampled_from(GOOD_ENDS * 4 + LITERALS), min_size=1, max_size=3))
    return f"{key}={','.join(values)}", len(values), None


@st.composite
def sweep_specs(draw) -> tuple[list[str], int | None, list]:
    """(the options, the number of variations when every axis is well formed and small, ranges)."""
    argv: list[str] = []
    count: int | None = 1
    ranges = []
    for _ in range(draw(st.integers(0, 3))):
        text, n, span = draw(grid_option())
        argv += ["--grid", text]
        count = None if n is None or count is None else count * n
        ranges.append((text.split("=", 1)[0].strip(), span))
    if draw(st.integers(0, 2)) == 0:
        argv += [
            "--random",
            f"{draw(st.sampled_from(KEYS))}={draw(st.sampled_from(ENDS))}:{draw(st.sampled_from(ENDS))}",
        ]
        samples = draw(st.sampled_from(["1", "2", "3", "0", "-5", "100000000", "x", None]))
        argv += [] if samples is None else ["--samples", samples]
        count = None if count is None or samples not in ("1", "2", "3", None) else count * int(samples or 100)
    if draw(st.integers(0, 3)) == 0:
        argv += ["--seed", draw(st.sampled_from(["0", "1", "-1", "x", "99999999999999999999"]))]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--set", draw(st.sampled_from(["integrator.h=2e-3", "x=1", "integrator.t_final=nan", "=", "a"]))]
    for flag in ("--walk", "--orbit", "--no-run"):
        if draw(st.integers(0, 9)) == 0:
            argv.append(flag)
    if draw(st.integers(0, 4)) == 0:
        argv += ["--timeout", draw(st.sampled_from(["1", "0", "-1", "nan", "inf", "x", "30"]))]
    if draw(st.integers(0, 4)) == 0:
        argv += ["--batch", draw(st.sampled_from(["1", "2", "0", "-1", "x"]))]
    where = draw(st.sampled_from(["in-process"] * 6 + ["malformed", "closed"]))
    if where == "in-process":
        argv.append("--in-process")
    else:
        address = draw(st.sampled_from(["tcp://h:1:2", "::::", "http://127.0.0.1:1", "nothing", "tcp://h:0"]))
        argv += ["--scheduler", f"tcp://127.0.0.1:{closed_port()}" if where == "closed" else address]
    if count is not None and count > 81:  # three small grids and draws: still quick
        count = None
    return argv, count, ranges


def check_spec(case) -> None:
    argv, count, ranges = case
    with tempfile.TemporaryDirectory(prefix="legsim-fuzz-sweep-") as folder:
        out = Path(folder) / "out"
        outcome, detail = spec_outcome(out, argv, count, ranges)
        if temporaries(Path(folder)):
            outcome, detail = "temporaries left", str(temporaries(Path(folder)))
    record(SPECS, outcome)
    assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), f"{outcome}: {detail}\n--- {argv}"


def spec_outcome(out: Path, argv: list[str], count: int | None, ranges: list) -> tuple[str, str]:
    began = time.monotonic()
    try:
        with watchdog(HANG_SECONDS):
            code, stdout, err = run_cli(*BALL, *argv, "--out", out)
    except Hang as exc:
        return "hangs", str(exc)
    seconds = time.monotonic() - began
    if code not in (0, 2, 3) or "Traceback" in err or "internal error" in err:
        return "tracebacks", f"exit {code}: {err[-2000:]}"
    if code == 2:
        usage = err.startswith("usage: legsim sweep") and "legsim sweep: error: argument " in err  # argparse's own
        if not usage and (not err.startswith("legsim: error: ") or err.count("\n") != 1):
            return "tracebacks", err
        if count is None and seconds > 30:
            return "hangs", f"an absurd sweep refused after {seconds:.1f} s"
        if out.exists() and any(out.iterdir()) and "already" not in err:
            return "files lost or changed", f"a refused sweep left {sorted(p.name for p in out.iterdir())}"
        return "clear errors (exit 2)", err
    table = pq.read_table(out / "results.parquet")
    summary = json.loads(stdout)
    n = summary["variations"]
    if count is not None and n != count:
        return "silent wrong results", f"{n} variations, {count} asked for"
    if table.column("index").to_pylist() != list(range(n)):
        return "silent wrong results", f"indices {table.column('index').to_pylist()[:20]} for {n} variations"
    statuses = set(table.column("task_status").to_pylist())
    if (code == 0) != (statuses == {"done"}):
        return "silent wrong results", f"exit {code} with rows {statuses}"
    for key, span in ranges:
        if span is not None and key in table.column_names:
            expected = (
                np.linspace(
                    float(tomllib.loads(f"v = {span[0]}")["v"]), float(tomllib.loads(f"v = {span[1]}")["v"]), span[2]
                )
                if span[2] > 1
                else None
            )
            seen = sorted(set(table.column(key).to_pylist()))
            if expected is not None and not np.array_equal(seen, sorted(set(expected.tolist()))):
                return "silent wrong results", f"{key} holds {seen}, not {expected.tolist()}"
    return "ran (exit 0 or 3)", ""


@pytest.mark.skipif(FULL, reason="the long form runs instead")
@fuzz_settings(40, long=False)
@given(sweep_specs())
def test_fuzzed_sweep_specifications_end_cleanly(case):
    check_spec(case)


@pytest.mark.slow
@fuzz_settings(500, long=True)
@given(sweep_specs())
def test_fuzzed_sweep_specifications_end_cleanly_long(case):
    check_spec(case)


# -- tables and manifests -------------------------------------------------------------------------
GRID = ["--grid", "initial.state.z=0.5:2:12", "--in-process", "--batch", "4"]


def without_timing(table: pa.Table) -> bytes:
    sink = io.BytesIO()
    pq.write_table(table.drop_columns([c for c in TIMING_COLUMNS if c in table.column_names]), sink)
    return sink.getvalue()


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, bytes]:
    """A finished 12-row sweep's folder and its table (without timing)."""
    out = tmp_path_factory.mktemp("sweep") / "done"
    assert run_cli(*BALL, *GRID, "--out", out)[0] == 0
    return out, without_timing(pq.read_table(out / "results.parquet"))


#: Places in a manifest an edit lands on.
MANIFEST_PATHS = [("format",), ("digest",), ("spec",), ("spec", "scene"), ("spec", "overrides"), ("spec", "grid"),
                  ("spec", "grid", 0), ("spec", "grid", 0, "values"), ("spec", "grid", 0, "values", 3),
                  ("spec", "grid", 0, "key"), ("spec", "grid", 0, "low"), ("spec", "samples"), ("spec", "seed"),
                  ("spec", "run"), ("spec", "orbit"), ("spec", "tol"), ("spec", "timeout"), ("spec", "random"),
                  ("spec", "max_steps"), ("extra",)]  # fmt: skip


def edit_json(document, path: tuple, value, remove: bool):
    """``document`` with the value at ``path`` replaced by ``value`` (or removed)."""
    node = document
    for key in path[:-1]:
        try:
            node = node[key]
        except (KeyError, IndexError, TypeError):
            return document
    if isinstance(node, dict) and remove:
        node.pop(path[-1], None)
    elif isinstance(node, dict) or (isinstance(node, list) and isinstance(path[-1], int) and path[-1] < len(node)):
        node[path[-1]] = value
    return document


def rewrite(path: Path, table: pa.Table) -> None:
    pq.write_table(table, path)


@st.composite
def damage(draw):
    """A function that damages a finished sweep's folder (drawn now, applied to a copy)."""
    target = draw(st.sampled_from(["manifest", "manifest", "table", "table", "table", "parts", "lock"]))
    if target == "manifest":
        how = draw(st.sampled_from(["edit", "edit", "nest", "cut", "flip", "text", "inflate"]))
        seed = draw(st.integers(0, 2**32 - 1))
        where, value, remove = draw(st.sampled_from(MANIFEST_PATHS)), draw(VALUES), draw(st.booleans())

        def apply(out: Path) -> None:
            path = out / "sweep.json"
            rng = np.random.default_rng(seed)
            raw = path.read_bytes()
            if how == "edit":
                path.write_text(json.dumps(edit_json(json.loads(raw), where, value, remove), default=str))
            elif how == "nest":
                path.write_text("[" * 100_000 + "]" * 100_000)
            elif how == "cut":
                path.write_bytes(raw[: int(rng.integers(0, len(raw)))])
            elif how == "flip":
                data = bytearray(raw)
                data[int(rng.integers(0, len(data)))] ^= 1 << int(rng.integers(0, 8))
                path.write_bytes(bytes(data))
            elif how == "inflate":  # a grid of 10 to 10^6 values: a manifest of up to 2 MB
                document = json.loads(raw)
                document["spec"]["grid"][0]["values"] *= int(10 ** rng.uniform(0, 5))
                path.write_text(json.dumps(document))
            else:
                path.write_text("\x1b[2J not json")

        return f"manifest {how} {seed}", apply
    if target == "table":
        kinds = ["flip", "cut", "drop", "rename", "retype", "index", "rows", "meta", "fifo", "empty"]
        how = draw(st.sampled_from([*kinds, "inflate", "bloat"]))
        seed = draw(st.integers(0, 2**32 - 1))

        def apply(out: Path) -> None:
            path = out / "results.parquet"
            rng = np.random.default_rng(seed)
            raw = path.read_bytes()
            table = pq.read_table(path)
            columns = table.column_names
            if how == "flip":
                data = bytearray(raw)
                data[int(rng.integers(0, len(data)))] ^= 1 << int(rng.integers(0, 8))
                path.write_bytes(bytes(data))
            elif how == "cut":
                path.write_bytes(raw[: int(rng.integers(0, len(raw)))])
            elif how == "drop":
                rewrite(path, table.drop_columns([columns[int(rng.integers(0, len(columns)))]]))
            elif how == "rename":
                k = int(rng.integers(0, len(columns)))
                rewrite(path, table.rename_columns([*columns[:k], "renamed", *columns[k + 1 :]]))
            elif how == "retype":
                k = int(rng.integers(0, len(columns)))
                column = table.column(k)
                rewrite(path, table.set_column(k, columns[k], pa.array([str(v) for v in column.to_pylist()])))
            elif how == "index":
                index = table.column("index").to_pylist()
                index[int(rng.integers(0, len(index)))] = int(rng.choice([-1, 12, 3, 2**40, 0]))
                rewrite(path, table.set_column(0, table.schema.field(0), pa.array(index, pa.int64())))
            elif how == "rows":
                keep = sorted(rng.choice(len(table), size=int(rng.integers(0, len(table))), replace=False).tolist())
                rewrite(path, table.take(pa.array(keep, pa.int64())))
            elif how == "inflate":  # 2 to 10^5 copies of the rows, the sweep's metadata kept
                rewrite(path, pa.concat_tables([table] * int(10 ** rng.uniform(0.3, 5))))
            elif how == "bloat":  # one text of 1 to 16 MiB, a few kilobytes once compressed
                error = table.column("error").to_pylist()
                error[int(rng.integers(0, len(error)))] = "x" * int(2 ** rng.uniform(20, 24))
                k = table.column_names.index("error")
                rewrite(path, table.set_column(k, table.schema.field(k), pa.array(error, pa.string())))
            elif how == "meta":
                rewrite(path, table.replace_schema_metadata({"legsim.sweep": str(rng.integers(0, 10**9))}))
            elif how == "fifo":
                path.unlink()
                os.mkfifo(path)
            else:
                rewrite(path, table.schema.empty_table())

        return f"table {how} {seed}", apply
    if target == "parts":
        how = draw(st.sampled_from(["copy", "foreign", "garbage", "file", "dir"]))

        def apply(out: Path) -> None:
            parts = out / "results.parts"
            if how == "file":
                parts.write_text("not a folder")
                return
            parts.mkdir()
            name = parts / "part-0000000000-deadbeef.parquet"
            table = pq.read_table(out / "results.parquet")
            if how == "copy":
                pq.write_table(table.slice(0, 5), name)
                pq.write_table(table.slice(3, 4), parts / "part-0000000003-cafecafe.parquet")
            elif how == "foreign":
                pq.write_table(pa.table({"index": pa.array([0, 1], pa.int64())}), name)
            elif how == "garbage":
                name.write_bytes(b"PAR1 not parquet PAR1")
            else:
                name.mkdir()

        return f"parts {how}", apply
    content = draw(st.sampled_from(["", "1\n", "999999\n", "\x00\xff", "x" * 100]))

    def apply(out: Path) -> None:
        (out / ".sweep.lock").write_text(content, errors="surrogateescape")

    return f"stale lock {content!r}", apply


def check_table(finished, case) -> None:
    base, reference = finished
    label, apply = case
    with tempfile.TemporaryDirectory(prefix="legsim-fuzz-resume-") as folder:
        out = Path(folder) / "done"
        shutil.copytree(base, out)
        apply(out)
        outcome, detail = table_outcome(out, reference)
    record(TABLES, outcome)
    assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), f"{outcome}: {detail}\n--- {label}"


def table_outcome(out: Path, reference: bytes) -> tuple[str, str]:
    try:
        with watchdog(HANG_SECONDS):
            code, _, err = run_cli(*BALL, *GRID, "--out", out, "--resume")
    except Hang as exc:
        return "hangs", str(exc)
    if code not in (0, 2) or "Traceback" in err or "internal error" in err:
        return ("silent wrong results" if code == 3 else "tracebacks"), f"exit {code}: {err[-2000:]}"
    if code == 2:
        if not err.startswith("legsim: error: ") or err.count("\n") != 1:
            return "tracebacks", err
        return "clear errors (exit 2)", err
    if temporaries(out):
        return "temporaries left", str(temporaries(out))
    if without_timing(pq.read_table(out / "results.parquet")) != reference:
        return "silent wrong results", "--resume accepted the folder and wrote another table"
    return "ran (exit 0 or 3)", ""


@pytest.mark.skipif(FULL, reason="the long form runs instead")
@fuzz_settings(50, long=False)
@given(case=damage())
def test_fuzzed_sweep_tables_resume_or_are_refused(finished, case):
    check_table(finished, case)


@pytest.mark.slow
@fuzz_settings(600, long=True)
@given(case=damage())
def test_fuzzed_sweep_tables_resume_or_are_refused_long(finished, case):
    check_table(finished, case)
