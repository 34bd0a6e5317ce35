"""The performer and questioner nodes as separate processes, playing tasks through the real graph.

Claims: with a small (untrained) checkpoint, `launch eval --performer et` (a performer node per
worker, RunTask goals) gives the very episodes of the in-process path (actions, steps, success,
goal conditions, questions) for a fixed seed, with the model-confusion questioner asking through
/questioner/ask; a running goal can be cancelled, and a second goal is refused while one runs; bad
goals (unknown task id, missing or corrupt checkpoint, negative seed) end with a clear error and the
node keeps serving.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import torch


from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.graph import Graph, NodeProcess, sim_node
from helpers import tiny_checkpoint

REPO = Path(__file__).resolve().parents[2]
RES = 64


@pytest.mark.slow   # fast: test_eval_local compares every local episode with the graph's
def test_the_node_path_and_the_in_process_path_play_identical_episodes(checkpoint, tmp_path):
    torch.set_num_threads(1)            # as the node (torch_threads=1): the same arithmetic
    common = dict(split='valid_unseen', questioner='confusion', limit=3, workers=1, resolution=RES, seed=5,
                  checkpoint=checkpoint)
    in_process, through_nodes = {}, {}
    a = run_eval(EvalConfig(agent='et', out=tmp_path / 'a.jsonl', **common), progress=False, traces=in_process)
    b = run_eval(EvalConfig(performer='et', out=tmp_path / 'b.jsonl', **common), progress=False,
                 traces=through_nodes)
    assert a.to_json()['through'] == 'in-process agent' and b.to_json()['through'] == 'performer node'
    def key(r):
        return (r.task_id, r.success, r.steps, r.goal_conditions_met, r.goal_conditions_total, r.questions,
                r.invalid_questions, r.failed_actions, r.end_reason, r.error, r.agent, r.dialogue)
    assert [key(r) for r in a.results] == [key(r) for r in b.results]      # the dialogues too (dialogue/qa)
    assert all(len(r.dialogue) == r.questions for r in b.results)
    assert in_process == through_nodes and len(in_process) == 3
    assert all(len(in_process[r.task_id]) == r.steps for r in a.results)
    assert sum(r.questions for r in a.results) > 0          # the confusion questioner did ask over ROS
    assert all(r.end_reason != 'error' for r in b.results), [r.error for r in b.results]


def wait(graph, future, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not future.done():
        graph.spin_until_any([future], 0.5)
        assert time.monotonic() < deadline, 'no reply'
    return future.result()


def test_cancel_a_refused_second_goal_and_bad_goals_while_the_node_keeps_serving(tmp_path):
    from action_msgs.msg import GoalStatus
    from rclpy.action import ActionClient

    from dialfred_msgs.action import RunTask
    spinning = tiny_checkpoint(tmp_path / 'spin.pt', favour='RotateLeft')    # never ends by itself before 1000 steps
    stopping = tiny_checkpoint(tmp_path / 'stop.pt', favour='Stop')
    corrupt = tmp_path / 'corrupt.pt'
    corrupt.write_bytes(b'not a checkpoint at all')
    ns = '/perf'
    nodes = [sim_node(RES, ns, publish_observations=False),
             NodeProcess('dialfred_performer', {'checkpoint': str(spinning)}, namespace=ns)]
    with Graph(nodes) as graph:
        client = ActionClient(graph.client_node, RunTask, f'{ns}/performer/run_task')
        while not client.wait_for_server(timeout_sec=0.1):
            graph.check()
        graph.spin_until_any([], 0.3)
        feedback = []

        def run(goal, on_feedback=None):
            handle = wait(graph, client.send_goal_async(goal, feedback_callback=on_feedback))
            assert handle.accepted
            return handle

        handle = run(RunTask.Goal(task_id='valid_unseen/000000', seed=1), lambda m: feedback.append(m.feedback))
        deadline = time.monotonic() + 30
        while len(feedback) < 3:
            graph.spin_until_any([], 0.1)
            assert time.monotonic() < deadline
        assert feedback[0].action.action == 'RotateLeft' and feedback[0].step == 1
        # One goal at a time: a second is refused while the first runs.
        second = wait(graph, client.send_goal_async(RunTask.Goal(task_id='valid_unseen/000001', seed=1)))
        assert not second.accepted
        wait(graph, handle.cancel_goal_async())
        done = wait(graph, handle.get_result_async())
        assert done.status == GoalStatus.STATUS_CANCELED and done.result.end_reason == 'canceled'
        assert 3 <= done.result.steps < 1000

        bad = [(RunTask.Goal(task_id='valid_unseen/999999', seed=1), "unknown task_id 'valid_unseen/999999'"),
               (RunTask.Goal(task_id='valid_unseen/000000', seed=1, checkpoint=str(tmp_path / 'missing.pt')),
                'no performer checkpoint at'),
               (RunTask.Goal(task_id='valid_unseen/000000', seed=1, checkpoint=str(corrupt)),
                'is not a readable checkpoint'),
               (RunTask.Goal(task_id='valid_unseen/000000', seed=-1), 'seed must be a non-negative integer'),
               (RunTask.Goal(task_id='', seed=1), 'task_id is empty'),
               (RunTask.Goal(task_id='  ', seed=1), 'task_id is empty')]
        for goal, said in bad:
            done = wait(graph, run(goal).get_result_async())
            assert done.status == GoalStatus.STATUS_ABORTED and done.result.end_reason == 'error'
            assert said in done.result.error, done.result.error
        # Still serving: a good goal plays to its end (Stop at once), checked by the simulator.
        done = wait(graph, run(RunTask.Goal(task_id='valid_unseen/000000', seed=1,
                                            checkpoint=str(stopping))).get_result_async())
        assert done.status == GoalStatus.STATUS_SUCCEEDED
        assert (done.result.end_reason, done.result.steps, done.result.last_action) == ('stop', 1, 'Stop')
        assert done.result.goal_conditions_total > 0 and not done.result.success
        graph.check()


def test_the_questioner_node_asks_like_the_baseline_and_refuses_a_confusion_request_without_a_gap():
    from dialfred_msgs.msg import QAPair, TaskDescription
    from dialfred_msgs.srv import QuestionerAsk
    task = TaskDescription(task_id='valid_unseen/000003', instruction='Put the apple in the fridge.',
                           object_nouns=['apple', 'fridge'])
    nodes = [NodeProcess('dialfred_questioner', {'questioner': 'all'}, namespace='/qa'),
             NodeProcess('dialfred_questioner', {'questioner': 'confusion'}, namespace='/qc')]
    with Graph(nodes) as graph:
        ask_all = graph.client(QuestionerAsk, '/qa/questioner/ask')
        asked, dialogue = [], []
        while True:
            reply = graph.call(ask_all, QuestionerAsk.Request(task=task, seed=1, step=0, dialogue=dialogue))
            assert reply.ok, reply.error
            if not reply.ask:
                break
            asked.append((reply.question_type, reply.object_noun))
            dialogue.append(QAPair(question_type=reply.question_type, object_noun=reply.object_noun, valid=True))
        assert asked == [('location', 'apple'), ('appearance', 'apple'), ('location', 'fridge'),
                         ('appearance', 'fridge'), ('direction', '')]          # AllQuestioner's order
        # An episode named by its player (the performer node sends its goal's id) starts afresh only under a
        # new name, not when a request of step 0 with an empty dialogue comes (which starts an unnamed one).
        named = [graph.call(ask_all, QuestionerAsk.Request(task=task, seed=1, step=0, episode=name, confusion_gap=gap))
                 for name, gap in (('goal-a', -1.0), ('goal-a', 0.5), ('goal-b', -1.0))]
        assert [(r.ok, r.question_type, r.object_noun) for r in named] == [
            (True, 'location', 'apple'), (True, 'appearance', 'apple'), (True, 'location', 'apple')]
        confusion = graph.client(QuestionerAsk, '/qc/questioner/ask')
        reply = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=0))
        assert not reply.ok and 'confusion_gap' in reply.error
        sure = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=0, confusion_gap=0.9))
        unsure = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=1, confusion_gap=0.1))
        assert (sure.ok, sure.ask, unsure.ok, unsure.ask) == (True, False, True, True)
        graph.check()
    bad = NodeProcess('dialfred_questioner', {'questioner': 'nosuch'})
    bad.start()
    assert bad.proc.wait(30) == 1
    time.sleep(0.2)
    assert any('unknown questioner' in line for line in bad.tail)


def test_the_performer_node_warns_once_when_the_camera_is_not_its_checkpoints_resolution(tmp_path):
    """A checkpoint trained at 64 px against a simulator of 32 px: the frames are resized and the performer
    plays otherwise than in its evaluation. The node says so, naming the resolution to start the simulator
    with, once per checkpoint and frame size; against a 64 px simulator it says nothing."""
    from rclpy.action import ActionClient

    from dialfred_msgs.action import RunTask
    stopping = tiny_checkpoint(tmp_path / 'stop.pt', favour='Stop')       # trained at 64 px: ends at once
    warned = {}
    for camera in (32, RES):
        ns = f'/cam{camera}'
        performer = NodeProcess('dialfred_performer', {'checkpoint': str(stopping)}, namespace=ns)
        with Graph([sim_node(camera, ns, publish_observations=False), performer]) as graph:
            client = ActionClient(graph.client_node, RunTask, f'{ns}/performer/run_task')
            while not client.wait_for_server(timeout_sec=0.1):
                graph.check()
            for task_id in ('valid_unseen/000000', 'valid_unseen/000001'):
                handle = wait(graph, client.send_goal_async(RunTask.Goal(task_id=task_id, seed=1)))
                assert handle.accepted and wait(graph, handle.get_result_async()).result.end_reason == 'stop'
            graph.spin_until_any([], 0.5)
            warned[camera] = [line for line in performer.tail if 'resolution:=' in line]
    assert len(warned[32]) == 1 and '32x32 px frames' in warned[32][0] and 'resolution:=64' in warned[32][0]
    assert warned[RES] == []
