"""What machine a benchmark ran on (its figures, bit patterns included, depend on it)."""

from __future__ import annotations

import os
import platform
import statistics
import time
from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo), else what platform says."""
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    return {'cpu': cpu_model(), 'cpus': os.cpu_count()}


def speed_probe(repeats: int = 5, threads: int = 2) -> float:
    """Seconds for a fixed piece of CPU work: a 3 x 3 convolution of 32 channels over 160 frames of 64 x 64
    (an 84 MB map in and out, as the performer's frozen network moves: a small one that stays in the core's
    cache misses what slows training most, the memory the machine's neighbours share), channels-last, fp32,
    in `threads` torch threads (at most the cores), the median of `repeats` after one warm-up. The same
    machine gives it up to 2x apart in different hours (docs/figures.md), so a stage's time is read beside
    it (the stamps of `reproduce` keep it from each run's start and end)."""
    import torch     # inline: the rest of this module is for callers without torch
    generator = torch.Generator().manual_seed(0)
    conv = torch.nn.Conv2d(32, 32, 3, padding=1).to(memory_format=torch.channels_last)
    frames = torch.rand(160, 32, 64, 64, generator=generator).contiguous(memory_format=torch.channels_last)
    before = torch.get_num_threads()
    torch.set_num_threads(max(1, min(threads, os.cpu_count() or 1)))
    times = []
    try:
        with torch.no_grad():
            conv(frames)
            for _ in range(repeats):
                t0 = time.perf_counter()
                conv(frames)
                times.append(time.perf_counter() - t0)
    finally:
        torch.set_num_threads(before)
    return round(statistics.median(times), 5)
