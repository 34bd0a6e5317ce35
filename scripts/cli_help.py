"""Write the `--help` text of every command of ./dialfred into docs/cli/, or check that it is current.

`./dialfred CMD --help` needs no set-up: on a checkout without .venv it prints the file written here,
the same text the command prints once set up (at 100 columns). One file a command (and one for each
`launch` job): docs/cli/<command>.txt, docs/cli/launch-<job>.txt.

    ./dialfred env python scripts/cli_help.py          # rewrite the files
    ./dialfred env python scripts/cli_help.py --check  # exit 1 naming each stale file
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import runpy
import sys
import warnings
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / 'docs' / 'cli'
COLUMNS = '100'
# file name -> (module run as `python -m`, its arguments before --help)
COMMANDS = {
    'demo': ('dialfred_bringup.launch', ['demo']),     # with DIALFRED_LAUNCH_PROG, as ./dialfred runs it (PROGS)
    'launch': ('dialfred_bringup.launch', []),
    'launch-demo': ('dialfred_bringup.launch', ['demo']),
    'launch-eval': ('dialfred_bringup.launch', ['eval']),
    'launch-nodes': ('dialfred_bringup.launch', ['nodes']),
    'launch-dialogue': ('dialfred_bringup.launch', ['dialogue']),
    'launch-explore': ('dialfred_bringup.launch', ['explore']),
    'graph': ('dialfred_bringup.graph_info', []),
    'baselines': ('dialfred_bringup.baseline_runs', []),
    'reproduce': ('dialfred_bringup.reproduce', []),
    'replay': ('dialfred_bringup.replay', []),
    'merge': ('dialfred_bringup.shards', []),
    'report': ('dialfred_bringup.report', []),
    'score': ('dialfred_bringup.score', []),
    'prepare-performer': ('dialfred_performer.prepare', []),
    'train-performer': ('dialfred_performer.train', []),
}


# The launcher's name as ./dialfred gives it for a command (the wrapper's DIALFRED_LAUNCH_PROG).
PROGS = {'demo': './dialfred'}


def help_text(module: str, args: list, prog: str = '') -> str:
    """What `python -m module ARGS --help` prints, at COLUMNS columns (`prog`: DIALFRED_LAUNCH_PROG)."""
    out = io.StringIO()
    saved = sys.argv, os.environ.get('COLUMNS')
    os.environ['COLUMNS'] = COLUMNS
    if prog:
        os.environ['DIALFRED_LAUNCH_PROG'] = prog
    sys.argv = [module, *args, '--help']
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit), warnings.catch_warnings():
            warnings.simplefilter('ignore', RuntimeWarning)     # runpy: the module was imported by its package
            runpy.run_module(module, run_name='__main__', alter_sys=True)
    finally:
        os.environ.pop('DIALFRED_LAUNCH_PROG', None)
        sys.argv = saved[0]
        if saved[1] is None:
            os.environ.pop('COLUMNS', None)
        else:
            os.environ['COLUMNS'] = saved[1]
    return out.getvalue()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--check', action='store_true', help='write nothing; exit 1 naming each stale file')
    args = ap.parse_args(argv)
    stale = []
    for name, (module, words) in COMMANDS.items():
        text, path = help_text(module, words, PROGS.get(name, '')), OUT / f'{name}.txt'
        if not text.strip():
            raise SystemExit(f'{module} {" ".join(words)} --help printed nothing')
        if path.exists() and path.read_text() == text:
            continue
        stale.append(path)
        if not args.check:
            OUT.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
    if args.check and stale:
        print('stale --help files (run ./dialfred env python scripts/cli_help.py): '
              + ', '.join(str(p.relative_to(OUT.parents[1])) for p in stale), file=sys.stderr)
        return 1
    if not args.check and stale:
        print(f'rewrote {len(stale)} --help files in {OUT.relative_to(OUT.parents[1])}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
