"""Fuzzing every service and the action of the graph: thousands of random requests, each bounded in
time. Each gets an answer (a refusal with a reason, never an internal error), no node dies, and a
refused request changes nothing: the simulator's state version and pose, the oracle's answers and
the questioner's next question are what they were. Seeded: the same requests every run.

Slow (about two minutes): `./dialfred test --all` or `./dialfred test tests/system/test_fuzz.py`."""

from __future__ import annotations

import time

import numpy as np
import pytest

from dialfred_bringup.graph import Graph, NodeProcess

pytestmark = pytest.mark.slow

NS = '/fuzz'
WORDS = ['', ' ', 'FloorPlan', 'FloorPlan0', 'FloorPlan1', 'FloorPlan1 ', 'floorplan1', 'valid_unseen/',
         'valid_unseen/000000', 'valid_unseen/999999', 'valid_unseen/-1', 'train/000001', '../../etc/passwd',
         'x' * 5000, 'é\u00e9\u4e2d', '\x00', '\n', 'Pickup', 'pickup', 'Stop ', 'MoveAhead', 'MoveAhead\n',
         'Teleport', 'location', 'appearance', 'direction', 'Location', 'colour', 'apple', 'fridge', 'Apple_0',
         'unicorn', '%s%s%n', '{}', 'null', '-1', '1e309', 'nan']
INTS = [0, -1, 1, 5, 63, 64, 127, 128, 2 ** 31 - 1, -2 ** 31, 10 ** 6]
SEEDS = [0, 1, -1, -2 ** 63, 2 ** 63 - 1, 5]


def word(rng) -> str:
    w = str(rng.choice(WORDS))
    return w + chr(int(rng.integers(32, 0x2FFF))) if rng.random() < 0.2 else w


@pytest.fixture(scope='module')
def graph():
    nodes = [NodeProcess('dialfred_sim', {'resolution': 64}, namespace=NS),
             NodeProcess('dialfred_oracle', namespace=NS),
             NodeProcess('dialfred_questioner', {'questioner': 'all'}, namespace=NS),
             NodeProcess('dialfred_performer', {'questioner': True, 'request_timeout': 10.0}, namespace=NS)]
    with Graph(nodes) as g:
        yield g


def test_the_simulators_services_answer_every_request_and_a_refusal_changes_nothing(graph):
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import GroundTruth, SimReset, SimStep
    reset = graph.client(SimReset, f'{NS}/sim/reset')
    step = graph.client(SimStep, f'{NS}/sim/step')
    truth = graph.client(GroundTruth, f'{NS}/sim/ground_truth')
    rng = np.random.default_rng(11)
    assert graph.call(reset, SimReset.Request(task_id='valid_unseen/000000', seed=0)).ok

    def state():
        t = graph.call(truth, GroundTruth.Request())
        return t.version, (t.agent.x, t.agent.y, t.agent.rotation_deg, t.agent.horizon_deg)

    before, refused, answered = state(), 0, 0
    deadline = time.monotonic() + 120
    for k in range(2000):
        kind = k % 3
        if kind == 0:
            request = SimReset.Request(scene=word(rng), task_id=word(rng) if rng.random() < 0.7 else '',
                                       seed=int(rng.choice(SEEDS)), with_depth=bool(rng.random() < 0.5))
            reply = graph.call(reset, request)
        elif kind == 1:
            action = Action(action=word(rng), x=int(rng.choice(INTS)), y=int(rng.choice(INTS)))
            reply = graph.call(step, SimStep.Request(action=action, with_segmentation=bool(rng.random() < 0.5)))
        else:
            ids = [word(rng) for _ in range(int(rng.integers(0, 4)))]
            reply = graph.call(truth, GroundTruth.Request(appearance_of=ids, known_version=int(rng.integers(0, 2 ** 63))))
        answered += 1
        assert reply.ok or reply.error, (kind, reply)                 # a refusal says why
        assert 'internal error' not in reply.error, reply.error
        if reply.ok and kind != 2:
            before = state()
        elif not reply.ok:
            refused += 1
            if kind != 2:
                assert state() == before, (kind, reply.error)         # a refused reset or step changed nothing
        assert time.monotonic() < deadline
    graph.check()
    assert answered == 2000 and refused > 500


