"""Which arithmetic settings change the training numbers on this CPU, and what they cost. Prints JSON.

Training repeats bit for bit on one kind of CPU, not across kinds (docs/evaluation.md): torch's own
kernels, oneDNN's convolutions and MKL's products each pick code for the instructions the CPU has. This
benchmark trains the perception network of `./dialfred reproduce` (its sizes, 2 threads, AdamW) on
synthetic frames and labels (seeded random tensors, not the benchmark's data) for `--updates` updates,
once per arithmetic mode, each in a fresh process (the settings are read when torch loads), and prints
each mode's weights digest and median time per update:

- `native`: what the CPU has (the pipeline's arithmetic);
- `avx2`: torch's kernels, oneDNN and MKL held to AVX2 (`ATEN_CPU_CAPABILITY=avx2`,
  `ONEDNN_MAX_CPU_ISA=AVX2`, `MKL_CBWR=AVX2`);
- `portable`: torch's kernels without vector code, oneDNN off (convolutions through MKL) and MKL's
  compatible branch (`ATEN_CPU_CAPABILITY=default`, `MKL_CBWR=COMPATIBLE`).

The same mode on another machine gives the same digest exactly when that mode repeats across the two
CPUs, so the digests printed on two machines tell which modes would make training portable, and the
times what each would cost.

    ./dialfred bench cpu_arithmetic [--updates 12] [--modes native,avx2,portable]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

from dialfred_bringup.machine import cpu_model

MODES = {
    'native': {},
    'avx2': {'ATEN_CPU_CAPABILITY': 'avx2', 'ONEDNN_MAX_CPU_ISA': 'AVX2', 'MKL_CBWR': 'AVX2'},
    'portable': {'ATEN_CPU_CAPABILITY': 'default', 'MKL_CBWR': 'COMPATIBLE', 'DIALFRED_PROBE_NO_ONEDNN': '1'},
}
# The perception network of `./dialfred reproduce` (dialfred_bringup.reproduce.plan.PERCEPTION), 40 classes.
NET = dict(c1=32, c2=64, c3=128, decoder=48, classes=40)
BATCH, RESOLUTION = 32, 64


def train(updates: int, net_sizes: dict) -> dict:
    """In this process: train on seeded random tensors, return the weights digest and the times."""
    # lazy: the parent only spawns the children, each loading torch under its mode's ISA environment
    import torch
    from dialfred_performer.perception import Perception, PerceptionNetConfig, perception_loss
    torch.set_num_threads(2)
    if os.environ.get('DIALFRED_PROBE_NO_ONEDNN') == '1':
        torch.backends.mkldnn.enabled = False
    torch.manual_seed(0)
    net = Perception(PerceptionNetConfig(**net_sizes))
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3, weight_decay=1e-4)
    g = torch.Generator().manual_seed(1)
    times, loss = [], None
    for _ in range(updates):
        frames = torch.rand(BATCH, 3, RESOLUTION, RESOLUTION, generator=g)
        classes = torch.randint(0, net_sizes['classes'], (BATCH, RESOLUTION, RESOLUTION), generator=g,
                                dtype=torch.uint8)
        depth = torch.randint(0, 256, (BATCH, RESOLUTION, RESOLUTION), generator=g, dtype=torch.uint8)
        t0 = time.perf_counter()
        out = net(frames)
        loss, _ = perception_loss(net, out, frames, classes, depth, 4.0, 0.5)
        opt.zero_grad()
        loss.backward()
        opt.step()
        times.append(time.perf_counter() - t0)
    h = hashlib.sha256()
    for name, tensor in sorted(net.state_dict().items()):
        h.update(name.encode())
        h.update(tensor.detach().contiguous().numpy().tobytes())
    return {'weights_sha256': h.hexdigest(), 'final_loss': float(loss.detach()),
            'median_s_per_update': round(sorted(times)[len(times) // 2], 4),
            'torch_capability': torch.backends.cpu.get_cpu_capability()}


def run_mode(mode: str, updates: int, tiny: bool) -> dict:
    env = {**os.environ, **MODES[mode]}
    cmd = [sys.executable, __file__, '--child', '--updates', str(updates)] + (['--tiny'] if tiny else [])
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f'mode {mode}: the training process failed:\n{proc.stderr[-2000:]}')
    return {'env': MODES[mode], **json.loads(proc.stdout.strip().splitlines()[-1])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--updates', type=int, default=12)
    ap.add_argument('--modes', default=','.join(MODES), help=f'comma-separated, of {", ".join(MODES)}')
    ap.add_argument('--tiny', action='store_true', help='a tiny network (checks the benchmark, says nothing)')
    ap.add_argument('--child', action='store_true', help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.updates < 1:
        ap.error('--updates must be at least 1')
    sizes = dict(NET, c1=8, c2=8, c3=8, decoder=8) if args.tiny else NET
    if args.child:
        print(json.dumps(train(args.updates, sizes)))
        return
    modes = [m for m in args.modes.split(',') if m]
    unknown = [m for m in modes if m not in MODES]
    if unknown or not modes:
        ap.error(f'unknown mode(s) {unknown}: choose from {", ".join(MODES)}')
    results = {}
    for mode in modes:
        results[mode] = run_mode(mode, args.updates, args.tiny)
        print(f'[cpu_arithmetic] {mode}: {results[mode]["median_s_per_update"]} s/update', file=sys.stderr)
    base = results.get('native')
    print(json.dumps({
        'benchmark': 'cpu_arithmetic', 'cpu': cpu_model(), 'updates': args.updates, 'tiny': args.tiny,
        'data': 'synthetic (seeded random frames and labels)', 'modes': results,
        'same_weights_as_native': {m: r['weights_sha256'] == base['weights_sha256'] for m, r in results.items()}
        if base else {},
        'time_against_native': {m: round(r['median_s_per_update'] / base['median_s_per_update'], 2)
                                for m, r in results.items()} if base else {}}, indent=1))


if __name__ == '__main__':
    main()
