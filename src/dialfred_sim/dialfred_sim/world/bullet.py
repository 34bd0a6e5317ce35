"""pybullet, imported in one place with its C-level banner ('pybullet build time: ...') kept off stdout,
so that every command's output (JSON on stdout above all) stays clean whichever module imports it first."""

from __future__ import annotations

import contextlib
import os
import sys


@contextlib.contextmanager
def quiet_stdout(streams: tuple[int, ...] = (1,)):
    """Silence C-level prints to the file descriptors `streams` for the block (stdout: pybullet's
    'argv[0]=' when a client connects)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(fd) for fd in streams]
    try:
        with open(os.devnull, 'wb') as null:
            for fd in streams:
                os.dup2(null.fileno(), fd)
        yield
    finally:
        for fd, keep in zip(streams, saved):
            os.dup2(keep, fd)
            os.close(keep)


with quiet_stdout((1, 2)):      # the banner goes to stderr
    import pybullet
    from pybullet_utils import bullet_client

__all__ = ['bullet_client', 'pybullet', 'quiet_stdout']
