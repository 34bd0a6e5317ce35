"""Every markdown table of the README and docs/ is whole: each row has the header's number of cells,
and no paragraph runs on from a table's last row (it would be read as part of that row's last cell)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]
RULE = re.compile(r'^\|[\s:|-]+\|\s*$')


def cells(line: str) -> list[str]:
    """The cells of a table row: split on '|' outside code spans, '\\|' being a pipe inside a cell."""
    out, cur, code, k = [], '', False, 0
    while k < len(line):
        ch = line[k]
        if ch == '\\' and line[k + 1:k + 2] == '|':
            cur, k = cur + '|', k + 2
            continue
        if ch == '`':
            code = not code
        if ch == '|' and not code:
            out.append(cur)
            cur = ''
        else:
            cur += ch
        k += 1
    out.append(cur)
    return out[1:-1]


def broken_rows(text: str) -> list[tuple[int, str]]:
    lines = text.split('\n')
    problems, k = [], 0
    while k < len(lines):
        if not (lines[k].startswith('|') and k + 1 < len(lines) and RULE.match(lines[k + 1])):
            k += 1
            continue
        width, j = len(cells(lines[k])), k + 2
        while j < len(lines) and lines[j].startswith('|'):
            if len(cells(lines[j])) != width:
                problems.append((j + 1, f'{len(cells(lines[j]))} cells, the header has {width}'))
            j += 1
        if j < len(lines) and lines[j].strip() and not lines[j].startswith('<!--'):
            problems.append((j + 1, f'text right after the table: {lines[j][:50]!r}'))
        k = j
    return problems


@pytest.mark.parametrize('page', PAGES, ids=lambda p: p.name)
def test_every_table_row_is_whole(page):
    assert broken_rows(page.read_text()) == []


def test_a_paragraph_inside_a_table_is_found():
    text = '| a | b |\n|---|---|\n| x | the cell goes on\nhere, outside the table |\n| y | z |\n'
    assert [line for line, _ in broken_rows(text)] == [3, 4]     # the cut row, then the run-on text
