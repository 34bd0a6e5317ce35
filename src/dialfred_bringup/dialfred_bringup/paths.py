"""Where the repository is: run outputs (out/), docs/ and config/ are found from here.

The package is installed with colcon's --symlink-install, so this file resolves into the source tree
(src/dialfred_bringup/dialfred_bringup/paths.py); a copy installed elsewhere falls back to the current
directory, which `./dialfred` sets to the repository root for the commands that write there.
"""

from __future__ import annotations

from pathlib import Path


def _repo_root() -> Path:
    here = Path(__file__).resolve()
    if len(here.parents) > 3 and (here.parents[3] / 'dialfred').is_file():
        return here.parents[3]
    return Path.cwd()


REPO = _repo_root()


def source_modules(with_main: bool = True) -> dict[str, Path]:
    """{dotted name: file} of every module of the project's packages (src/<dist>/<package>/...); without
    `with_main`, not the `__main__` ones (importing those runs them)."""
    modules = {}
    for init in sorted(REPO.glob('src/*/*/__init__.py')):
        root = init.parent
        for path in sorted(root.rglob('*.py')):
            if path.name == '__main__.py' and not with_main:
                continue
            parts = path.relative_to(root.parent).with_suffix('').parts
            modules['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    return modules
