"""Text tables the commands print (``legsim stress``, ``legsim bench``), laid out by ``rich.table``.

A cell too long for its column wraps onto the next lines of its row (at spaces, long words
folded): nothing is cut. The table fits the terminal's width when printed to one and
``PIPE_WIDTH`` columns otherwise; the text is plain (no colours, ASCII rules) either way, so
logs and pipes read the same as the screen.
"""

from __future__ import annotations

import io
import shutil
import sys
from collections.abc import Iterable, Sequence
from typing import TextIO

from rich.box import Box
from rich.console import Console
from rich.table import Table
from rich.text import Text

#: Width (characters) of a table printed to a pipe or a file.
PIPE_WIDTH = 120
#: Characters a wrapping column is left at least before the columns kept whole are wrapped too.
MIN_WRAPPED = 12
#: The header, a rule of dashes under it, the rows: no frame, no lines between rows.
PLAIN_HEAD = Box("    \n    \n -- \n    \n    \n    \n    \n    \n", ascii=True)


def output_width(stream: TextIO | None = None) -> int:
    """Characters a table printed to ``stream`` (default stdout) may take: the terminal's
    width on a terminal, ``PIPE_WIDTH`` elsewhere."""
    stream = stream if stream is not None else sys.stdout
    try:
        interactive = stream.isatty()
    except (AttributeError, ValueError):
        interactive = False
    return shutil.get_terminal_size((PIPE_WIDTH, 24)).columns if interactive else PIPE_WIDTH


def render_table(
    header: Sequence[str],
    rows: Iterable[Sequence[str]],
    *,
    right: Iterable[int] = (),
    whole: Iterable[int] = (),
    width: int | None = None,
) -> str:
    """The table as text at most ``width`` characters wide (default ``output_width()``).

    ``header``: the column titles; ``rows``: one sequence of cell texts per row, as many as the
    header (taken literally: no markup); ``right``: indices of the columns aligned right
    (numbers); ``whole``: indices of the columns whose cells wrap only when the others cannot
    make room (names, numbers; the widest of them wrap first then): the long text columns wrap
    first. Lines carry no trailing blanks.
    """
    header = [str(title) for title in header]
    cells = [[str(cell) for cell in row] for row in rows]
    for row in cells:
        if len(row) != len(header):
            raise ValueError(f"a table row has {len(row)} cells for {len(header)} columns: {row}")
    width = width or output_width()
    aligned_right = set(right)
    kept = _kept_whole(header, cells, set(whole), width)
    table = Table(box=PLAIN_HEAD, show_edge=False, pad_edge=False, collapse_padding=True)
    for i, title in enumerate(header):
        table.add_column(
            Text(title), justify="right" if i in aligned_right else "left", overflow="fold", no_wrap=i in kept
        )
    for row in cells:
        table.add_row(*(Text(cell) for cell in row))
    buffer = io.StringIO()
    console = Console(
        file=buffer, width=width, color_system=None, highlight=False, force_terminal=False, legacy_windows=False
    )
    console.print(table)
    return "\n".join(line.rstrip() for line in buffer.getvalue().rstrip("\n").splitlines())


def _kept_whole(header: list[str], rows: list[list[str]], whole: set[int], width: int) -> set[int]:
    """The columns of ``whole`` kept at their full width: all of them when that leaves every
    other column ``MIN_WRAPPED`` characters within ``width``, else without the widest ones
    until it does (a squeezed table wraps a long name rather than cutting a column)."""
    natural = [max([len(title), *(len(row[i]) for row in rows)]) for i, title in enumerate(header)]
    kept = sorted(whole, key=lambda i: natural[i])
    while kept:
        least = [natural[i] if i in kept else min(natural[i], MIN_WRAPPED) for i in range(len(header))]
        if sum(least) + 2 * (len(header) - 1) <= width:
            break
        kept.pop()
    return set(kept)
