"""Integrity of the benchmark: no agent is told what only the checker may know.

Claims: an agent (and a questioner) is given the public view of its task, the instruction and the
nouns it names, never the expert's plan, the goal, the type or the expert's end pose; an agent that
looks for the plan in everything it is given and never at a frame scores nothing through
`launch eval`; the expert, which does read the plan, is a privileged reference and its results say
so; a user's class cannot make itself privileged.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import pytest

from dialfred_sim.agents import ExpertAgent, RandomAgent, make_agent, public_view, task_view
from dialfred_sim.tasks import PublicTask, get_task

from dialfred_bringup.evaluation import EvalConfig, run_eval

REPO = Path(__file__).resolve().parents[2]
SPLIT = 'valid_unseen'
SOLUTION_FIELDS = {'task_type', 'episode', 'goal', 'expert_actions', 'expert_length', 'expert_end_pose',
                   'step_instructions', 'primitives', 'start', 'end', 'start_pose', 'resolution', 'visible_end'}

CHEATERS = '''
from dialfred_sim.protocol import ACTIONS


def find_plan(obj, depth=0, seen=None):
    """Every list of expert-looking actions reachable from `obj` through attributes and items."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 4:
        return None
    seen.add(id(obj))
    if isinstance(obj, (list, tuple)) and obj and all(getattr(a, 'action', None) in ACTIONS for a in obj):
        return list(obj)
    children = []
    if isinstance(obj, dict):
        children = list(obj.values())
    elif isinstance(obj, (list, tuple)):
        children = list(obj)
    elif not isinstance(obj, (str, bytes, int, float, bool, type(None))):
        names = [n for n in dir(obj) if not n.startswith('__')]
        for n in names:
            try:
                children.append(getattr(obj, n))
            except Exception:
                pass
    for child in children:
        if callable(child) and not isinstance(child, type):
            try:
                child = child()
            except Exception:
                continue
        found = find_plan(child, depth + 1, seen)
        if found:
            return found
    return None


class BlindReplayer:
    """Never looks at a frame: searches whatever it is told for the expert's plan and replays it;
    with nothing to replay it stops at once."""

    name = 'blind'
    found = []

    def __init__(self, resolution=128):
        self.resolution = resolution

    def reset(self, task, seed):
        self.plan = find_plan(task) or []
        BlindReplayer.found.append(bool(self.plan))

    def act(self, observation):
        if self.plan:
            a = self.plan.pop(0)
            return (a.action, a.x, a.y)
        return ('Stop', -1, -1)


class SelfProclaimedExpert(BlindReplayer):
    privileged = True
'''


@pytest.fixture
def cheaters(tmp_path, monkeypatch):
    (tmp_path / 'cheaters.py').write_text(CHEATERS)
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib
    module = importlib.import_module('cheaters')
    yield importlib.reload(module)
    sys.modules.pop('cheaters', None)


def test_an_agent_is_told_the_instruction_and_its_nouns_not_the_solution():
    task = get_task(f'{SPLIT}/000012')
    seen = task_view(RandomAgent(), task)
    assert isinstance(seen, PublicTask)
    assert (seen.task_id, seen.instruction, seen.object_nouns) == (task.task_id, task.instruction,
                                                                    tuple(task.object_nouns))
    assert not SOLUTION_FIELDS & {f.name for f in dataclasses.fields(seen)}
    assert not any(hasattr(seen, name) for name in SOLUTION_FIELDS)
    with pytest.raises(dataclasses.FrozenInstanceError):
        seen.instruction = 'something else'
    assert public_view(seen) is seen


def test_only_the_privileged_expert_is_given_the_whole_task():
    task = get_task(f'{SPLIT}/000012')
    assert task_view(ExpertAgent(), task) is task
    with pytest.raises(TypeError, match='needs the whole Task'):
        ExpertAgent().reset(task.public(), 0)


def test_the_blind_replayer_would_score_if_it_were_given_the_task(cheaters):
    # The check below means something: given the whole Task, the cheater finds the plan.
    agent = cheaters.BlindReplayer()
    agent.reset(get_task(f'{SPLIT}/000012'), 0)
    assert agent.plan and agent.act(None)[0] != 'Stop'


def test_an_observation_blind_agent_scores_nothing_through_the_evaluation(tmp_path, cheaters):
    report = run_eval(EvalConfig(split=SPLIT, agent='cheaters:BlindReplayer', questioner='all', limit=10,
                                 workers=2, out=tmp_path / 'blind.jsonl'), progress=False)
    assert cheaters.BlindReplayer.found == [False] * 10     # no plan in what it was told, nor in the questioner's
    overall = report.summary['overall']
    assert (overall['n'], overall['SR'], overall['PWSR']) == (10, 0.0, 0.0)
    assert not any(r.privileged for r in report.results)


def test_the_experts_results_are_marked_privileged(tmp_path):
    report = run_eval(EvalConfig(split=SPLIT, agent='expert', limit=2, workers=1, out=tmp_path / 'expert.jsonl'),
                      progress=False)
    assert all(r.privileged and r.success for r in report.results)
    summary = json.loads(report.run.summary_path.read_text())
    assert summary['privileged'] is True and summary['agent'] == 'expert'
    assert json.loads((tmp_path / 'expert.jsonl').read_text().splitlines()[0])['privileged'] is True


def test_a_users_class_cannot_make_itself_privileged(cheaters):
    with pytest.raises(ValueError, match='says it is privileged'):
        make_agent('cheaters:SelfProclaimedExpert')


def test_an_unanswered_reset_is_sent_again_but_a_step_never_is(monkeypatch):
    import dialfred_bringup.workers

    class Future:
        def done(self):
            return False

    class Client:
        def __init__(self):
            self.sent, self.removed = [], 0

        def call_async(self, request):
            self.sent.append(request)
            return Future()

        def remove_pending_request(self, future):
            self.removed += 1

    worker = dialfred_bringup.workers.SimWorker.__new__(dialfred_bringup.workers.SimWorker)
    cli = Client()
    monkeypatch.setattr(dialfred_bringup.workers, 'RESEND_AFTER_S', 0.0)
    for pending, resent in (('reset', True), ('question', True), ('step', False)):
        cli.sent.clear()
        worker._send(cli, pending, pending)
        assert worker.resend_if_lost() is resent
        assert cli.sent == [pending, pending] if resent else cli.sent == [pending]
