"""A person in the loop (`--human`): the oracle puts each question to the person once, however often the
transport sends it again while they think, and the robot waits as long as they need, or `human_timeout`
seconds and then hears "I don't know.". A scripted person answers after 8 s (the oracle node, and the
in-process agent through the graph) and after 70 s (through the performer node: slow tier)."""

from __future__ import annotations

import collections
import os
import subprocess
import threading
import time

import pytest

from dialfred_bringup import workers
from dialfred_bringup.evaluation import EvalConfig, run_eval
from dialfred_bringup.graph import Graph, NodeProcess, sim_node
from dialfred_msgs.msg import Action
from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep
from dialfred_sim.ros_util import RESEND_AFTER_S
from dialfred_sim.tasks import get_task

TASK = 'valid_unseen/000003'
PROMPT = 'waiting for your answer'

ASK_ONCE = '''
from dialfred_sim.protocol import Question


class AskOnce:
    """Asks where the first object of its task is, once, before its first action."""

    name = 'ask-once'

    def reset(self, task, seed):
        self.noun, self.asked = (list(task.object_nouns) or [''])[0], False

    def ask(self, observation, step):
        if self.asked:
            return None
        self.asked = True
        return Question('location', self.noun)

    def hear(self, qa):
        pass
'''


class ScriptedPerson:
    """Reads the oracle's prompts from its output and answers each one `delay` seconds after it appeared,
    with `words` (numbered: 'words 1', 'words 2', ...)."""

    def __init__(self, node: NodeProcess, delay: float, words: str = 'It is by the window'):
        self.node, self.delay, self.words = node, delay, words
        self.prompts = 0
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> 'ScriptedPerson':
        self.thread.start()
        return self

    def _run(self) -> None:
        answered = 0
        while not self._stop.is_set():
            self.prompts = sum(PROMPT in line for line in self.node.tail)
            if self.prompts > answered:
                if self._stop.wait(self.delay):
                    return
                answered += 1
                self.node.proc.stdin.write(f'{self.words} {answered}.\n')
                self.node.proc.stdin.flush()
            time.sleep(0.05)

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(timeout=5)


def person_oracle(namespace: str, **params) -> NodeProcess:
    """The oracle node in human mode, its terminal the test's pipes (all its output kept)."""
    return NodeProcess('dialfred_oracle', {'human': True, **params}, namespace=namespace, stdin=subprocess.PIPE,
                       tail=collections.deque(maxlen=100_000))


def test_a_person_who_takes_8_s_is_asked_each_question_once_and_heard(tmp_path):
    oracle = person_oracle('/p')
    with Graph([sim_node(64, namespace='/p'), oracle]) as g:
        assert g.call(g.client(SimReset, '/p/sim/reset'), SimReset.Request(task_id=TASK), retry_after=RESEND_AFTER_S).ok
        cli, step = g.client(OracleAnswer, '/p/oracle/answer'), g.client(SimStep, '/p/sim/step')
        noun = get_task(TASK).object_nouns[0]
        person = ScriptedPerson(oracle, delay=8.0).start()
        try:
            t0 = time.monotonic()
            first = g.call(cli, OracleAnswer.Request(question_type='location', object_noun=noun),
                           timeout=120, retry_after=RESEND_AFTER_S)      # sent again after 5 s, as the callers do
            waited = time.monotonic() - t0
            assert first.valid and first.answer == 'It is by the window 1.', (first, list(oracle.tail)[-8:])
            assert waited >= 8.0 and person.prompts == 1
            second = g.call(cli, OracleAnswer.Request(question_type='direction'), timeout=120,
                            retry_after=RESEND_AFTER_S)
            assert second.answer == 'It is by the window 2.' and person.prompts == 2
            # the same question in the same world state is the question already asked: no new prompt
            again = g.call(cli, OracleAnswer.Request(question_type='location', object_noun=noun), timeout=30)
            assert again.answer == first.answer and person.prompts == 2
            # once the world has changed it is a new question
            assert g.call(step, SimStep.Request(action=Action(action='RotateLeft'), with_depth=False)).ok
            later = g.call(cli, OracleAnswer.Request(question_type='location', object_noun=noun), timeout=120,
                           retry_after=RESEND_AFTER_S)
            assert later.answer == 'It is by the window 3.' and person.prompts == 3
        finally:
            person.stop()
    assert sum('the agent asks' in line for line in oracle.tail) == 3


