"""The perception network in PyTorch's two memory layouts, contiguous (NCHW) and channels-last (NHWC):
seconds per training step (forward, loss, backward, AdamW step on a batch of frames), one forward pass
of a batch without gradient (as the performer's frozen network runs in training), and one frame on one
thread (as an agent's step runs it); with the largest difference of the two layouts' outputs on the same
frames and weights (the same numbers up to rounding, not bit for bit). Prints JSON.

    ./dialfred bench perception_layout [--rounds 3] [--steps 15] [--skip 3] [--batch 64] [--forward-batch 176] [--threads 2]

The layouts take turns, `--rounds` times (the first of each round in alternating order): each figure is
the median of a layout's rounds, so that neither pays alone for the allocator's warm-up or a busy moment.

The network is `./dialfred reproduce`'s (reproduce/plan.py's PERCEPTION sizes). The frames and labels are
synthetic (uniform random pixels, classes and depths, seeded): a step's time does not depend on them.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np
import torch

from dialfred_bringup.reproduce.plan import PERCEPTION
from dialfred_performer.perception import Perception, PerceptionNetConfig, perception_loss
from dialfred_sim.tasks.demonstrations import label_classes

LAYOUTS = {'nchw': torch.contiguous_format, 'nhwc': torch.channels_last}


def synthetic_batch(rng: np.random.Generator, n: int, size: int, classes: int):
    """(frames [n, 3, R, R] in [0, 1], classes [n, R, R] int, depth [n, R, R] metres): synthetic."""
    frames = torch.from_numpy(rng.random((n, 3, size, size), dtype=np.float32))
    labels = torch.from_numpy(rng.integers(0, classes, (n, size, size)).astype(np.int16))
    depth = torch.from_numpy(rng.uniform(0.3, 6.0, (n, size, size)).astype(np.float32))
    return frames, labels, depth


def best_of(fn, repeats: int) -> float:
    best = float('inf')
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(layout: str, args, sizes: dict) -> tuple[dict, torch.nn.Module]:
    fmt = LAYOUTS[layout]
    torch.manual_seed(0)
    net = Perception(PerceptionNetConfig(**sizes)).to(memory_format=fmt)
    opt = torch.optim.AdamW(net.parameters(), 1e-3)
    rng = np.random.default_rng(0)
    times = []
    for k in range(args.skip + args.steps):
        frames, classes, depth = synthetic_batch(rng, args.batch, sizes['resolution'], sizes['classes'])
        t0 = time.perf_counter()
        out = net(frames.contiguous(memory_format=fmt))
        loss, _ = perception_loss(net, out, frames, classes, depth, 4.0, 0.5)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        if k >= args.skip:
            times.append(time.perf_counter() - t0)
    net.eval()
    frames = synthetic_batch(np.random.default_rng(1), args.forward_batch, sizes['resolution'], 2)[0]
    one = frames[:1].contiguous(memory_format=fmt)
    frames = frames.contiguous(memory_format=fmt)
    with torch.no_grad():
        forward = best_of(lambda: net(frames), 5)
        torch.set_num_threads(1)
        single = best_of(lambda: net(one), 30)
        torch.set_num_threads(args.threads)
    return {'train_step_s': round(statistics.median(times), 4), f'forward_{args.forward_batch}_s': round(forward, 4),
            'forward_1_frame_1_thread_ms': round(single * 1000, 2)}, net


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--steps', type=int, default=15, help='training steps timed')
    ap.add_argument('--skip', type=int, default=3, help='training steps first run and not counted')
    ap.add_argument('--batch', type=int, default=64, help='frames per training step (the perception stage\'s)')
    ap.add_argument('--forward-batch', type=int, default=176, help='frames of the batched forward pass '
                    '(a performer batch of 16 episodes holds about 176)')
    ap.add_argument('--threads', type=int, default=2)
    ap.add_argument('--rounds', type=int, default=3, help='turns of each layout (medians reported)')
    args = ap.parse_args()
    for name in ('steps', 'batch', 'forward_batch', 'threads', 'rounds'):
        if getattr(args, name) < 1:
            ap.error(f'--{name.replace("_", "-")} must be at least 1')
    if args.skip < 0:
        ap.error('--skip must be 0 or more')
    torch.set_num_threads(args.threads)
    sizes = dict(resolution=64, classes=len(label_classes()),
                 **{k: PERCEPTION[k] for k in ('c1', 'c2', 'c3', 'decoder')})
    rounds, nets = {layout: [] for layout in LAYOUTS}, {}
    for r in range(args.rounds):
        for layout in (list(LAYOUTS) if r % 2 == 0 else list(LAYOUTS)[::-1]):
            row, nets[layout] = measure(layout, args, sizes)
            rounds[layout].append(row)
    report = {layout: {k: round(statistics.median(row[k] for row in rows), 4) for k in rows[0]}
              for layout, rows in rounds.items()}
    # The two layouts' outputs on the same weights and frames (the contiguous network's weights in both).
    nets['nhwc'].load_state_dict(nets['nchw'].state_dict())
    frames = synthetic_batch(np.random.default_rng(2), 8, sizes['resolution'], 2)[0]
    with torch.no_grad():
        a = nets['nchw'](frames)
        b = nets['nhwc'](frames.contiguous(memory_format=torch.channels_last))
    diff = max(float((x - y).abs().max()) for x, y in zip(a, b))
    key = f'forward_{args.forward_batch}_s'
    print(json.dumps({
        'network': sizes, 'threads': args.threads, 'batch': args.batch, 'rounds': args.rounds, 'data': 'synthetic',
        **report,
        'speedup': {k: round(report['nchw'][k] / report['nhwc'][k], 3)
                    for k in ('train_step_s', key, 'forward_1_frame_1_thread_ms')},
        'max_abs_output_difference': diff,
    }))


if __name__ == '__main__':
    main()
