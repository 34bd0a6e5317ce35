#!/usr/bin/env python3
"""Fuzzing `/oracle/answer`: malformed and random requests, with valid ones in between.

Sends `--requests` malformed or random questions (unknown types, unknown objects, empty strings,
1 MB strings, non-ASCII and control characters, random bytes as text, scene objects that are not
part of the task) and, after every `--every` of them, a valid question whose answer must equal the
one given before the fuzzing started (the world does not change meanwhile). Counts crashes (the node
process exiting), malformed replies (valid with an empty answer or a reason; invalid without a
reason or with an answer) and wrong valid answers. Prints JSON.

    ./dialfred bench oracle_fuzz [--requests 10000] [--every 10] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from dialfred_bringup.graph import Graph, NodeDied, oracle_node, sim_node, use_private_ros_domain
from dialfred_msgs.srv import GroundTruth, OracleAnswer, SimReset

TYPES = ('location', 'appearance', 'direction')


def fuzz_request(rng: np.random.Generator, scene_nouns: list[str]) -> tuple[str, str, str]:
    """(kind, question_type, object_noun) of one malformed or random request."""
    kind = ['unknown_type', 'unknown_object', 'empty', 'huge', 'non_ascii', 'control', 'random_text',
            'off_task_object', 'whitespace'][int(rng.integers(9))]
    qtype = TYPES[int(rng.integers(3))]
    if kind == 'unknown_type':
        return kind, ''.join(chr(int(c)) for c in rng.integers(97, 123, int(rng.integers(1, 12)))), 'apple'
    if kind == 'unknown_object':
        return kind, qtype, ''.join(chr(int(c)) for c in rng.integers(97, 123, int(rng.integers(3, 15))))
    if kind == 'empty':
        return kind, ['', qtype][int(rng.integers(2))], ''
    if kind == 'huge':
        return kind, [qtype, 'x' * 1_000_000][int(rng.integers(2))], 'a' * 1_000_000
    if kind == 'non_ascii':
        return kind, qtype, ''.join(chr(int(c)) for c in rng.integers(0x00C0, 0x2FFF, int(rng.integers(1, 20))))
    if kind == 'control':
        return kind, qtype, 'apple' + ''.join(chr(int(c)) for c in rng.integers(1, 32, 3))
    if kind == 'random_text':
        raw = bytes(rng.integers(32, 127, int(rng.integers(1, 60))).astype(np.uint8))
        return kind, raw.decode('ascii'), raw[::-1].decode('ascii')
    if kind == 'off_task_object':
        return kind, qtype, scene_nouns[int(rng.integers(len(scene_nouns)))]
    return kind, qtype, ' ' * int(rng.integers(1, 10))


def well_formed(reply) -> bool:
    if reply.valid:
        return bool(reply.answer) and not reply.reason
    return bool(reply.reason) and not reply.answer


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--requests', type=int, default=10000)
    ap.add_argument('--every', type=int, default=10)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--task', default='valid_unseen/000003')
    args = ap.parse_args()
    use_private_ros_domain()
    rng = np.random.default_rng(args.seed)
    report = {'benchmark': 'oracle_fuzz', 'requests': args.requests, 'seed': args.seed, 'task': args.task}
    oracle = oracle_node()
    crashes = malformed = wrong = valid_asked = 0
    kinds: dict[str, int] = {}
    valid_fuzz = 0
    t0 = time.perf_counter()
    with Graph([sim_node(128), oracle]) as graph:
        assert graph.call(graph.client(SimReset, '/sim/reset'), SimReset.Request(task_id=args.task)).ok
        truth = graph.call(graph.client(GroundTruth, '/sim/ground_truth'), GroundTruth.Request())
        scene_nouns = sorted({f.noun for f in truth.objects} - set(truth.task_nouns))
        cli = graph.client(OracleAnswer, '/oracle/answer')
        good = [(t, n) for n in truth.task_nouns for t in TYPES]
        reference = {}
        for t, n in good:
            reply = graph.call(cli, OracleAnswer.Request(question_type=t, object_noun=n))
            if reply.valid:
                reference[(t, n)] = reply.answer
        good = sorted(reference)
        for k in range(args.requests):
            kind, qtype, noun = fuzz_request(rng, scene_nouns)
            kinds[kind] = kinds.get(kind, 0) + 1
            try:
                reply = graph.call(cli, OracleAnswer.Request(question_type=qtype, object_noun=noun))
            except NodeDied:
                crashes += 1
                break
            malformed += not well_formed(reply)
            valid_fuzz += reply.valid
            if (k + 1) % args.every == 0:
                t, n = good[int(rng.integers(len(good)))]
                reply = graph.call(cli, OracleAnswer.Request(question_type=t, object_noun=n))
                valid_asked += 1
                wrong += not (reply.valid and reply.answer == reference[(t, n)])
        alive = oracle.proc.poll() is None
    report.update({
        'wall_s': round(time.perf_counter() - t0, 1), 'request_kinds': kinds, 'crashes': crashes,
        'oracle_alive_at_end': alive, 'malformed_replies': malformed,
        'fuzz_requests_answered_valid': valid_fuzz, 'valid_requests_between': valid_asked,
        'valid_requests_answered_wrong': wrong, 'reference_questions': len(reference),
        'passed': crashes == 0 and alive and malformed == 0 and wrong == 0,
    })
    print(json.dumps(report, indent=2))


if __name__ == '__main__':
    main()
