"""glibc malloc settings for batched torch on a small CPU machine, and the re-exec that applies them.

glibc reads these variables at process start only, so an entry point that needs them and was started
without them (not through `./dialfred env` or `./dialfred train-performer`, which set them) runs itself
again with them set.
"""

from __future__ import annotations

import os
import sys

# glibc malloc: big buffers stay on the heap and are never handed back; measured to cut batched CNN
# time by 25-60% on this project's 2-core machine. Read by glibc at process start only.
MALLOC_SETTINGS = {'MALLOC_MMAP_THRESHOLD_': '1000000000', 'MALLOC_TRIM_THRESHOLD_': '1000000000',
                   'MALLOC_TOP_PAD_': '1000000000'}
_REEXEC_MARK = 'DIALFRED_MALLOC_REEXEC'


def ensure_malloc_settings(module: str) -> None:
    """Re-execute this process (`python -m module ARGS`) with MALLOC_SETTINGS unless they are set
    already (`./dialfred env` and `./dialfred train-performer` set them)."""
    missing = {k: v for k, v in MALLOC_SETTINGS.items() if k not in os.environ}
    if not missing or os.environ.get(_REEXEC_MARK):
        return
    env = {**os.environ, **missing, _REEXEC_MARK: '1'}
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, '-m', module, *sys.argv[1:]], env)
