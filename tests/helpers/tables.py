"""Reading back a text table of legsim.tables: its cells, from the column gutters."""

from __future__ import annotations


def column_spans(lines: list[str]) -> list[tuple[int, int]]:
    """[start, end) of each column: runs of positions with text in some line, split at gutters
    (two or more positions blank in every line)."""
    width = max(len(line) for line in lines)
    padded = [line.ljust(width) for line in lines]
    used = [any(line[i] != " " for line in padded) for i in range(width)]
    spans: list[list[int]] = []
    for i, u in enumerate(used):
        if not u:
            continue
        if spans and i - spans[-1][1] < 2:
            spans[-1][1] = i + 1
        else:
            spans.append([i, i + 1])
    return [(a, b) for a, b in spans]


def read_cells(table: str, columns: int, key: int = 0) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of the table at the start of ``table`` (up to its first empty line), each
    cell's wrapped lines joined with their blanks removed. A row starts on a line where column
    ``key`` has text (cells are top-aligned)."""
    lines = table.split("\n\n")[0].splitlines()
    rule = next(i for i, line in enumerate(lines) if line and set(line) == {"-"})
    spans = column_spans(lines[:rule] + lines[rule + 1 :])
    assert len(spans) == columns, (spans, table)

    def cells(block: list[str]) -> list[str]:
        return ["".join("".join(line.ljust(b)[a:b].split()) for line in block) for a, b in spans]

    rows: list[list[str]] = []
    for line in lines[rule + 1 :]:
        a, b = spans[key]
        if line.ljust(b)[a:b].strip() or not rows:
            rows.append([])
        rows[-1].append(line)
    return cells(lines[:rule]), [cells(block) for block in rows]