def test_a_person_who_does_not_answer_in_human_timeout_is_heard_as_i_dont_know():
    oracle = person_oracle('/q', human_timeout=2.0)
    with Graph([sim_node(64, namespace='/q'), oracle]) as g:
        assert g.call(g.client(SimReset, '/q/sim/reset'), SimReset.Request(task_id=TASK), retry_after=RESEND_AFTER_S).ok
        t0 = time.monotonic()
        reply = g.call(g.client(OracleAnswer, '/q/oracle/answer'), OracleAnswer.Request(question_type='direction'),
                       timeout=60)
        assert reply.valid and reply.answer == "I don't know." and time.monotonic() - t0 >= 2.0
        deadline = time.monotonic() + 5
        while not any('no answer in 2 s' in line for line in oracle.tail) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert any('no answer in 2 s' in line for line in oracle.tail), list(oracle.tail)


def human_run(tmp_path, monkeypatch, delay: float, **settings):
    """An evaluation with --human whose person is a ScriptedPerson answering after `delay` seconds."""
    (tmp_path / 'ask_once.py').write_text(ASK_ONCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv('PYTHONPATH', f'{tmp_path}:{os.environ.get("PYTHONPATH", "")}')   # the questioner node's too
    made = []

    def oracle_node(namespace='', human=False, **params):
        assert human
        made.append(person_oracle(namespace, **params))
        return made[-1]

    monkeypatch.setattr(workers, 'oracle_node', oracle_node)
    people = []
    real_start = NodeProcess.start

    def start(node):
        real_start(node)
        if node in made:
            people.append(ScriptedPerson(node, delay).start())

    monkeypatch.setattr(NodeProcess, 'start', start)
    try:
        report = run_eval(EvalConfig(split='valid_unseen', questioner='ask_once:AskOnce', human=True, workers=1,
                                     resolution=64, out=tmp_path / 'h.jsonl', **settings), progress=False)
    finally:
        for p in people:
            p.stop()
    return report, people


@pytest.mark.slow    # a whole evaluation with a person; fast: the oracle node's 8 s person above
def test_the_in_process_agent_waits_8_s_for_its_person_with_one_prompt_a_question(tmp_path, monkeypatch):
    report, (person,) = human_run(tmp_path, monkeypatch, 8.0, agent='random', limit=2)
    assert [r.questions for r in report.results] == [1, 1] and person.prompts == 2
    assert [r.dialogue[0]['answer'] for r in report.results] == ['It is by the window 1.', 'It is by the window 2.']
    assert all(r.end_reason != 'error' for r in report.results)


@pytest.mark.slow    # 70 s of a person thinking; fast: the 8 s person above
def test_a_person_who_takes_70_s_gets_through_the_performer_node_with_one_prompt(tmp_path, monkeypatch, checkpoint):
    report, (person,) = human_run(tmp_path, monkeypatch, 70.0, performer='et', checkpoint=checkpoint, limit=1)
    (r,) = report.results
    assert r.questions == 1 and person.prompts == 1 and r.end_reason != 'error', r
    assert r.dialogue[0]['answer'] == 'It is by the window 1.'


def test_the_person_sees_what_the_map_performer_took_from_their_words(tmp_path, monkeypatch, capfd):
    report, (person,) = human_run(tmp_path, monkeypatch, 0.2, performer='map', limit=1)
    (r,) = report.results
    assert r.questions == 1 and person.prompts == 1
    # the person is told what the map performer's reader took from their words ("It is by the window 1.")
    heard = [line for line in capfd.readouterr().err.splitlines() if line.startswith('[robot] heard: ')]
    assert len(heard) == 1 and heard[0].endswith('on the Window'), heard
