#!/usr/bin/env python3
"""`/sim/step` round trip through ROS between two processes vs the same step in-process.

Starts the real `dialfred_sim node` executable (as `ros2 run` would) and plays a fixed action
sequence through `/sim/step` from this process, timing each step paired with the same step on an
in-process DialfredEnv. Done twice: replies with the full observation, and replies with RGB only
(`with_depth=false, with_segmentation=false`). Also reads the node's peak resident memory (VmHWM).

A third, reference run measures the floor of ROS itself in the same pattern: a bare `std_srvs/Trigger`
service in another process whose callback performs the same step on its own DialfredEnv and replies
with nothing. What it adds over the in-process step is the cost of any ROS service round trip here
(wake-ups, executors, DDS, caches left cold by the render); the rest of `/sim/step`'s overhead is the
observation message itself. Prints JSON.

    ./dialfred bench ros_step [--resolution 300] [--steps 300] [--cpu-dma-latency 0]

`--cpu-dma-latency US` holds a Linux PM QoS request (/dev/cpu_dma_latency, root only) for the whole
run, as real-time tuning guides do: with 0, idle CPUs poll instead of halting, so waking a process
that waits for a reply costs less (on a VM, a halted vCPU is woken through the hypervisor).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import struct
import sys
import time
from pathlib import Path

import rclpy
from std_srvs.srv import Trigger

from dialfred_bringup.graph import Graph, NodeProcess, sim_node, use_private_ros_domain
from dialfred_msgs.msg import Action
from dialfred_msgs.srv import SimReset, SimStep
from dialfred_sim.env import DialfredEnv
from dialfred_sim.ros_util import make_executor, spin_forever

PATTERN = ['MoveAhead', 'RotateLeft', 'LookDown', 'MoveAhead', 'RotateRight', 'LookUp', 'RotateRight',
           'MoveAhead', 'RotateLeft', 'RotateLeft', 'Pickup']


def peak_rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmHWM:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def paired_times(resolution: int, steps: int, scene: str, seed: int, full: bool):
    """Each action goes once through /sim/step and once through an in-process env in the same state.

    Both simulators start from the same seed and get the same actions, so by determinism they stay
    in identical states; pairing the two timings per step lets machine noise hit both alike.
    """
    env = DialfredEnv(resolution=resolution)
    node = sim_node(resolution)
    ros, local = [], []
    with Graph([node]) as graph:
        reset_cli = graph.client(SimReset, '/sim/reset')
        step_cli = graph.client(SimStep, '/sim/step')

        def reset(s):
            reply = graph.call(reset_cli, SimReset.Request(scene=scene, seed=s))
            if not reply.ok:
                raise RuntimeError(reply.error)
            env.reset(seed=s, options={'scene': scene})

        reset(seed)
        c = resolution // 2
        for k in range(steps):
            name = PATTERN[k % len(PATTERN)]
            t0 = time.perf_counter()
            req = SimStep.Request(action=Action(action=name, x=c, y=c), with_depth=full, with_segmentation=full)
            reply = graph.call(step_cli, req)
            t1 = time.perf_counter()
            env.step({'action': name, 'pixel': (c, c)})
            t2 = time.perf_counter()
            if not reply.ok:
                raise RuntimeError(reply.error)
            ros.append(t1 - t0)
            local.append(t2 - t1)
            if reply.terminated or reply.truncated:
                reset(seed + k + 1)
        rss = peak_rss_mb(node.proc.pid)
    env.close()
    return ros, local, rss


def play_pattern(env, k: int) -> bool:
    """Action k of PATTERN on `env` (interactions at the frame's centre); whether the episode ended."""
    c = env.resolution // 2
    _, _, terminated, truncated, _ = env.step({'action': PATTERN[k % len(PATTERN)], 'pixel': (c, c)})
    return terminated or truncated


class FloorServer(NodeProcess):
    """This script re-run as a bare Trigger service that steps its own env (see --serve-floor)."""

    def command(self) -> list[str]:
        return [sys.executable, str(Path(__file__).resolve()), '--serve-floor',
                f'{self.parameters["resolution"]},{self.parameters["scene"]},{self.parameters["seed"]}']


def serve_floor(spec: str) -> None:
    """Serve `floor/step` (std_srvs/Trigger): each call performs the next action of PATTERN."""
    resolution, scene, seed = spec.split(',')
    env = DialfredEnv(resolution=int(resolution))
    env.reset(seed=int(seed), options={'scene': scene})
    state = {'k': 0}

    def on_step(request, response):
        k = state['k']
        state['k'] += 1
        if play_pattern(env, k):
            env.reset(seed=int(seed) + k + 1, options={'scene': scene})
        response.success = True
        return response

    rclpy.init()
    node = rclpy.create_node('ros_floor')
    node.create_service(Trigger, 'floor/step', on_step)
    executor = make_executor()
    executor.add_node(node)
    try:
        spin_forever(executor)
    except KeyboardInterrupt:
        pass


def floor_times(resolution: int, steps: int, scene: str, seed: int):
    """Like paired_times, against the bare Trigger service: the same steps, an empty reply."""
    env = DialfredEnv(resolution=resolution)
    env.reset(seed=seed, options={'scene': scene})
    server = FloorServer('dialfred_sim', parameters={'resolution': resolution, 'scene': scene, 'seed': seed})
    ros, local = [], []
    with Graph([server]) as graph:
        cli = graph.client(Trigger, '/floor/step')
        for k in range(steps):
            t0 = time.perf_counter()
            graph.call(cli, Trigger.Request())
            t1 = time.perf_counter()
            ended = play_pattern(env, k)
            t2 = time.perf_counter()
            if ended:
                env.reset(seed=seed + k + 1, options={'scene': scene})
            ros.append(t1 - t0)
            local.append(t2 - t1)
    env.close()
    return ros, local


def hold_cpu_dma_latency(us: int) -> int:
    """Ask the kernel to keep CPU wake-up latency at most `us` microseconds while the returned file
    descriptor stays open (PermissionError unless root)."""
    fd = os.open('/dev/cpu_dma_latency', os.O_WRONLY)
    os.write(fd, struct.pack('i', us))
    return fd


def summary(times):
    ms = sorted(t * 1e3 for t in times)
    return {'median_ms': round(statistics.median(ms), 3), 'mean_ms': round(statistics.fmean(ms), 3),
            'p90_ms': round(ms[int(0.9 * (len(ms) - 1))], 3)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--resolution', type=int, default=300)
    ap.add_argument('--steps', type=int, default=300)
    ap.add_argument('--scene', default='FloorPlan1')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--cpu-dma-latency', type=int, metavar='US',
                    help='hold a PM QoS CPU wake-up latency request of US microseconds during the run')
    ap.add_argument('--serve-floor', help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.serve_floor:
        serve_floor(args.serve_floor)
        return
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    use_private_ros_domain()
    report = {'benchmark': 'ros_step', 'resolution': args.resolution, 'steps': args.steps, 'scene': args.scene,
              'cpu_dma_latency_us': args.cpu_dma_latency}
    if args.cpu_dma_latency is not None:
        try:
            hold_cpu_dma_latency(args.cpu_dma_latency)   # released when this process exits
        except OSError as e:
            ap.error(f'--cpu-dma-latency needs write access to /dev/cpu_dma_latency: {e}')
    # The full observation (RGB + float32 depth + int32 segmentation) and the agent's view (RGB only:
    # what ALFRED/DialFRED agents observe; depth and segmentation are privileged, opt-in channels).
    for label, full in (('rgb_depth_segmentation', True), ('rgb_only', False), ('floor_empty_trigger', None)):
        if full is None:
            ros, local = floor_times(args.resolution, args.steps, args.scene, args.seed)
            rss = float('nan')
        else:
            ros, local, rss = paired_times(args.resolution, args.steps, args.scene, args.seed, full)
        r, lo = summary(ros), summary(local)
        report[label] = {
            'ros_round_trip': r, 'in_process': lo,
            'added_by_ros_median_ms': round(r['median_ms'] - lo['median_ms'], 3),
            'added_by_ros_mean_ms': round(r['mean_ms'] - lo['mean_ms'], 3),
            # The median of the per-step differences: what the pairing is for (view-dependent
            # render time cancels out step by step).
            'added_by_ros_paired_median_ms': round(statistics.median(
                (a - b) * 1e3 for a, b in zip(ros, local)), 3),
        }
        if full is not None:
            report[label]['sim_node_peak_rss_mb'] = round(rss, 1)
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
