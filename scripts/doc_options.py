"""Write the option tables of the docs from the config dataclasses, or check that they are current.

A table sits between `<!-- options: package.module:Class -->` and `<!-- /options -->` in a page of
docs/; this script replaces what is between the markers with `dialfred_sim.dataclass_cli.markdown_options`
of that class (and the rows a job adds beside its fields, EXTRA below).

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
# Options a job's parser adds beside its config's fields: (flag, meaning, default).
EXTRA = {'dialfred_bringup.evaluation:EvalConfig': [('--no-progress', 'no progress bar on stderr', '--progress')]}


def table(target: str) -> str:
    module, name = target.split(':')
    return markdown_options(getattr(importlib.import_module(module), name), EXTRA.get(target, ()))


def rewrite(text: str) -> str:
    return BLOCK.sub(lambda m: m.group(1) + table(m.group('target')) + m.group(4), text)


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