def test_the_oracle_answers_every_request_and_its_answers_stay_the_same(graph):
    from dialfred_msgs.srv import OracleAnswer, SimReset
    reset = graph.client(SimReset, f'{NS}/sim/reset')
    ask = graph.client(OracleAnswer, f'{NS}/oracle/answer')
    assert graph.call(reset, SimReset.Request(task_id='valid_unseen/000003', seed=0)).ok
    probe = [OracleAnswer.Request(question_type=t, object_noun=n) for t, n in
             [('location', 'apple'), ('appearance', 'apple'), ('direction', '')]]
    first = [(r.valid, r.answer, r.reason) for r in (graph.call(ask, p) for p in probe)]
    rng = np.random.default_rng(12)
    for k in range(2000):
        reply = graph.call(ask, OracleAnswer.Request(question_type=word(rng), object_noun=word(rng)))
        assert reply.valid == bool(reply.answer) and (reply.valid or reply.reason), reply
        assert 'internal error' not in reply.reason
        if k % 200 == 0:
            assert [(r.valid, r.answer, r.reason) for r in (graph.call(ask, p) for p in probe)] == first
    graph.check()


def test_the_questioner_answers_every_request_and_refusals_leave_its_episode_as_it_was(graph):
    from dialfred_msgs.msg import QAPair, TaskDescription
    from dialfred_msgs.srv import QuestionerAsk
    from sensor_msgs.msg import Image
    ask = graph.client(QuestionerAsk, f'{NS}/questioner/ask')
    task = TaskDescription(task_id='valid_unseen/000003', instruction='Put the apple in the fridge.',
                           object_nouns=['apple', 'fridge'])
    rng = np.random.default_rng(13)

    def junk():
        return QuestionerAsk.Request(
            task=TaskDescription(task_id=word(rng), instruction=word(rng), object_nouns=[word(rng)]),
            seed=int(rng.choice(SEEDS)), step=int(rng.integers(0, 2 ** 32)), confusion_gap=float(rng.normal()),
            rgb=Image(height=int(rng.integers(0, 4)), width=int(rng.integers(0, 4)), encoding=word(rng),
                      data=bytes(rng.integers(0, 256, int(rng.integers(0, 40))).astype(np.uint8))),
            dialogue=[QAPair(question_type=word(rng), object_noun=word(rng), valid=bool(rng.random() < 0.5))
                      for _ in range(int(rng.integers(0, 3)))])

    def episode(with_junk: bool):
        asked, dialogue = [], []
        for step in range(8):
            if with_junk:
                for _ in range(150):
                    reply = graph.call(ask, junk())
                    assert reply.ok or reply.error, reply
                    assert 'internal error' not in reply.error, reply.error
            reply = graph.call(ask, QuestionerAsk.Request(task=task, seed=1, step=step, dialogue=dialogue))
            assert reply.ok, reply.error
            asked.append((reply.ask, reply.question_type, reply.object_noun))
            if reply.ask:
                dialogue.append(QAPair(question_type=reply.question_type, object_noun=reply.object_noun, valid=True))
        return asked

    assert episode(with_junk=True) == episode(with_junk=False)
    graph.check()


def test_the_performer_refuses_every_bad_goal_with_a_reason_and_plays_the_next(graph):
    from action_msgs.msg import GoalStatus
    from dialfred_msgs.action import RunTask
    from rclpy.action import ActionClient
    client = ActionClient(graph.client_node, RunTask, f'{NS}/performer/run_task')
    assert client.wait_for_server(timeout_sec=30)

    def wait(future, timeout=60.0):
        deadline = time.monotonic() + timeout
        while not future.done():
            graph.spin_until_any([], 0.05)
            assert time.monotonic() < deadline
        return future.result()

    rng = np.random.default_rng(14)
    bad_ids = [w for w in WORDS if not w.startswith(('valid_unseen/0', 'train/0'))]
    for _ in range(300):
        goal = RunTask.Goal(task_id=str(rng.choice(bad_ids)), seed=int(rng.choice(SEEDS)),
                            checkpoint=word(rng) if rng.random() < 0.3 else '')
        handle = wait(client.send_goal_async(goal))
        assert handle.accepted
        done = wait(handle.get_result_async())
        assert done.status == GoalStatus.STATUS_ABORTED and done.result.end_reason == 'error', (goal, done.result)
        assert done.result.error and 'internal error' not in done.result.error, done.result.error
    # and a good goal still plays (cancelled after a few steps: the node serves on)
    handle = wait(client.send_goal_async(RunTask.Goal(task_id='valid_unseen/000000', seed=1)))
    assert handle.accepted
    wait(handle.cancel_goal_async())
    done = wait(handle.get_result_async(), timeout=120)
    assert done.result.end_reason in ('canceled', 'stop', 'success', 'max_steps', 'max_failures'), done.result
    graph.check()
