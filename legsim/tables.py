"""Tables the commands print (``legsim stress``, ``legsim bench ...``): as text laid out by
``rich.table``, or as CSV, Markdown or JSON (``--format``).

Text: on a terminal the table fits the terminal's width where it can: the long text columns
wrap at spaces onto more lines of their row. A cell is never broken inside a word: names and
numbers (the ``whole`` columns) never wrap, and a text column is never narrower than its longest
word, so a table that cannot fit otherwise is wider than the terminal. Into a pipe or a file
nothing wraps: each row is one line, whatever the width, so that ``grep`` and ``cut`` see whole
rows. The text is plain either way (no colours, ASCII rules).

A command's output is a report: lines of text and tables in order (``render_report``). In CSV
only the tables go to stdout (the lines go to stderr), so that the output reads as CSV; JSON
holds both.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import shutil
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TextIO

#: The box of a text table (``rich.box.Box``'s eight rows of four characters): the header, a
#: rule of dashes under it, the rows; no frame, no lines between rows.
PLAIN_HEAD = "    \n    \n -- \n    \n    \n    \n    \n    \n"
#: Blanks between two columns of a text table.
GUTTER = 2
#: The output formats of ``--format``.
FORMATS = ("text", "csv", "markdown", "json")


def output_width(stream: TextIO | None = None) -> int | None:
    """Characters a table printed to ``stream`` (default stdout) may take: the terminal's width
    on a terminal, None (no limit: nothing wraps) elsewhere."""
    stream = stream if stream is not None else sys.stdout
    try:
        interactive = stream.isatty()
    except (AttributeError, ValueError):
        interactive = False
    return shutil.get_terminal_size().columns if interactive else None


@dataclass(frozen=True)
class Table:
    """A table of text cells: ``header`` (column titles), ``rows`` (as many cells as titles,
    taken literally: no markup), ``right`` (indices of the columns aligned right: numbers),
    ``whole`` (indices of the columns whose cells never wrap: names, numbers) and ``title``
    (what the table shows, for CSV and JSON readers)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    right: frozenset[int] = field(default_factory=frozenset)
    whole: frozenset[int] = field(default_factory=frozenset)
    title: str = ""

    @classmethod
    def of(
        cls,
        header: Sequence[str],
        rows: Iterable[Sequence[object]],
        *,
        right: Iterable[int] = (),
        whole: Iterable[int] = (),
        title: str = "",
    ) -> Table:
        """The table of ``header`` and ``rows`` (cells turned to text); ValueError naming a row
        whose length is not the header's."""
        head = tuple(str(title) for title in header)
        cells = tuple(tuple(str(cell) for cell in row) for row in rows)
        for row in cells:
            if len(row) != len(head):
                raise ValueError(f"a table row has {len(row)} cells for {len(head)} columns: {list(row)}")
        return cls(head, cells, frozenset(right), frozenset(whole), title)

    def natural_widths(self) -> list[int]:
        """Each column's width unwrapped: its widest cell or title."""
        return [max([len(title), *(len(row[i]) for row in self.rows)]) for i, title in enumerate(self.header)]

    def least_widths(self) -> list[int]:
        """Each column's narrowest width: a whole column's natural width, another column's
        longest word (rich then wraps at spaces only and never folds a word)."""
        natural = self.natural_widths()
        return [natural[i] if i in self.whole else _longest_word(self, i) for i in range(len(self.header))]

    def least_width(self) -> int:
        """The narrowest the text table can be: wider than a ``width`` asked of ``text``, the
        table takes this width."""
        return sum(self.least_widths()) + GUTTER * (len(self.header) - 1)

    def text(self, width: int | None = None) -> str:
        """The table as text at most ``width`` characters wide where words allow (None: no
        limit, one line per row); lines carry no trailing blanks."""
        # rich is imported here, not with the module: the commands import this module at start.
        from rich.box import Box
        from rich.console import Console
        from rich.table import Table as RichTable
        from rich.text import Text

        widths = self.column_widths(width)
        table = RichTable(box=Box(PLAIN_HEAD, ascii=True), show_edge=False, pad_edge=False, collapse_padding=True)
        for i, title in enumerate(self.header):
            table.add_column(
                Text(title),
                justify="right" if i in self.right else "left",
                overflow="fold",
                no_wrap=i in self.whole,
                width=widths[i],
            )
        for row in self.rows:
            table.add_row(*(Text(cell) for cell in row))
        total = sum(widths) + GUTTER * (len(widths) - 1)
        buffer = io.StringIO()
        console = Console(
            file=buffer, width=total, color_system=None, highlight=False, force_terminal=False, legacy_windows=False
        )
        console.print(table)
        return "\n".join(line.rstrip() for line in buffer.getvalue().rstrip("\n").splitlines())

    def column_widths(self, width: int | None = None) -> list[int]:
        """Each column's width in a text table at most ``width`` characters wide (None: no
        limit): the text columns are narrowed as ``rich.table`` narrows wrapping columns (the
        widest first, down to the next widest), but never below their longest word."""
        natural, floor = self.natural_widths(), self.least_widths()
        if width is None:
            return natural
        # As rich counts them: a column's width with its padding (one blank after every column
        # but the last) within the width less the dividers (one blank between two columns); a
        # wrapping column starts no wider than that.
        last, limit = len(natural) - 1, width - (len(natural) - 1)
        wrapping = [i not in self.whole for i in range(len(natural))]
        floors = [w + (i < last) for i, w in enumerate(floor)]
        padded = [w + (i < last) for i, w in enumerate(natural)]
        padded = [max(min(w, limit), f) if wraps else w for w, f, wraps in zip(padded, floors, wrapping, strict=True)]
        padded = _narrowed(padded, floors, wrapping, limit)
        return [w - (i < last) for i, w in enumerate(padded)]

    def csv(self) -> str:
        """The header and the rows as CSV (RFC 4180 quoting, ``\\n`` line ends)."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(self.header)
        writer.writerows(self.rows)
        return buffer.getvalue().rstrip("\n")

    def markdown(self) -> str:
        """The table in Markdown (GitHub's pipe tables): right-aligned columns marked ``--:``,
        ``|`` in a cell escaped, a line break in a cell written as ``<br>``."""

        def cell(text: str) -> str:
            return text.replace("\\", "\\\\").replace("|", "\\|").replace("\n", "<br>")

        rule = ["--:" if i in self.right else "---" for i in range(len(self.header))]
        lines = [self.header, rule, *self.rows]
        return "\n".join("| " + " | ".join(cell(c) for c in line) + " |" for line in lines)

    def to_json(self) -> dict[str, object]:
        """``{"title", "columns", "rows": [{column: cell}, ...]}``."""
        return {
            "title": self.title,
            "columns": list(self.header),
            "rows": [dict(zip(self.header, row, strict=True)) for row in self.rows],
        }


def _narrowed(widths: list[int], floors: list[int], wrapping: list[bool], limit: int) -> list[int]:
    """``widths`` with a total of at most ``limit`` where the ``wrapping`` columns allow, none
    below its floor: the widest of them are narrowed together, each step at most down to the
    next widest, the excess shared in proportion. That is rich.table's rule, with the floors
    added: a table that needs no word broken is laid out as rich lays it out."""
    widths = list(widths)
    while (excess := sum(widths) - limit) > 0:
        narrowing = [wraps and w > f for w, f, wraps in zip(widths, floors, wrapping, strict=True)]
        if not any(narrowing):
            break
        widest = max(w for w, n in zip(widths, narrowing, strict=True) if n)
        next_widest = max((w for w, wraps in zip(widths, wrapping, strict=True) if wraps and w < widest), default=0)
        sharing = [i for i, n in enumerate(narrowing) if n and widths[i] == widest]
        left = excess
        for k, i in enumerate(sharing):
            cut = min(excess, widest - next_widest, round(left / (len(sharing) - k)), widths[i] - floors[i])
            widths[i] -= cut
            left -= cut
    return widths


def _longest_word(table: Table, column: int) -> int:
    texts = [table.header[column], *(row[column] for row in table.rows)]
    return max([1, *(len(word) for text in texts for word in text.split())])


def render_table(
    header: Sequence[str],
    rows: Iterable[Sequence[object]],
    *,
    right: Iterable[int] = (),
    whole: Iterable[int] = (),
    width: int | None = None,
) -> str:
    """``Table.of(header, rows, right=, whole=).text(width)``: the table as text."""
    return Table.of(header, rows, right=right, whole=whole).text(width)


#: What a command prints: lines of text and tables, in order.
Report = Sequence["str | Table"]


def render_report(report: Report, fmt: str = "text", width: int | None = None) -> tuple[str, str]:
    """(stdout, stderr) texts of ``report`` in the format ``fmt`` (one of ``FORMATS``).

    text: the lines, and the tables as text within ``width`` (None: unwrapped); markdown: the
    lines, and the tables as Markdown between blank lines; csv: the tables only (one blank line
    between two), the lines go to stderr; json: ``{"tables": [Table.to_json(), ...], "text":
    [line, ...]}``. A text line is one item of the report, line breaks and all."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown table format {fmt!r}; choose one of {', '.join(FORMATS)}")
    tables = [part for part in report if isinstance(part, Table)]
    lines = [part for part in report if not isinstance(part, Table)]
    if fmt == "json":
        document = {"tables": [t.to_json() for t in tables], "text": [line for line in lines if line.strip()]}
        return json.dumps(document, allow_nan=False), ""
    if fmt == "csv":
        return "\n\n".join(t.csv() for t in tables), "\n".join(line for line in lines if line.strip())
    if fmt == "text":
        return "\n".join(part.text(width) if isinstance(part, Table) else part for part in report).rstrip("\n"), ""
    # Markdown: a table between blank lines, never two blank lines in a row.
    out: list[str] = []
    for part in report:
        for line in ["", part.markdown(), ""] if isinstance(part, Table) else [part]:
            if line or (out and out[-1]):
                out.append(line)
    return "\n".join(out).strip("\n"), ""


def print_report(report: Report, fmt: str = "text") -> None:
    """Print ``report`` in the format ``fmt``: to stdout, and (CSV) its lines to stderr; text
    tables within the terminal's width, unwrapped into a pipe (``output_width``)."""
    out, err = render_report(report, fmt, output_width(sys.stdout))
    if err:
        print(err, file=sys.stderr, flush=True)
    if out:
        print(out, flush=True)


def add_format_argument(parser: argparse.ArgumentParser) -> None:
    """The ``--format`` option of a command that prints tables."""
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default="text",
        help="how tables are printed: text (wrapped to a terminal's width, one line per row into a "
        "pipe), csv (the tables only; other lines to stderr), markdown, or json",
    )
