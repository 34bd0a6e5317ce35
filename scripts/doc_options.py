"""Write the option tables of the docs from the config dataclasses, or check that they are current.

A table sits between `<!-- options: package.module:Class -->` and `<!-- /options -->` in a page of
docs/; this script replaces what is between the markers with `dialfred_sim.dataclass_cli.markdown_options`
of that class (and the rows a job adds beside its fields, EXTRA below). Between
`<!-- parameters: package.module -->` and `<!-- /parameters -->` goes the table of a node module's
PARAMETERS (`dialfred_sim.ros_util.Param`).

    ./dialfred env python scripts/doc_options.py          # rewrite the tables
    ./dialfred env python scripts/doc_options.py --check  # exit 1 naming each stale table
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from pathlib import Path

from dialfred_sim.dataclass_cli import markdown_options

DOCS = Path(__file__).resolve().parents[1] / 'docs'
BLOCK = re.compile(r'(<!-- options: (?P<target>[\w.]+:\w+) -->\n)(?P<table>.*?)(<!-- /options -->)', re.S)
PARAMETER_BLOCK = re.compile(r'(<!-- parameters: (?P<target>[\w.]+) -->\n)(?P<table>.*?)(<!-- /parameters -->)', re.S)
# Options a job's parser adds beside its config's fields: (flag, meaning, default).
EXTRA = {'dialfred_bringup.eval_config:EvalConfig': [('--no-progress', 'no progress bar on stderr', '--progress')]}


def table(target: str) -> str:
    module, name = target.split(':')
    return markdown_options(getattr(importlib.import_module(module), name), EXTRA.get(target, ()))


def parameter_table(module: str) -> str:
    """A Markdown table of a node module's PARAMETERS: name, default, values, whether it may change
    while the node runs, meaning."""
    rows = ['| parameter | default | values | at run time | meaning |', '|---|---|---|---|---|']
    repo = str(DOCS.parent)
    for p in importlib.import_module(module).PARAMETERS:
        values = (f'{p.span[0]} to {p.span[1]}' if p.span else
                  ', '.join(f'`{c!r}`' if c == '' else f'`{c}`' for c in p.allowed()) if p.choices else
                  '`true`, `false`' if isinstance(p.default, bool) else 'any')
        default = p.default
        if isinstance(default, str) and default.startswith(repo + '/'):
            default = default[len(repo) + 1:]          # a file of the repository, wherever it is cloned
        meaning = p.description.replace('|', '\\|')
        shown = str(default).lower() if isinstance(default, bool) else repr(default)
        rows.append(f'| `{p.name}` | `{shown}` | {values} | {"may change" if p.dynamic else "read-only"} | '
                    f'{meaning} |')
    return '\n'.join(rows) + '\n'


def rewrite(text: str) -> str:
    text = BLOCK.sub(lambda m: m.group(1) + table(m.group('target')) + m.group(4), text)
    return PARAMETER_BLOCK.sub(lambda m: m.group(1) + parameter_table(m.group('target')) + m.group(4), text)


def stale_pages(docs: Path = DOCS) -> list[str]:
    """The pages whose option tables differ from what the dataclasses make."""
    return [p.name for p in sorted(docs.glob('*.md')) if rewrite(p.read_text()) != p.read_text()]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--check', action='store_true', help='only check; exit 1 if a table is stale')
    args = ap.parse_args(argv)
    stale = stale_pages()
    if args.check:
        for name in stale:
            print(f'docs/{name}: an option table is stale; run scripts/doc_options.py', file=sys.stderr)
        return 1 if stale else 0
    for name in stale:
        path = DOCS / name
        path.write_text(rewrite(path.read_text()))
        print(f'rewrote the option tables of docs/{name}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
