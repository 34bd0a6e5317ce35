#!/usr/bin/env python3
"""`/oracle/answer` from another process: sustained requests per second and p50/p99 latency.

Starts the simulator and oracle nodes as separate processes (the oracle fetches the ground truth
from the simulator over ROS for every question), resets the simulator to a valid_unseen task, and
sends `--requests` questions cycling through location, appearance and direction about the task's
objects, one at a time (latency) and then with `--in-flight` outstanding (throughput). Prints JSON.

    ./dialfred bench oracle_latency [--requests 10000] [--in-flight 8]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dialfred_launch import Graph, oracle_node, sim_node, use_private_ros_domain  # noqa: E402

TYPES = ('location', 'appearance', 'direction')


def percentile(sorted_ms, q):
    return sorted_ms[min(len(sorted_ms) - 1, int(q * (len(sorted_ms) - 1) + 0.5))]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--requests', type=int, default=10000)
    ap.add_argument('--in-flight', type=int, default=8)
    ap.add_argument('--task', default='valid_unseen/000003')
    args = ap.parse_args()
    use_private_ros_domain()
    from dialfred_msgs.srv import OracleAnswer, SimReset
    from dialfred_sim.tasks import get_task
    nouns = get_task(args.task).object_nouns
    questions = [(TYPES[k % 3], nouns[(k // 3) % len(nouns)]) for k in range(args.requests)]
    report = {'benchmark': 'oracle_latency', 'requests': args.requests, 'task': args.task}
    with Graph([sim_node(128), oracle_node()]) as graph:
        reset = graph.client(SimReset, '/sim/reset')
        assert graph.call(reset, SimReset.Request(task_id=args.task)).ok
        cli = graph.client(OracleAnswer, '/oracle/answer')
        for q in questions[:30]:     # warm-up
            graph.call(cli, OracleAnswer.Request(question_type=q[0], object_noun=q[1]))
        per_type = {t: [] for t in TYPES}
        invalid = 0
        t0 = time.perf_counter()
        for qtype, noun in questions:
            s = time.perf_counter()
            reply = graph.call(cli, OracleAnswer.Request(question_type=qtype, object_noun=noun))
            per_type[qtype].append((time.perf_counter() - s) * 1e3)
            invalid += not reply.valid
        sequential_s = time.perf_counter() - t0
        all_ms = sorted(ms for v in per_type.values() for ms in v)
        report['sequential'] = {
            'requests_per_s': round(args.requests / sequential_s, 1),
            'p50_ms': round(percentile(all_ms, 0.5), 3), 'p99_ms': round(percentile(all_ms, 0.99), 3),
            'mean_ms': round(statistics.fmean(all_ms), 3), 'invalid_replies': invalid,
            'per_type_p50_ms': {t: round(statistics.median(v), 3) for t, v in per_type.items()},
            'per_type_p99_ms': {t: round(percentile(sorted(v), 0.99), 3) for t, v in per_type.items()},
        }
        # Throughput with several requests outstanding.
        pending, sent, done = [], 0, 0
        t0 = time.perf_counter()
        while done < args.requests:
            while sent < args.requests and len(pending) < args.in_flight:
                qtype, noun = questions[sent]
                pending.append(cli.call_async(OracleAnswer.Request(question_type=qtype, object_noun=noun)))
                sent += 1
            graph.spin_until_any(pending, timeout=1.0)
            finished = [f for f in pending if f.done()]
            done += len(finished)
            pending = [f for f in pending if not f.done()]
        report['pipelined'] = {'in_flight': args.in_flight,
                               'requests_per_s': round(args.requests / (time.perf_counter() - t0), 1)}
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
