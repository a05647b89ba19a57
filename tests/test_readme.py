"""The README's tables are well formed: each row has its header's number of cells (a table
pasted under the wrong header shows up here)."""

from __future__ import annotations

from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _tables(lines: list[str]):
    """``(header line number, header cells, [(line number, cells), ...])`` of every Markdown
    table outside code blocks."""
    in_code, table = False, None
    for number, line in enumerate(lines, 1):
        if line.startswith("```"):
            in_code = not in_code
        is_row = not in_code and line.startswith("|") and line.rstrip().endswith("|")
        if is_row and table is None:
            table = (number, _cells(line), [])
        elif is_row:
            table[2].append((number, _cells(line)))
        elif table is not None:
            yield table
            table = None
    if table is not None:
        yield table


def _cells(line: str) -> int:
    return len(line.strip().strip("|").split("|"))


def test_every_readme_table_row_has_its_header_cells():
    tables = list(_tables(README.read_text(encoding="utf-8").splitlines()))
    assert len(tables) >= 5
    bad = [f"line {n}: {cells} cells under the {head}-cell header of line {h}"
           for h, head, rows in tables for n, cells in rows if cells != head]
    assert not bad, "\n".join(bad)
