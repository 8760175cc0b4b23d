"""Text tables (legsim.tables) and the bench's: cells wrap within the width asked, nothing is
cut, the text is plain, and a cell is taken literally."""

import math

import pytest

from helpers.tables import read_cells
from legsim.bench.work_precision import Row, format_table
from legsim.tables import PIPE_WIDTH, output_width, render_table


def test_every_cell_is_in_the_table_and_no_line_is_wider_than_asked():
    header = ("name", "note", "value")
    rows = [
        ("first", "a note long enough to need several lines in a narrow table " * 2, "1.5e-07"),
        ("second_name_that_is_long", "[bold]markup is text[/bold] " + "z" * 50, "12"),
    ]
    for width in (30, 50, 80, 200):
        text = render_table(header, rows, right=[2], whole=[0, 2], width=width)
        assert max(len(line) for line in text.splitlines()) <= width, text
        assert all(ord(c) < 128 for c in text) and "\x1b" not in text  # plain: no colours, ASCII rules
        head, cells = read_cells(text, 3, key=0 if width >= 50 else 2)
        assert head == list(header)
        assert cells == [["".join(cell.split()) for cell in row] for row in rows], text
    wide = render_table(header, rows, whole=[0, 2], width=200).splitlines()
    # Wide enough: one line per row, the numbers aligned right.
    assert len(wide) == 4 and wide[2].endswith("  1.5e-07") and wide[3].endswith("       12")


def test_columns_kept_whole_wrap_only_when_the_others_cannot_make_room():
    rows = [("a_rather_long_case_name", "word " * 20, "3")]
    roomy = render_table(("case", "text", "n"), rows, whole=[0, 2], width=60).splitlines()
    assert roomy[2].startswith("a_rather_long_case_name  ")  # whole, the text wraps instead
    squeezed = render_table(("case", "text", "n"), rows, whole=[0, 2], width=30)
    assert max(len(line) for line in squeezed.splitlines()) <= 30 and "a_rather_long_case_name" not in squeezed


def test_a_row_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match=r"a table row has 2 cells for 3 columns"):
        render_table(("a", "b", "c"), [("1", "2")])


def test_tables_fit_a_terminal_and_take_the_pipe_width_elsewhere(monkeypatch):
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    assert output_width(io.StringIO()) == PIPE_WIDTH
    monkeypatch.setenv("COLUMNS", "77")  # what shutil.get_terminal_size reads first
    assert output_width(Terminal()) == 77


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
        assert max(len(line) for line in text.splitlines()) <= width, text
        head, cells = read_cells(text, 14, key=1)  # h: a number, kept whole
        assert head[0] == "method" and head[-2:] == ["status", "P"]
        assert [c[0] for c in cells] == [r.method for r in rows]
        assert [c[12] for c in cells] == ["".join(r.status.split()) for r in rows]
        assert [c[13] for c in cells] == ["*", "", "*"]
