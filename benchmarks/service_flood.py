#!/usr/bin/env python3
"""Floods of concurrent requests on /sim/step and /oracle/answer: how many get a reply.

For each service, N requests are sent at once from one client (call_async, nothing awaited between
them), and the client waits until every reply is in or `--wait` seconds pass. Two servers per
service in the same run: the nodes as shipped (history KEEP_ALL, `ros_util.SERVICE_QOS`) and the
same node code with ROS's default service QoS (keep last 10), the baseline that lost requests.

    ./dialfred bench service_flood [--steps 500] [--questions 200] [--wait 20]

Prints JSON: per service and QoS, sent, replied, ok (executed), seconds until the last reply.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from rclpy.qos import qos_profile_services_default

from dialfred_bringup.graph import Graph, NodeProcess, sim_service, use_private_ros_domain
from dialfred_msgs.msg import Action
from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep

REPO = Path(__file__).resolve().parents[1]
class DefaultQosNode(NodeProcess):
    """The package's node run by this script with ROS's default service QoS (see --serve)."""

    def command(self) -> list[str]:
        return [sys.executable, str(Path(__file__).resolve()), '--serve', self.package] + super().command()[1:]


def serve_with_default_qos(package: str, ros_args: list[str]) -> None:
    module = __import__(f'{package}.node', fromlist=['main'])
    module.SERVICE_QOS = qos_profile_services_default
    module.main([package, *ros_args])


def flood(graph: Graph, cli, request, n: int, wait: float) -> dict:
    t0 = time.monotonic()
    futures = [cli.call_async(request) for _ in range(n)]
    deadline = t0 + wait
    last = t0
    while time.monotonic() < deadline:
        pending = [f for f in futures if not f.done()]
        if not pending:
            break
        graph.executor.spin_once(timeout_sec=0.05)
        if len(pending) != sum(not f.done() for f in futures):
            last = time.monotonic()
    replies = [f.result() for f in futures if f.done()]
    ok = sum(bool(getattr(r, 'ok', getattr(r, 'valid', False))) for r in replies)
    return {'sent': n, 'replied': len(replies), 'ok': ok, 'last_reply_s': round(last - t0, 3)}


def run(qos: str, steps: int, questions: int, wait: float) -> dict:
    ns = f'/flood_{qos}'
    node_class = NodeProcess if qos == 'keep_all' else DefaultQosNode
    nodes = [node_class('dialfred_sim', {'resolution': 64}, namespace=ns),
             node_class('dialfred_oracle', {}, namespace=ns)]
    with Graph(nodes) as graph:
        reset = graph.client(SimReset, sim_service(ns, 'reset'))
        step = graph.client(SimStep, sim_service(ns, 'step'))
        ask = graph.client(OracleAnswer, f'{ns}/oracle/answer')
        assert graph.call(reset, SimReset.Request(task_id='valid_unseen/000012')).ok
        question = OracleAnswer.Request(question_type='location', object_noun=graph.call(
            reset, SimReset.Request(task_id='valid_unseen/000012')).task.object_nouns[0])
        oracle = flood(graph, ask, question, questions, wait)
        sim = flood(graph, step, SimStep.Request(action=Action(action='RotateLeft'), with_depth=False,
                                                 with_segmentation=False), steps, wait)
    return {'sim_step': sim, 'oracle_answer': oracle}


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == '--serve':
        serve_with_default_qos(sys.argv[2], sys.argv[3:])
        return
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', type=int, default=500)
    parser.add_argument('--questions', type=int, default=200)
    parser.add_argument('--wait', type=float, default=20.0, help='seconds to wait for the last reply')
    args = parser.parse_args()
    use_private_ros_domain()
    report = {'benchmark': 'service_flood', 'steps': args.steps, 'questions': args.questions}
    for qos in ('keep_all', 'ros_default'):
        report[qos] = run(qos, args.steps, args.questions, args.wait)
    print(json.dumps(report, indent=1))


if __name__ == '__main__':
    main()
