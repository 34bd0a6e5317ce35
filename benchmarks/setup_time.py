#!/usr/bin/env python3
"""Set-up time of the README test command's set-up step on a fresh clone: first and second run.

Clones the committed repository into a temporary folder and times `./dialfred setup` twice there.
The first run creates the venv, installs requirements.txt (pip's download cache is whatever this
machine has; the JSON says whether one existed) and colcon-builds src/. Prints JSON.

    python3 benchmarks/setup_time.py        # needs only git and python3, not the project venv
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def timed(cmd, cwd) -> float:
    t0 = time.monotonic()
    subprocess.run(cmd, cwd=cwd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - t0


def main(argv=None) -> None:
    argparse.ArgumentParser(prog='python3 benchmarks/setup_time.py', description=__doc__.split('\n\n')[0],
                            epilog='It takes no arguments; it prints JSON.').parse_args(argv)
    cache = Path.home() / '.cache' / 'pip'
    with tempfile.TemporaryDirectory() as tmp:
        clone = Path(tmp) / 'dialfred'
        subprocess.run(['git', 'clone', '-q', str(REPO), str(clone)], check=True)
        first = timed(['./dialfred', 'setup'], clone)
        second = timed(['./dialfred', 'setup'], clone)
    print(json.dumps({'benchmark': 'setup_time', 'first_run_s': round(first, 1),
                      'second_run_s': round(second, 1), 'pip_cache_present': cache.exists()}, indent=2))


if __name__ == '__main__':
    sys.exit(main())
