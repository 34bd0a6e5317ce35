"""Decision overhead of the performer node: ms per step of a RunTask goal through the graph (sim node +
performer node, two processes) against the same policy stepping DialfredEnv in one process.

A random-init performer of the default config whose action head favours RotateLeft (an episode that
never ends by itself) plays `--steps` steps of one task both ways; prints JSON.

    ./dialfred bench performer_node [--steps 200] [--resolution 128]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import torch
from rclpy.action import ActionClient

from dialfred_bringup.graph import Graph, NodeProcess, sim_node, use_private_ros_domain
from dialfred_msgs.action import RunTask
from dialfred_performer.agent import PerformerAgent
from dialfred_performer.model import Performer, PerformerConfig, save_checkpoint
from dialfred_performer.preprocess import Vocabulary
from dialfred_sim.env import DialfredEnv
from dialfred_sim.protocol import ACTIONS
from dialfred_sim.tasks import load_split

REPO = Path(__file__).resolve().parents[1]
TASK = 'valid_unseen/000000'


def checkpoint(path: Path) -> Path:
    vocab = Vocabulary.build([t.instruction for t in load_split('valid_unseen')[:200]])
    torch.manual_seed(0)
    model = Performer(PerformerConfig(), len(vocab))
    with torch.no_grad():
        model.action_head.linear.bias[ACTIONS.index('RotateLeft')] += 50.0
    save_checkpoint(path, model, vocab, command='benchmarks/performer_node.py')
    return path


def in_process(ckpt: Path, steps: int, resolution: int) -> float:
    env = DialfredEnv(resolution=resolution, max_steps=steps)
    agent = PerformerAgent.from_checkpoint(ckpt)
    obs, _ = env.reset(options={'task_id': TASK})
    agent.reset(env.task.public(), 0)
    t0, n = time.perf_counter(), 0
    while True:
        name, x, y = agent.act(obs['rgb'])
        obs, _, terminated, truncated, _ = env.step({'action': name, 'pixel': (x, y)})
        n += 1
        if terminated or truncated:
            break
    env.close()
    return (time.perf_counter() - t0) / n * 1000


def through_nodes(ckpt: Path, steps: int, resolution: int) -> float:
    nodes = [sim_node(resolution, '/b', publish_observations=False, max_steps=steps),
             NodeProcess('dialfred_performer', {'checkpoint': str(ckpt)}, namespace='/b')]
    with Graph(nodes) as graph:
        client = ActionClient(graph.client_node, RunTask, '/b/performer/run_task')
        while not client.wait_for_server(timeout_sec=0.1):
            graph.check()
        graph.spin_until_any([], 0.3)
        first = []

        def run():
            future = client.send_goal_async(RunTask.Goal(task_id=TASK, seed=0),
                                            feedback_callback=lambda m: first or first.append(time.perf_counter()))
            while not future.done():
                graph.spin_until_any([future], 0.5)
            result = future.result().get_result_async()
            while not result.done():
                graph.spin_until_any([result], 0.5)
            return result.result().result, time.perf_counter()

        run()                              # warm-up: loads the checkpoint, discovers the services
        first.clear()
        result, end = run()
        # From the first step's feedback to the result: steps - 1 steps, start-up (reset) excluded.
        return (end - first[0]) / (result.steps - 1) * 1000


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument('--steps', type=int, default=200)
    parser.add_argument('--resolution', type=int, default=128)
    args = parser.parse_args()
    use_private_ros_domain()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        ckpt = checkpoint(Path(tmp) / 'rotate.pt')
        local = in_process(ckpt, args.steps, args.resolution)
        node = through_nodes(ckpt, args.steps, args.resolution)
    print(json.dumps({'steps': args.steps, 'resolution': args.resolution, 'ms_per_step_in_process': round(local, 2),
                      'ms_per_step_through_nodes': round(node, 2), 'overhead_ms': round(node - local, 2)}, indent=1))


if __name__ == '__main__':
    main()
