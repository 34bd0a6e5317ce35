"""The import graph has no circle: no module of src/ imports, at module
level or inside a function, a module that imports it back (directly or through others). A circle such
as dialfred_sim.env <-> dialfred_sim.tasks.splits works only in the order its modules happen to be
imported; each module must import on its own, in a fresh interpreter. Imports sit at module level,
where a reader sees who depends on whom; one inside a function says why in a comment (a heavy package
the rest of its module does without, an optional feature), in src/ and in scripts/ and benchmarks/ too.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from dialfred_bringup.paths import REPO, source_modules


def ancestors(name: str) -> list[str]:
    parts = name.split('.')
    return ['.'.join(parts[:k]) for k in range(1, len(parts))]


def imports_of(name: str, path: Path, known: set, module_level_only: bool) -> set:
    """The project modules `name` imports (with the packages that importing them loads first)."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    nodes = tree.body if module_level_only else list(ast.walk(tree))
    if module_level_only:      # module level includes if/try blocks, not function or class bodies
        nodes = [n for top in tree.body if not isinstance(top, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                 for n in ast.walk(top)]
    targets = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            targets |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')[:len(package.split('.')) - (node.level - 1)]
                base = '.'.join(anchor + ([base] if base else []))
            targets.add(base)
            targets |= {f'{base}.{alias.name}' for alias in node.names}    # `from pkg import submodule`
    found = set()
    for target in targets:
        for t in [*ancestors(target), target]:
            if t in known and t != name and t not in ancestors(name):
                found.add(t)
    return found


def find_cycle(graph: dict) -> list:
    """One cycle of `graph` ({node: set of nodes}) as a list of nodes, or [] if it has none."""
    state, stack = {}, []

    def visit(n):
        state[n] = 'open'
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 'open':
                return stack[stack.index(m):] + [m]
            if m not in state:
                cycle = visit(m)
                if cycle:
                    return cycle
        stack.pop()
        state[n] = 'done'
        return []

    for n in sorted(graph):
        if n not in state:
            cycle = visit(n)
            if cycle:
                return cycle
    return []


@pytest.mark.parametrize('module_level_only', [True, False], ids=['module-level imports', 'all imports'])
def test_no_module_imports_a_module_that_imports_it_back(module_level_only):
    modules = source_modules()
    graph = {name: imports_of(name, path, set(modules), module_level_only) for name, path in modules.items()}
    if not module_level_only:      # env looks tasks up inside functions: the walk must see it
        assert 'dialfred_sim.tasks' in graph['dialfred_sim.env']
    cycle = find_cycle(graph)
    assert not cycle, ' -> '.join(cycle)


def test_the_walk_finds_a_circle_through_a_function_level_import(tmp_path):
    pkg = tmp_path / 'pkg'
    pkg.mkdir()
    (pkg / '__init__.py').write_text('')
    (pkg / 'a.py').write_text('from . import b\n')
    (pkg / 'b.py').write_text('def f():\n    from .a import x\n')
    modules = {'pkg': pkg / '__init__.py', 'pkg.a': pkg / 'a.py', 'pkg.b': pkg / 'b.py'}
    graph = {n: imports_of(n, p, set(modules), False) for n, p in modules.items()}
    assert find_cycle(graph) in (['pkg.a', 'pkg.b', 'pkg.a'], ['pkg.b', 'pkg.a', 'pkg.b'])
    module_level = {n: imports_of(n, p, set(modules), True) for n, p in modules.items()}
    assert find_cycle(module_level) == []


@pytest.mark.parametrize('module', ['dialfred_sim.tasks.splits', 'dialfred_sim.env', 'dialfred_sim.tasks.split_files',
                                    'dialfred_bringup.evaluation', 'dialfred_bringup.launch'])
def test_each_module_imports_first_in_a_fresh_interpreter(module):
    proc = subprocess.run([sys.executable, '-c', f'import {module}'], cwd=REPO, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]


def unexplained_inner_imports(path: Path) -> list[str]:
    """'file:line: statement' of each import inside a function of `path` with no comment on its line
    and none on a comment line heading the run of imports it is in."""
    lines = path.read_text().splitlines()
    found = []
    for fn in ast.walk(ast.parse('\n'.join(lines), str(path))):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if not isinstance(node, (ast.Import, ast.ImportFrom)) or '#' in lines[node.lineno - 1]:
                continue
            k = node.lineno - 2
            while k >= 0 and re.match(r'\s*(import|from) ', lines[k]) and '#' not in lines[k]:
                k -= 1
            if not (k >= 0 and lines[k].strip().startswith('#')):
                found.append(f'{path.relative_to(REPO)}:{node.lineno}: {lines[node.lineno - 1].strip()}')
    return sorted(set(found))


@pytest.mark.parametrize('where', ['src', 'scripts', 'benchmarks'])
def test_an_import_inside_a_function_says_why_it_is_there(where):
    paths = source_modules().values() if where == 'src' else sorted((REPO / where).rglob('*.py'))
    unexplained = [line for path in paths for line in unexplained_inner_imports(path)]
    assert not unexplained, 'move these to module level, or say why not in a comment:\n' + '\n'.join(unexplained)


def test_the_rule_finds_an_unexplained_inner_import_and_accepts_explained_ones(tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules[__name__], 'REPO', tmp_path)
    (tmp_path / 'm.py').write_text(
        'def a():\n    import json\n'
        'def b():\n    import torch  # lazy: torch\n    import json\n'
        'def c():\n    # lazy: the ROS messages\n    from x import y\n    from x import z\n')
    assert unexplained_inner_imports(tmp_path / 'm.py') == ['m.py:2: import json', 'm.py:5: import json']


# The simulator's seam (docs/simulator.md, "Another simulator"): agents and the oracle know the robot's body from
# protocol.BODY and the world from Snapshots and observations, never from the pybullet world's own modules.
AGENT_PACKAGES = ('dialfred_oracle', 'dialfred_performer', 'dialfred_questioner')
SIMULATOR_INTERNALS = ('dialfred_sim.world', 'dialfred_sim.actions', 'pybullet', 'pybullet_utils')


def internals_imported(name: str, path: Path) -> list[str]:
    """'module:line: target' of each import (module level or inside a function) of `path` that reaches into
    SIMULATOR_INTERNALS."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')[:len(package.split('.')) - (node.level - 1)]
                base = '.'.join(anchor + ([base] if base else []))
            targets = [base, *(f'{base}.{alias.name}' for alias in node.names)]
        else:
            continue
        bad = [t for t in targets if any(t == b or t.startswith(b + '.') for b in SIMULATOR_INTERNALS)]
        found += [f'{name}:{node.lineno}: {bad[0]}'] if bad else []
    return found


def test_agents_and_the_oracle_import_nothing_of_the_pybullet_world():
    modules = {n: p for n, p in source_modules().items() if n.split('.')[0] in AGENT_PACKAGES}
    assert len(modules) > 50
    found = [line for n, p in sorted(modules.items()) for line in internals_imported(n, p)]
    assert not found, 'read the body from dialfred_sim.protocol.BODY and the world from a Snapshot:\n' + '\n'.join(found)


def test_the_seam_rule_finds_a_reach_into_the_world(tmp_path):
    (tmp_path / 'm.py').write_text('from dialfred_sim.world.camera import ray_lengths\n'
                                   'def f():\n    import pybullet  # lazy\n    from dialfred_sim import actions\n'
                                   'from dialfred_sim.protocol import BODY\n')
    assert internals_imported('dialfred_performer.m', tmp_path / 'm.py') == [
        'dialfred_performer.m:1: dialfred_sim.world.camera', 'dialfred_performer.m:3: pybullet',
        'dialfred_performer.m:4: dialfred_sim.actions']
