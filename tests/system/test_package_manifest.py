"""Each package says what it needs, and the packages depend on each other in one direction.

- every ROS package a module of src/<pkg>/ imports (another dialfred package, rclpy, a message package)
  is an <exec_depend> of src/<pkg>/package.xml, and every declared dialfred package is imported;
- every other third-party module it imports is pinned in requirements.txt (the project installs its
  Python dependencies with pip, not rosdep);
- the dialfred packages' dependencies have no circle: msgs <- sim <- oracle <- performer <- questioner
  <- bringup (the questioner may use the performer, never the reverse);
- no Python file outside src/ reaches a module by editing sys.path, and the repository root holds no
  Python script: everything `./dialfred` runs is an installed module.
"""

from __future__ import annotations

import ast
import importlib.metadata
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PYTHON_PACKAGES = sorted(p.name for p in (REPO / 'src').iterdir() if (p / 'setup.py').is_file())
# Modules that come from the ROS 2 wheels: declared in package.xml, not in requirements.txt.
ROS_MODULES = {'rclpy', 'rcl_interfaces', 'ament_index_python', 'action_msgs', 'builtin_interfaces', 'sensor_msgs',
               'std_msgs', 'geometry_msgs', 'unique_identifier_msgs', 'dialfred_msgs'}


def imported_top_modules(package: str) -> set[str]:
    """Top-level names of every module the package's Python files import (module level or not)."""
    found = set()
    for path in (REPO / 'src' / package / package).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found |= {a.name.split('.')[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split('.')[0])
    return found - set(sys.stdlib_module_names) - {package, '__future__'}


def declared(package: str) -> set[str]:
    root = ET.parse(REPO / 'src' / package / 'package.xml').getroot()
    return {e.text.strip() for e in root if e.tag in ('depend', 'exec_depend', 'build_depend') and e.text}


def pinned_distributions() -> set[str]:
    names = set()
    for line in (REPO / 'requirements.txt').read_text().splitlines():
        m = re.match(r'([A-Za-z0-9_.\-]+)(\[[^\]]*\])?==', line.strip())
        if m:
            names.add(m.group(1).lower().replace('_', '-'))
    return names


@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_package_xml_declares_every_ros_package_it_imports_and_no_other(package):
    imports = imported_top_modules(package)
    ros = {m for m in imports if m in ROS_MODULES or m.startswith('dialfred_')}
    assert ros <= declared(package), f'{package} imports {sorted(ros - declared(package))} without declaring them'
    unused = {d for d in declared(package) if d.startswith('dialfred_')} - ros
    assert not unused, f'{package}/package.xml declares {sorted(unused)}, which it never imports'


@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_every_third_party_module_a_package_imports_is_pinned(package):
    distributions = importlib.metadata.packages_distributions()
    pinned = pinned_distributions()
    for module in sorted(imported_top_modules(package)):
        if module in ROS_MODULES or module.startswith('dialfred_'):
            continue
        dists = {d.lower().replace('_', '-') for d in distributions.get(module, [])}
        assert dists & pinned, f'{package} imports {module!r} (from {sorted(dists) or "nowhere"}), not in requirements.txt'


def test_the_dialfred_packages_depend_on_each_other_without_a_circle():
    graph = {p: {d for d in declared(p) if d.startswith('dialfred_')} for p in PYTHON_PACKAGES}
    order = []

    def visit(p, path):
        assert p not in path, ' -> '.join([*path, p])
        if p in order:
            return
        for d in sorted(graph.get(p, ())):
            visit(d, [*path, p])
        order.append(p)

    for p in PYTHON_PACKAGES:
        visit(p, [])
    assert 'dialfred_questioner' in graph['dialfred_bringup'] and 'dialfred_performer' in graph['dialfred_questioner']
    assert 'dialfred_questioner' not in graph['dialfred_performer']


def test_no_sys_path_edits_and_no_python_scripts_at_the_root():
    hits = subprocess.run(['git', 'grep', '-n', 'sys.path', '--', 'src', 'scripts', 'benchmarks', 'tests', 'examples'],
                          cwd=REPO, capture_output=True, text=True).stdout
    hits = '\n'.join(line for line in hits.splitlines() if not line.startswith('tests/system/test_package_manifest.py'))
    assert hits == '', hits
    assert sorted(p.name for p in REPO.glob('*.py')) == []
