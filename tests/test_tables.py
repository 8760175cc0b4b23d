"""Text tables (legsim.tables) and the bench's: cells wrap at spaces within the width asked,
nothing is cut, no word is broken, the text is plain, and a cell is taken literally; the same
table as CSV, Markdown and JSON."""

import math

import pytest

from helpers.tables import read_cells
from legsim.bench.rows import Row
from legsim.bench.work_precision import format_table
from legsim.tables import Table, output_width, render_report, render_table


def test_every_cell_is_in_the_table_and_no_word_is_broken():
    header = ("name", "note", "value")
    rows = [
        ("first", "a note long enough to need several lines in a narrow table " * 2, "1.5e-07"),
        ("second_name_that_is_long", "[bold]markup is text[/bold] " + "z" * 50, "12"),
    ]
    table = Table.of(header, rows, right=[2], whole=[0, 2])
    assert table.least_width() == 24 + 2 + 50 + 2 + 7
    for width in (30, 50, 80, 200):
        text = render_table(header, rows, right=[2], whole=[0, 2], width=width)
        # Within the width asked, unless the names, numbers and longest word need more.
        assert max(len(line) for line in text.splitlines()) <= max(width, table.least_width()), text
        assert all(ord(c) < 128 for c in text) and "\x1b" not in text  # plain: no colours, ASCII rules
        words = [word for row in rows for cell in row for word in cell.split()]
        assert all(word in text.split() for word in words), text
        head, cells = read_cells(text, 3, key=0)
        assert head == list(header)
        assert cells == [["".join(cell.split()) for cell in row] for row in rows], text
    wide = render_table(header, rows, whole=[0, 2], width=200).splitlines()
    # Wide enough: one line per row, the numbers aligned right.
    assert len(wide) == 4 and wide[2].endswith("  1.5e-07") and wide[3].endswith("       12")


def test_without_a_width_nothing_wraps():
    rows = [("solve_ivp-RK45", "finished: " + "word " * 60, "3"), ("relaxed-dop853", "ok", "12")]
    lines = render_table(("method", "status", "n"), rows, whole=[0, 2], right=[2]).splitlines()
    assert len(lines) == 4 and lines[2].startswith("solve_ivp-RK45  finished: word") and lines[3].endswith("12")


def test_columns_kept_whole_never_wrap():
    rows = [("a_rather_long_case_name", "word " * 20, "3")]
    roomy = render_table(("case", "text", "n"), rows, whole=[0, 2], width=60).splitlines()
    assert roomy[2].startswith("a_rather_long_case_name  ")  # whole, the text wraps instead
    squeezed = render_table(("case", "text", "n"), rows, whole=[0, 2], width=20).splitlines()
    # Too narrow for the name: the table is wider than asked, the name on one line.
    assert squeezed[2].startswith("a_rather_long_case_name  word") and max(map(len, squeezed)) == 23 + 2 + 4 + 2 + 1


def test_the_narrowing_is_rich_tables_where_no_word_breaks():
    # Widths as rich.table gives them (padding and dividers included), then the floors: the
    # widest wrapping columns narrow together, down to the next widest, excess shared.
    table = Table.of(("a", "b"), [("x" * 71, "y" * 44)])
    assert table.column_widths(40) == [71, 44]  # one word per cell: floors
    table = Table.of(("a", "b"), [("xx " * 23 + "xx", "yy " * 14 + "yy")])
    assert table.column_widths(40) == [18, 20] and table.column_widths(None) == [71, 44]


def test_a_row_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match=r"a table row has 2 cells for 3 columns"):
        render_table(("a", "b", "c"), [("1", "2")])


def test_tables_fit_a_terminal_and_are_unwrapped_elsewhere(monkeypatch):
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setenv("COLUMNS", "77")  # what shutil.get_terminal_size reads first
    assert output_width(io.StringIO()) is None
    assert output_width(Terminal()) == 77


def test_the_formats_hold_the_same_cells():
    import csv
    import io
    import json

    table = Table.of(("method", "note|pipe", "n"), [("solve_ivp-RK45", 'a, "quoted" note', "3")], right=[2])
    report = ["# title", table, "", "targets: none"]
    out, err = render_report(report, "csv")
    assert list(csv.reader(io.StringIO(out))) == [list(table.header), *map(list, table.rows)]
    assert err == "# title\ntargets: none"
    out, err = render_report(report, "json")
    assert err == "" and json.loads(out) == {
        "tables": [
            {"title": "", "columns": list(table.header), "rows": [dict(zip(table.header, table.rows[0], strict=True))]}
        ],
        "text": ["# title", "targets: none"],
    }
    out, _ = render_report(report, "markdown")
    assert out.splitlines() == [
        "# title",
        "",
        "| method | note\\|pipe | n |",
        "| --- | --- | --: |",
        '| solve_ivp-RK45 | a, "quoted" note | 3 |',
        "",
        "targets: none",
    ]
    with pytest.raises(ValueError, match="unknown table format 'html'"):
        render_report(report, "html")


def test_bench_table_keeps_every_run_and_fits_the_width():
    rows = [
        Row(
            "c",
            f"relaxed-rk4-with-a-long-method-name-{k}",
            "relaxed",
            10.0**-k,
            1e-6,
            math.nan,
            math.inf,
            "",
            3.2e-5 * k,
            math.nan,
            0.01 * k,
            3,
            1000 * k,
            k,
            4000 * k,
            10,
            7,
            "finished: a status message " * 3,
            k % 2,
        )
        for k in range(1, 4)
    ]
    for width in (100, 160):
        text = format_table(rows, width=width)
        # The names and numbers need 132 columns: at 100 the table is that wide, none broken.
        assert max(len(line) for line in text.splitlines()) == max(width, 132), text
        assert all(line.split()[0] in {r.method for r in rows} for line in text.splitlines()[2:] if line[0] != " ")
        head, cells = read_cells(text, 14, key=1)  # h: a number, kept whole
        assert head[0] == "method" and head[-2:] == ["status", "P"]
        assert [c[0] for c in cells] == [r.method for r in rows]
        assert [c[12] for c in cells] == ["".join(r.status.split()) for r in rows]
        assert [c[13] for c in cells] == ["*", "", "*"]
