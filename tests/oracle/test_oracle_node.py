"""The oracle as a ROS 2 node (integration): `dialfred_oracle node` beside `dialfred_sim node`, each
in its own process, answering /oracle/answer from the simulator's ground truth fetched over ROS."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import pytest

from dialfred_msgs.srv import GroundTruth, OracleAnswer, SimReset
from dialfred_bringup.graph import Graph, NodeProcess, oracle_node, sim_node

REPO = Path(__file__).resolve().parents[2]
TASK = 'valid_unseen/000003'
# A reset may be sent again (as the launcher does): a reply sent before DDS matched our reply path is lost.
RESEND_S = 5.0


@pytest.fixture(scope='module')
def graph():
    with Graph([sim_node(128, namespace='/o'), oracle_node(namespace='/o')]) as g:
        g.reset_cli = g.client(SimReset, '/o/sim/reset')
        g.truth_cli = g.client(GroundTruth, '/o/sim/ground_truth')
        g.ask_cli = g.client(OracleAnswer, '/o/oracle/answer')
        # The very first question comes before any reset: the simulator has nothing to tell.
        g.first = g.call(g.ask_cli, OracleAnswer.Request(question_type='location', object_noun='apple'))
        assert g.call(g.reset_cli, SimReset.Request(task_id=TASK, with_depth=False, with_segmentation=False),
                      retry_after=RESEND_S).ok
        yield g


def ask(g, qtype, noun, cli=None):
    return g.call(cli or g.ask_cli, OracleAnswer.Request(question_type=qtype, object_noun=noun))


def task_noun():
    from dialfred_sim.tasks import get_task
    return get_task(TASK).object_nouns[0]


def test_a_question_before_any_episode_is_invalid_with_a_reason(graph):
    assert not graph.first.valid and 'reset' in graph.first.reason


def test_each_question_type_is_answered_from_the_ground_truth(graph):
    noun = task_noun()
    truth = graph.call(graph.truth_cli, GroundTruth.Request())
    assert truth.ok and truth.has_task and truth.task.task_id == TASK
    target = dict(zip(truth.task_nouns, truth.task_object_ids))[noun]
    fact = next(f for f in truth.objects if f.object_id == target)
    loc = ask(graph, 'location', noun)
    assert loc.valid and noun in loc.answer and not loc.reason
    if fact.held:
        assert 'holding' in loc.answer
    elif fact.parent_noun:
        assert f'{fact.preposition} the {fact.parent_noun}' in loc.answer
    app = ask(graph, 'appearance', noun)
    assert app.valid and fact.material in app.answer
    direction = ask(graph, 'direction', '')
    assert direction.valid and direction.answer.startswith('You')


def test_an_answer_names_its_task_and_after_a_failed_reset_a_client_playing_another_refuses_it(graph):
    """The oracle answers from whatever the simulator holds. A reset that fails changes nothing there (the
    task before it stays), so each answer says which task it is about, and a client playing another task
    takes it as invalid, both tasks named (messages.qa_from_answer, as the evaluation and the performer do)."""
    from dialfred_sim.messages import qa_from_answer
    from dialfred_sim.protocol import Question
    assert graph.first.task_id == ''                               # before any reset: about no task
    reply = ask(graph, 'direction', '')
    assert reply.valid and reply.task_id == TASK
    bad = graph.call(graph.reset_cli, SimReset.Request(task_id='valid_unseen/999999'), retry_after=RESEND_S)
    assert not bad.ok
    after = ask(graph, 'direction', '')
    assert after.valid and after.task_id == TASK and after.answer == reply.answer
    assert qa_from_answer(Question('direction'), after, TASK).valid
    qa = qa_from_answer(Question('direction'), after, 'valid_unseen/999999')
    assert not qa.valid and qa.answer == '' and f"about '{TASK}', not 'valid_unseen/999999'" in qa.reason


def test_the_same_question_gets_the_same_answer(graph):
    noun = task_noun()
    assert ask(graph, 'appearance', noun).answer == ask(graph, 'appearance', noun).answer


@pytest.mark.parametrize('qtype, noun, why', [
    ('colour', 'apple', 'question type'),
    ('location', '', 'noun'),
    ('location', 'x' * 1_000_000, 'long'),
    ('location', 'pomme de terre \u00e9\u00e8 \u2603', ''),
    ('location', 'unicorn', 'no unicorn'),
])
def test_a_bad_question_is_invalid_and_the_node_serves_on(graph, qtype, noun, why):
    reply = ask(graph, qtype, noun)
    assert not reply.valid and reply.answer == '' and reply.reason
    assert why.lower() in reply.reason.lower()
    graph.check()
    assert ask(graph, 'location', task_noun()).valid


@pytest.mark.parametrize('qtype', ['Location', 'LOCATION', ' location', 'location ', 'Loc', 'APPEARANCE',
                                   ' Direction '])
def test_a_question_type_in_any_case_or_spacing_is_answered_through_the_node(graph, qtype):
    reply = ask(graph, qtype, task_noun())
    assert reply.valid and reply.answer and not reply.reason, reply.reason
    from dialfred_oracle.answers import parse_question_type
    assert reply.answer == ask(graph, parse_question_type(qtype), task_noun()).answer


def test_a_flood_of_200_concurrent_questions_gets_200_replies(graph):
    import time
    noun = task_noun()
    kinds = [('location', noun), ('appearance', noun), ('direction', ''), ('location', 'unicorn'), ('colour', noun)]
    futures = [graph.ask_cli.call_async(OracleAnswer.Request(question_type=q, object_noun=n))
               for q, n in (kinds[k % len(kinds)] for k in range(200))]
    deadline = time.monotonic() + 120
    while not all(f.done() for f in futures) and time.monotonic() < deadline:
        graph.executor.spin_once(timeout_sec=0.05)
    replies = [f.result() for f in futures if f.done()]
    assert len(replies) == 200
    for k, r in enumerate(replies):     # each one valid with an answer, or invalid with a reason
        assert (r.valid and r.answer and not r.reason) or (not r.valid and r.reason and not r.answer), (k, r)
        assert 'internal error' not in r.reason
    assert [r.valid for r in replies] == [k % len(kinds) < 3 for k in range(200)]
    graph.check()


def test_the_simulator_says_unchanged_to_a_caller_holding_the_current_state(graph):
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import SimStep
    full = graph.call(graph.truth_cli, GroundTruth.Request())
    assert full.ok and not full.unchanged and full.version > 0 and full.objects
    target = dict(zip(full.task_nouns, full.task_object_ids))[task_noun()]
    same = graph.call(graph.truth_cli, GroundTruth.Request(known_version=full.version, appearance_of=[target]))
    assert same.ok and same.unchanged and same.version == full.version
    assert not same.objects and not same.task_nouns and [a.object_id for a in same.appearances] == [target]
    step = graph.client(SimStep, '/o/sim/step')
    assert graph.call(step, SimStep.Request(action=Action(action='RotateLeft'), with_depth=False)).ok
    moved = graph.call(graph.truth_cli, GroundTruth.Request(known_version=full.version))
    assert moved.ok and not moved.unchanged and moved.version > full.version and moved.objects
    assert moved.agent.rotation_deg != full.agent.rotation_deg
    assert graph.call(graph.reset_cli, SimReset.Request(task_id=TASK, with_depth=False, with_segmentation=False),
                      retry_after=RESEND_S).ok


class _AskingAnotherSimulator(NodeProcess):
    """An oracle in its own namespace that asks the simulator of namespace `sim_namespace`."""

    def __init__(self, namespace: str, sim_namespace: str, **params):
        super().__init__('dialfred_oracle', params, namespace=namespace)
        self.sim_namespace = sim_namespace

    def command(self) -> list[str]:
        return super().command() + ['-r', f'sim/ground_truth:={self.sim_namespace}/sim/ground_truth']


@pytest.mark.slow   # fast: test_ground_truth's cache tests (the snapshot of the moment, close-ups equal fresh renders)
def test_answers_with_the_cache_are_byte_identical_to_fetching_the_world_every_time():
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import SimStep
    from dialfred_sim.tasks import get_task
    cached = oracle_node(namespace='/same')
    uncached = _AskingAnotherSimulator('/fresh', '/same', cache_ground_truth=False)
    with Graph([sim_node(128, namespace='/same'), cached, uncached]) as g:
        reset_cli, step_cli = g.client(SimReset, '/same/sim/reset'), g.client(SimStep, '/same/sim/step')
        new, old = g.client(OracleAnswer, '/same/oracle/answer'), g.client(OracleAnswer, '/fresh/oracle/answer')
        compared = 0
        for task_id in (TASK, 'valid_unseen/000010', 'valid_unseen/000020', 'valid_unseen/000072',
                        'valid_unseen/000131', 'valid_unseen/000191'):     # the last three make or move slices
            task = get_task(task_id)
            assert g.call(reset_cli, SimReset.Request(task_id=task_id, with_depth=False), retry_after=RESEND_S).ok
            nouns = list(task.object_nouns)
            questions = [(q, n) for n in nouns for q in ('location', 'appearance')]
            questions += [('direction', ''), ('location', nouns[0] + 's'), ('appearance', f'the {nouns[-1]}'),
                          ('location', 'unicorn'), ('location', 'tv'), ('appearance', 'counter'),
                          ('Location', f'sliced {nouns[-1]}'), ('location', 'floor lamp')]
            for a in [None] + list(task.expert_actions):       # every state along the expert's path
                if a is not None:
                    g.call(step_cli, SimStep.Request(action=Action(action=a.action, x=a.x, y=a.y), with_depth=False))
                for qtype, noun in questions + questions[:3]:     # some asked twice in the same state
                    mine, theirs = ask(g, qtype, noun, new), ask(g, qtype, noun, old)
                    assert (mine.valid, mine.answer, mine.reason) == (theirs.valid, theirs.answer, theirs.reason), \
                        (task_id, a, qtype, noun)
                    compared += 1
        assert compared >= 200


def test_without_a_simulator_the_oracle_says_so():
    with Graph([oracle_node(namespace='/lonely', sim_timeout=1.0)]) as g:
        cli = g.client(OracleAnswer, '/lonely/oracle/answer')
        reply = g.call(cli, OracleAnswer.Request(question_type='location', object_noun='apple'))
        assert not reply.valid and 'simulator' in reply.reason


@pytest.mark.slow   # fast: test_answers (the perturbation withholds one type at the given rate, deterministically)
def test_the_perturbation_withholds_about_half_of_one_type_reproducibly():
    from dialfred_msgs.msg import Action
    from dialfred_msgs.srv import SimStep
    from dialfred_sim.tasks import get_task

    def run():
        """The location and appearance of the task's object, asked in 48 situations: 4 tasks, 12 poses each."""
        loc, app, again = [], [], []
        with Graph([sim_node(64, namespace='/p'),
                    oracle_node(namespace='/p', perturb_type='location', perturb_probability=0.5, seed=3)]) as g:
            reset_cli, step_cli = g.client(SimReset, '/p/sim/reset'), g.client(SimStep, '/p/sim/step')
            cli = g.client(OracleAnswer, '/p/oracle/answer')
            for task_id in (TASK, 'valid_unseen/000010', 'valid_unseen/000020', 'valid_unseen/000030'):
                assert g.call(reset_cli, SimReset.Request(task_id=task_id, with_depth=False), retry_after=RESEND_S).ok
                noun = get_task(task_id).object_nouns[0]
                for k in range(12):
                    action = 'RotateLeft' if k % 4 else 'LookUp' if k % 8 else 'LookDown'
                    assert g.call(step_cli, SimStep.Request(action=Action(action=action), with_depth=False)).ok
                    loc.append(ask(g, 'location', noun, cli).answer)
                    again.append(ask(g, 'location', noun, cli).answer)
                    app.append(ask(g, 'appearance', noun, cli).answer)
        return loc, app, again
    loc, app, again = run()
    withheld = sum(a == "I don't know." for a in loc) / len(loc)
    assert 0.25 < withheld < 0.75
    assert again == loc                                      # asking again in the same place does not help
    assert not any(a == "I don't know." for a in app)       # other types are untouched
    assert run()[0] == loc                                    # same seed, same answers withheld


