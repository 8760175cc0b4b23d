"""Tables through a pipe: no name is broken across lines (each row is one line, whatever
COLUMNS says), and ``--format csv|markdown|json`` prints the same cells."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import subprocess
import sys

from legsim.bench.rows import Row
from legsim.bench.work_precision import rows_table, write_csv


def _legsim(*argv: str) -> subprocess.CompletedProcess:
    """``legsim ARGV`` with stdout and stderr pipes, as ``legsim ... | cat`` runs it, and a
    narrow COLUMNS, which a pipe ignores."""
    return subprocess.run(
        [sys.executable, "-m", "legsim", *argv],
        env={**os.environ, "COLUMNS": "40"},
        capture_output=True,
        text=True,
        timeout=600,
    )


def _rows_of(text: str, names: set[str]) -> list[str]:
    """The lines of the table in ``text`` (from its header line, starting ``method``, to the
    first empty line); each must start with a whole name of ``names``."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("method "))
    body = lines[start + 2 : lines.index("", start)]
    assert all(line.split()[0] in names for line in body), "\n".join(body)
    return body


def test_the_bench_table_in_a_pipe_breaks_no_name(tmp_path):
    # The check: `legsim bench work-precision --case bouncing-ball --quick | cat`.
    result = _legsim(
        "bench",
        "work-precision",
        "--case",
        "bouncing-ball",
        "--quick",
        "--no-figure",
        "--quiet",
        "--out",
        str(tmp_path),
    )
    assert result.returncode == 0, result.stderr
    names = {"relaxed-rk4", "relaxed-euler", "solve_ivp-RK45"}
    assert len(_rows_of(result.stdout, names)) == 3


def _long_rows() -> list[Row]:
    nan = math.nan
    return [
        Row("bouncing-ball", f"relaxed-rk4-with-a-rather-long-name-{k}", "relaxed", 0.01, 1e-6, nan, math.inf, "aim",
            10.0**-k, nan, 1e-3 * k, 1, 100, 0, 400, 10, 5, "finished: with a status long enough to wrap " * 2)
        for k in range(1, 4)
    ]  # fmt: skip


def test_long_names_and_statuses_stay_on_one_line_in_a_pipe(tmp_path):
    rows = _long_rows()
    write_csv(rows, tmp_path / "bouncing-ball.csv")
    result = _legsim("bench", "targets", "--case", "bouncing-ball", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    body = _rows_of(result.stdout, {r.method for r in rows})
    assert len(body) == 3 and all(line.endswith(rows[0].status.strip()) for line in body)


def test_the_formats_print_the_tables_cells(tmp_path):
    rows = _long_rows()
    write_csv(rows, tmp_path / "bouncing-ball.csv")
    table = rows_table(rows)
    argv = ("bench", "targets", "--case", "bouncing-ball", "--out", str(tmp_path), "--format")
    as_csv = _legsim(*argv, "csv")
    assert as_csv.returncode == 0 and list(csv.reader(io.StringIO(as_csv.stdout))) == [
        list(table.header),
        *map(list, table.rows),
    ]
    assert "targets:" in as_csv.stderr  # what is not the table goes to stderr
    as_json = json.loads(_legsim(*argv, "json").stdout)
    assert as_json["tables"][0]["rows"][1]["method"] == rows[1].method and "targets:" in as_json["text"]
    markdown = _legsim(*argv, "markdown").stdout.splitlines()
    assert markdown[0] == "| " + " | ".join(table.header) + " |" and markdown[1].startswith("| --- | --: |")


def test_the_stress_table_in_a_pipe_has_one_line_per_case():
    result = _legsim("stress", "--quick", "--case", "zeno_two_tanks")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[3].startswith("zeno_two_tanks  finished; 10 switches") and lines[3].endswith("pass")
    assert lines[4] == ""
