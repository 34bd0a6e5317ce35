"""Size bounds on the source: no class in src/ over 300 lines and no function over 80 (a body that long
holds several steps that want names of their own). An exception stands in EXCEPTIONS with its reason."""

from __future__ import annotations

import ast
import sys

from dialfred_bringup.paths import REPO, source_modules

MAX_CLASS, MAX_FUNCTION = 300, 80
EXCEPTIONS: dict[str, str] = {}      # 'package/module.py:Name' -> why it is longer


def oversized(path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ClassDef):
            limit = MAX_CLASS
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            limit = MAX_FUNCTION
        else:
            continue
        lines = node.end_lineno - node.lineno + 1
        name = f'{path.relative_to(REPO / "src")}:{node.name}'
        if lines > limit and name not in EXCEPTIONS:
            found.append(f'{name} (line {node.lineno}): {lines} lines, the bound is {limit}')
    return found


def test_no_class_or_function_in_src_is_over_its_bound():
    modules = source_modules().values()
    assert len(modules) > 100
    over = [line for path in modules for line in oversized(path)]
    assert not over, 'split these, or list them in EXCEPTIONS with the reason:\n' + '\n'.join(over)


def test_the_bound_finds_a_long_function(tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules[__name__], 'REPO', tmp_path)
    (tmp_path / 'src').mkdir()
    module = tmp_path / 'src' / 'm.py'
    module.write_text('def long():\n' + '    x = 1\n' * 80 + '\ndef short():\n    return 1\n')
    assert oversized(module) == ['m.py:long (line 1): 81 lines, the bound is 80']
