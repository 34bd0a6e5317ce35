#!/usr/bin/env python3
"""What importing each module of src/ costs: the heavy packages it loads, and the seconds it takes.

Each module is imported alone in a fresh interpreter (so nothing another module loaded counts), and the
heavy packages found in `sys.modules` afterwards are listed. A module that needs no simulator, network or
ROS (the protocol, the oracle's rules, the results schema) should load none of them; an import moved to
module level must not make a light module heavy. Also counts the imports still inside functions (each
says why in a comment: tests/system/test_import_graph.py). Prints JSON.

    ./dialfred bench import_weight                          # every module (minutes: each starts a Python)
    ./dialfred bench import_weight --modules dialfred_sim.protocol dialfred_oracle.answers
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
from pathlib import Path

from dialfred_bringup.paths import REPO, source_modules

HEAVY = ('torch', 'rclpy', 'dialfred_msgs', 'pybullet', 'gymnasium', 'PIL', 'foxglove', 'rosbags', 'matplotlib')
PROBE = ('import sys, time\nt0 = time.perf_counter()\nimport {module}\nseconds = time.perf_counter() - t0\n'
         'print(repr((seconds, [h for h in {heavy!r} if h in sys.modules])))')


def weigh(module: str, timeout: float = 300) -> dict:
    """{'heavy': [...], 'seconds': s} of importing `module` in a fresh interpreter; {'error': ...} if it fails."""
    proc = subprocess.run([sys.executable, '-c', PROBE.format(module=module, heavy=HEAVY)], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)
    if proc.returncode:
        return {'error': (proc.stderr.strip().splitlines() or ['exit status %d' % proc.returncode])[-1][:300]}
    seconds, heavy = ast.literal_eval(proc.stdout.strip().splitlines()[-1])
    return {'heavy': heavy, 'seconds': round(seconds, 3)}


def inner_imports(paths) -> int:
    """How many import statements sit inside functions of these files."""
    count = 0
    for path in paths:
        tree = ast.parse(Path(path).read_text())
        lines = {node.lineno for fn in ast.walk(tree) if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
                 for node in ast.walk(fn) if isinstance(node, (ast.Import, ast.ImportFrom))}
        count += len(lines)
    return count


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--modules', nargs='+', metavar='NAME', help='only these modules (default: all of src/)')
    args = parser.parse_args(argv)
    known = source_modules(with_main=False)
    chosen = args.modules or list(known)
    unknown = [m for m in chosen if m not in known]
    if unknown:
        print(f'not a module of src/: {", ".join(unknown)}', file=sys.stderr)
        return 2
    rows = {}
    for k, module in enumerate(chosen, 1):
        rows[module] = weigh(module)
        if sys.stderr.isatty():
            print(f'\r{k}/{len(chosen)} {module:<60}', end='', file=sys.stderr, flush=True)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    loads = {h: sorted(m for m, r in rows.items() if h in r.get('heavy', ())) for h in HEAVY}
    print(json.dumps({'benchmark': 'import_weight', 'heavy_packages': list(HEAVY), 'modules': rows,
                      'modules_loading': {h: len(ms) for h, ms in loads.items()},
                      'light_modules': sorted(m for m, r in rows.items() if r.get('heavy') == []),
                      'errors': sorted(m for m, r in rows.items() if 'error' in r),
                      'imports_inside_functions': inner_imports(known[m] for m in chosen)}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
