#!/usr/bin/env python3
"""`/oracle/answer` from another process: answers per second and p50/p99 latency, without and with
the oracle's ground-truth cache, in one run.

For each path the simulator and oracle nodes start as separate processes, the simulator is reset to
a valid_unseen task, and this process asks:
- `location_direction`: location and direction questions in turn about the task's objects;
- `appearance`: appearance questions about them;
each `--requests` times one at a time (latency; requests/s = 1 / mean) and then with `--in-flight`
requests outstanding (throughput, and each request's time from sending to its reply). Then
`--after-steps` times: one /sim/step (turning left and right in turn) and one location question,
the question timed: the first question in a new state, which fetches the whole world on both paths.
One at a time, the CPU time each process (sim, oracle, this client) spent per request is measured
too: on a loaded machine, latency is mostly waiting for a core.

Paths: `fetch_every_question` (node parameter cache_ground_truth:=false: the whole world is fetched
for every question, and again for an appearance's pixels, as before) and `cached` (the default: the
oracle keeps the last state and asks the simulator only whether it is still current). Prints JSON,
with the machine's load average before and after (the figures depend on what else runs).

    ./dialfred bench oracle_latency [--requests 2000] [--in-flight 8] [--after-steps 200]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

from dialfred_bringup.graph import Graph, oracle_node, sim_node, use_private_ros_domain
from dialfred_msgs.msg import Action
from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
from dialfred_sim.tasks import get_task

PATHS = {'fetch_every_question': False, 'cached': True}
GOAL = {'location_direction_requests_per_s': 1000.0, 'location_direction_p99_ms': 5.0}


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * (len(ordered) - 1) + 0.5))]


def summary(ms: list[float]) -> dict:
    return {'p50_ms': round(percentile(ms, 0.5), 3), 'p99_ms': round(percentile(ms, 0.99), 3),
            'mean_ms': round(statistics.fmean(ms), 3)}


def call(graph, cli, request):
    """One request, waiting for its reply (a lean loop: this process's overhead is part of the figure)."""
    future = cli.call_async(request)
    while not future.done():
        graph.executor.spin_once(timeout_sec=0.1)
    return future.result()


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process `pid` so far (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def one_at_a_time(graph, cli, requests) -> tuple[dict, int]:
    """Latency one request at a time, and the CPU time each process spent per request."""
    ms, invalid = [], 0
    pids = {n.package.removeprefix('dialfred_'): n.proc.pid for n in graph.nodes}
    cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()} | {'client': time.process_time()}
    for request in requests:
        t = time.perf_counter()
        reply = call(graph, cli, request)
        ms.append((time.perf_counter() - t) * 1e3)
        invalid += not reply.valid
    cpu1 = {name: cpu_seconds(pid) for name, pid in pids.items()} | {'client': time.process_time()}
    out = summary(ms)
    out['requests_per_s'] = round(1e3 / out['mean_ms'], 1)
    out['cpu_ms_per_request'] = {name: round((cpu1[name] - cpu0[name]) / len(requests) * 1e3, 3) for name in cpu0}
    return out, invalid


def pipelined(graph, cli, requests, in_flight: int) -> tuple[dict, int]:
    """All `requests` with `in_flight` outstanding; each one's time from sending to its reply."""
    sent_at, done_at, futures = {}, {}, {}
    pending, k = set(), 0
    t0 = time.perf_counter()
    while len(done_at) < len(requests):
        while k < len(requests) and len(pending) < in_flight:
            sent_at[k] = time.perf_counter()
            futures[k] = cli.call_async(requests[k])
            pending.add(k)
            k += 1
        graph.executor.spin_once(timeout_sec=0.1)
        now = time.perf_counter()
        for j in [j for j in pending if futures[j].done()]:
            done_at[j] = now
            pending.discard(j)
    wall = time.perf_counter() - t0
    out = summary([(done_at[j] - sent_at[j]) * 1e3 for j in range(len(requests))])
    out.update(in_flight=in_flight, requests_per_s=round(len(requests) / wall, 1))
    return out, sum(not futures[j].result().valid for j in range(len(requests)))


def run_path(cache: bool, args, nouns) -> dict:
    def question(qtype, noun=''):
        return OracleAnswer.Request(question_type=qtype, object_noun=noun)
    groups = {
        'location_direction': [question('location', nouns[(k // 2) % len(nouns)]) if k % 2 == 0
                               else question('direction') for k in range(args.requests)],
        'appearance': [question('appearance', nouns[k % len(nouns)]) for k in range(args.requests)],
    }
    out = {'cache_ground_truth': cache}
    with Graph([sim_node(128), oracle_node(cache_ground_truth=cache)]) as graph:
        reset, step = graph.client(SimReset, '/sim/reset'), graph.client(SimStep, '/sim/step')
        assert call(graph, reset, SimReset.Request(task_id=args.task, with_depth=False, with_segmentation=False)).ok
        cli = graph.client(OracleAnswer, '/oracle/answer')
        for request in groups['location_direction'][:50] + groups['appearance'][:20]:     # warm-up
            call(graph, cli, request)
        for name, requests in groups.items():
            seq, invalid_seq = one_at_a_time(graph, cli, requests)
            pipe, invalid_pipe = pipelined(graph, cli, requests, args.in_flight)
            out[name] = {'one_at_a_time': seq, 'pipelined': pipe, 'invalid_replies': invalid_seq + invalid_pipe}
        ms = []
        for k in range(args.after_steps):
            turn = Action(action='RotateLeft' if k % 2 == 0 else 'RotateRight')
            assert call(graph, step, SimStep.Request(action=turn, with_depth=False, with_segmentation=False)).ok
            t = time.perf_counter()
            assert call(graph, cli, question('location', nouns[k % len(nouns)])).valid
            ms.append((time.perf_counter() - t) * 1e3)
        out['location_after_a_step'] = summary(ms) if ms else {}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--requests', type=int, default=2000, help='per question group, per mode, per path')
    ap.add_argument('--in-flight', type=int, default=8)
    ap.add_argument('--after-steps', type=int, default=200)
    ap.add_argument('--task', default='valid_unseen/000003')
    args = ap.parse_args()
    if args.requests < 1 or args.in_flight < 1 or args.after_steps < 0:
        ap.error('--requests and --in-flight must be >= 1, --after-steps >= 0')
    use_private_ros_domain()
    nouns = list(get_task(args.task).object_nouns)
    report = {'benchmark': 'oracle_latency', 'task': args.task, 'nouns': nouns, 'requests': args.requests,
              'in_flight': args.in_flight, 'after_steps': args.after_steps,
              'load_average_before': [round(v, 2) for v in os.getloadavg()], 'paths': {}}
    for name, cache in PATHS.items():
        report['paths'][name] = run_path(cache, args, nouns)
    report['load_average_after'] = [round(v, 2) for v in os.getloadavg()]
    cached = report['paths']['cached']['location_direction']
    best_rate = max(cached['one_at_a_time']['requests_per_s'], cached['pipelined']['requests_per_s'])
    report['goal'] = {**GOAL, 'cached_requests_per_s': best_rate, 'cached_p99_ms': cached['one_at_a_time']['p99_ms'],
                      'met': best_rate >= GOAL['location_direction_requests_per_s']
                      and cached['one_at_a_time']['p99_ms'] <= GOAL['location_direction_p99_ms']}
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
