"""Progress bars on stderr: tqdm's own on a terminal; where stderr is a file or a pipe (a log, CI), one
plain line at most every LOG_INTERVAL_S seconds instead of carriage-return redraws that pile up into one
endless line."""

from __future__ import annotations

import sys

from tqdm import tqdm

LOG_INTERVAL_S = 30.0


class _Lines:
    """A stream for tqdm that writes each of its redraws as a line of its own."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace('\r', '').strip()
        if text:
            self.stream.write(text + '\n')

    def flush(self) -> None:
        self.stream.flush()


def progress_bar(iterable=None, **kwargs) -> tqdm:
    """tqdm on stderr with `kwargs` (total, initial, unit, desc, disable, ...), drawn for where stderr goes."""
    stream = sys.stderr
    if stream.isatty():
        kwargs.setdefault('dynamic_ncols', True)
        return tqdm(iterable, file=stream, **kwargs)
    kwargs.pop('dynamic_ncols', None)
    return tqdm(iterable, file=_Lines(stream), mininterval=LOG_INTERVAL_S, ncols=100, ascii=True, **kwargs)