def test_the_human_mode_asks_a_person_on_standard_input(tmp_path):
    log = tmp_path / 'dialogue.jsonl'
    person = NodeProcess('dialfred_oracle', {'human': True, 'log_file': str(log)}, namespace='/h',
                         stdin=subprocess.PIPE)
    with Graph([sim_node(128, namespace='/h'), person]) as g:
        assert g.call(g.client(SimReset, '/h/sim/reset'), SimReset.Request(task_id=TASK), retry_after=RESEND_S).ok
        cli = g.client(OracleAnswer, '/h/oracle/answer')
        person.proc.stdin.write('It is next to the toaster.\n')
        person.proc.stdin.flush()
        reply = ask(g, 'location', task_noun(), cli)
        assert reply.valid and reply.answer == 'It is next to the toaster.', (reply, list(person.tail))
        reply = ask(g, 'location', task_noun(), cli)     # asked again in the same state: the person's answer, no prompt
        assert reply.answer == 'It is next to the toaster.'
        person.proc.stdin.write('\n')                    # an empty line accepts the simulator's answer
        person.proc.stdin.flush()
        reply = ask(g, 'appearance', task_noun(), cli)
        assert reply.valid and task_noun() in reply.answer, (reply, list(person.tail))
        person.proc.stdin.close()                         # nobody there any more
        reply = ask(g, 'direction', '', cli)
        assert not reply.valid and 'no person' in reply.reason, (reply, list(person.tail))
        deadline = time.monotonic() + 5                   # the node's output is read by a thread: give it a moment
        while not any('Where is' in line for line in person.tail) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert any('Where is' in line for line in person.tail), list(person.tail)   # the question was put to the person
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r['answer'] for r in rows[:1]] == ['It is next to the toaster.'] and all(r['human'] for r in rows)
