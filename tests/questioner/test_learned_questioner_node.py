"""The learned questioner by name, in the questioner node, and in the evaluation (in process and through
the graph).

Claims: `make_questioner` makes the learned questioner of a shipped name (its checkpoint in the package's
checkpoints folder) or of learned:PATH, greedy, with the checkpoint's timing; a missing shipped checkpoint
is named with the command that makes it. The same task and episode seed give the same episode (steps,
every question at the same step, every answer's validity, success) played by `rollout.play_rollout` in process,
by the in-process evaluation (the agent in the eval process, sim and oracle nodes), and through the graph
(performer, questioner, oracle and sim nodes as separate processes), also with a perturbed oracle. The
questioner node publishes each question it decides on, refuses a request it cannot serve (a confusion
timing without the gap) and keeps serving; bad parameters stop it with one line.

The questioner checkpoint is made here without any training: a seeded untrained model, its 'direction'
type token pushed up a little so that it asks a mix of (valid) direction and (invalid) appearance
questions at the chances of its anytime timing (gap 2).
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import pytest
import torch

from dialfred_performer.model import SHIPPED_CHECKPOINT
from dialfred_questioner import policy
from dialfred_questioner.baselines import AllQuestioner, ModelConfusionQuestioner, RandomQuestioner
from dialfred_questioner.policy import LearnedQuestioner, retimed
from dialfred_questioner.questioners import make_questioner
from dialfred_questioner.rollout import Timing

import dialfred_bringup.workers
from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_bringup.workers import worker_nodes
from dialfred_bringup.graph import Graph, NodeProcess
from dialfred_sim.protocol import Observation

REPO = Path(__file__).resolve().parents[2]
SPLIT, TASK_INDEX = 'valid_seen', 78       # 15 steps, direction and appearance questions (so when withheld)
TIMING = {'mode': 'anytime', 'gap': 2, 'epsilon': 0.5}
CONFUSION = {'mode': 'confusion', 'gap': 5, 'epsilon': 0.8}     # on this task: questions before some of its actions, not all
DIRECTION_BIAS = 0.3


def questioner_checkpoint(path: Path, timing: dict = TIMING) -> Path:
    """An untrained questioner with the shipped performer's vocabulary and visual encoder, saved as
    pre-training saves one; its 'direction' type token pushed up by DIRECTION_BIAS."""
    from dialfred_performer.model import load_checkpoint
    from dialfred_questioner.data import catalog_nouns
    from dialfred_questioner.model import Questioner, QuestionerConfig, type_tokens
    from dialfred_questioner.pretrain import PretrainConfig, save
    performer, vocab, info = load_checkpoint(SHIPPED_CHECKPOINT)
    torch.manual_seed(0)
    model = Questioner(QuestionerConfig(), len(vocab), catalog_nouns())
    with torch.no_grad():     # output index 0 is <start>, then the type tokens
        model.output.bias[1 + type_tokens().index('direction')] += DIRECTION_BIAS
    save(path, model, vocab, performer.visual.state_dict(), dict(info, path=str(SHIPPED_CHECKPOINT)),
         PretrainConfig(), commit='test', timing=timing)
    return path


@pytest.fixture(scope='module')
def checkpoint(tmp_path_factory) -> Path:
    return questioner_checkpoint(tmp_path_factory.mktemp('questioner') / 'q.pt')


@pytest.fixture(scope='module')
def mc_checkpoint(tmp_path_factory) -> Path:
    return questioner_checkpoint(tmp_path_factory.mktemp('questioner_mc') / 'mc.pt', CONFUSION)


# ---------------------------------------------------------------------------------------------- by name (no ROS)

def test_every_kind_of_name_makes_its_questioner(checkpoint, tmp_path, monkeypatch):
    assert isinstance(make_questioner('random'), RandomQuestioner)
    assert isinstance(make_questioner('all'), AllQuestioner)
    assert isinstance(make_questioner('confusion'), ModelConfusionQuestioner)
    learned = make_questioner(f'learned:{checkpoint}')
    assert isinstance(learned, LearnedQuestioner) and learned.greedy
    assert learned.timing == Timing(**TIMING) and not learned.needs_gap
    monkeypatch.setattr(policy, 'CHECKPOINTS', tmp_path)
    for name in policy.SHIPPED_LEARNED:
        shutil.copy(checkpoint, tmp_path / (name.replace('-', '_') + '.pt'))
        shipped = make_questioner(name)
        assert isinstance(shipped, LearnedQuestioner) and shipped.timing == Timing(**TIMING)
    assert policy.learned_checkpoint('rl-anytime-withhold-location') == tmp_path / 'rl_anytime_withhold_location.pt'
    assert policy.learned_checkpoint('random') is None


def test_the_shipped_names_are_the_checkpoints_files_and_ship_with_the_package():
    assert policy.CHECKPOINTS == Path(policy.__file__).resolve().parent / 'checkpoints'
    assert {policy.learned_checkpoint(n).name for n in policy.SHIPPED_LEARNED} == {
        'pretrained.pt', 'rl_begin.pt', 'rl_anytime.pt', 'rl_anytime_1.pt', 'rl_anytime_10.pt', 'rl_mc.pt',
        'rl_anytime_withhold_location.pt', 'rl_anytime_withhold_appearance.pt', 'rl_anytime_withhold_direction.pt',
        'rl_anytime_no_dialogue.pt', 'map_rl_anytime.pt', 'rl_anytime_chained.pt', 'map_rl_anytime_chained.pt'}
    assert "package_data={package_name: ['checkpoints/*.pt']}" in (
        REPO / 'src' / 'dialfred_questioner' / 'setup.py').read_text()


def test_a_missing_or_bad_checkpoint_is_named_with_what_makes_it(tmp_path, monkeypatch):
    monkeypatch.setattr(policy, 'CHECKPOINTS', tmp_path)
    with pytest.raises(ValueError, match=r'rl_anytime\.pt is not there: it is made by `python -m '
                                         r'dialfred_questioner\.finetune`'):
        make_questioner('rl-anytime')
    with pytest.raises(ValueError, match=r'pretrained\.pt is not there: it is made by `python -m '
                                         r'dialfred_questioner\.pretrain`'):
        make_questioner('pretrained')
    with pytest.raises(ValueError, match='no questioner checkpoint at .*nowhere.pt'):
        make_questioner(f'learned:{tmp_path / "nowhere.pt"}')
    with pytest.raises(ValueError, match='needs a checkpoint file'):
        make_questioner('learned:')
    (tmp_path / 'bad.pt').write_bytes(b'not a checkpoint')
    with pytest.raises(ValueError, match='is not a questioner checkpoint'):
        make_questioner(f'learned:{tmp_path / "bad.pt"}')
    with pytest.raises(ValueError, match=r"unknown questioner 'rl-sometimes'( \(did you mean [\w-]+\?\))?; known: "
                                         r"random, all, confusion, every\[-N\]:TYPES, pretrained, rl-begin"):
        make_questioner('rl-sometimes')


def test_retimed_changes_only_the_fields_given():
    t = Timing('anytime', 5, 0.5)
    assert retimed(t) == t
    assert retimed(t, 'confusion', epsilon=0.2) == Timing('confusion', 5, 0.2)
    assert retimed(t, gap=10) == Timing('anytime', 10, 0.5)
    for bad in (dict(mode='sometimes'), dict(gap=-1), dict(epsilon=2.0)):
        with pytest.raises(ValueError):
            retimed(t, **bad)


def test_results_of_a_checkpoint_file_are_named_by_its_stem_and_content(checkpoint, tmp_path, monkeypatch):
    import hashlib
    run = EvalRun(EvalConfig(split=SPLIT, questioner=f'learned:{checkpoint}'))
    digest = hashlib.sha256(checkpoint.read_bytes()).hexdigest()[:8]
    assert run.agent_name == f'expert+learned-q-{digest}'
    assert run.results_path.name == f'valid_seen_expert+learned-q-{digest}.jsonl'
    monkeypatch.setattr(policy, 'CHECKPOINTS', tmp_path)
    shutil.copy(checkpoint, tmp_path / 'rl_anytime.pt')
    assert EvalRun(EvalConfig(split=SPLIT, questioner='rl-anytime')).results_path.name == \
        f'valid_seen_expert+rl-anytime-{digest}.jsonl'
    # The node path hands the questioner node an absolute path (the node runs with its own working folder).
    relative = EvalConfig(split=SPLIT, agent='et', performer='et', questioner=f'learned:{checkpoint.name}')
    questioner = next(n for n in worker_nodes(EvalRun(relative, check=False), '/w0')
                      if n.package == 'dialfred_questioner')
    assert questioner.parameters['questioner'] == f'learned:{Path(checkpoint.name).resolve()}'


def test_the_eval_command_takes_a_shipped_name_and_refuses_a_missing_checkpoint_before_any_node(
        checkpoint, tmp_path, monkeypatch, capsys):
    import argparse

    from dialfred_bringup.evaluation import add_eval_parser, eval_config, run_eval_command
    parser = argparse.ArgumentParser()
    add_eval_parser(parser.add_subparsers())
    monkeypatch.setattr(policy, 'CHECKPOINTS', tmp_path)
    args = parser.parse_args(['eval', '--split', SPLIT, '--questioner', 'rl-anytime',
                              '--out', str(tmp_path / 'r.jsonl')])
    assert eval_config(args).questioner == 'rl-anytime'
    assert run_eval_command(args) == 2
    said = capsys.readouterr().err
    assert 'rl_anytime.pt is not there: it is made by `python -m dialfred_questioner.finetune`' in said
    assert not (tmp_path / 'r.jsonl').exists()
    shutil.copy(checkpoint, tmp_path / 'rl_anytime.pt')
    agent = EvalRun(eval_config(args)).make_agent()
    assert isinstance(agent.questioner, LearnedQuestioner) and agent.questioner.timing == Timing(**TIMING)


# ---------------------------------------------------------------------------------------------- one episode, three ways

def questions_of(episode) -> list:
    """(step, type, noun, valid, answer) of each QA of a rollout.Episode."""
    return [(t, qa.question.question_type, qa.question.object_noun, qa.valid, qa.answer)
            for qa, t in zip(episode.dialogue, episode.asked_at)]


def in_process_episode(checkpoint, perturbation=None):
    """The episode of rollout.play_rollout (as the RL fine-tuning plays it) of the eval's task and seed."""
    from dialfred_performer.agent import PerformerAgent
    from dialfred_questioner.rollout import play_rollout
    from dialfred_sim.protocol import episode_seed
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks import load_split
    questioner = LearnedQuestioner.from_checkpoint(checkpoint, greedy=True)
    env = DialfredEnv(resolution=128)
    try:
        task = load_split(SPLIT)[TASK_INDEX]
        return play_rollout(env, PerformerAgent.from_checkpoint(SHIPPED_CHECKPOINT), questioner, task.task_id,
                    episode_seed(0, TASK_INDEX), questioner.timing, perturbation=perturbation)
    finally:
        env.close()


def eval_episode(checkpoint, tmp_path, monkeypatch, graph: bool, **kw):
    """(result, [(step, type, noun, valid, answer) of each QA]) of the eval's first task: in process (the
    questioner in this process: its own record of the dialogue) or through the performer node (the
    steps from the goal's feedback, the QAs from dialogue/qa; the questions the questioner node
    published on questioner/question must be the same)."""
    from dialfred_msgs.msg import QAPair
    config = EvalConfig(split=SPLIT, agent='et', questioner=f'learned:{checkpoint}', limit=TASK_INDEX + 1,
                        shard=(TASK_INDEX, TASK_INDEX + 1),            # that one task
                        resolution=128, workers=1,   # the rollout's DialfredEnv(resolution=128)
                        out=tmp_path / f'{"graph" if graph else "local"}.jsonl',
                        performer='et' if graph else '', **kw)
    if not graph:
        agents = []
        make_agent = EvalRun.make_agent
        monkeypatch.setattr(EvalRun, 'make_agent', lambda self: agents.append(make_agent(self)) or agents[-1])
        report = run_eval(config, progress=False)
        dialogue = agents[-1].questioner.dialogue
        return report.results[-1], [(a.step, a.qa.question.question_type, a.qa.question.object_noun, a.qa.valid,
                                     a.qa.answer) for a in dialogue]
    counts, qas, decided = [], [], []
    worker = dialfred_bringup.workers.PerformerWorker.__init__

    def init(self, g, namespace, run, on_feedback=None):
        subs = [g.client_node.create_subscription(QAPair, f'{namespace}/dialogue/qa', qas.append, 100),
                g.client_node.create_subscription(QAPair, f'{namespace}/questioner/question', decided.append, 100)]
        # the topics are volatile: wait until both publishers are matched, or a loaded machine loses the first
        deadline = time.monotonic() + 60
        while any(s.get_publisher_count() == 0 for s in subs) and time.monotonic() < deadline:
            g.executor.spin_once(timeout_sec=0.1)
        worker(self, g, namespace, run, on_feedback=lambda task, fb: counts.append(fb.questions))

    monkeypatch.setattr(dialfred_bringup.workers.PerformerWorker, '__init__', init)
    report = run_eval(config, progress=False, traces={})       # traces: wait for the last messages
    result = report.results[-1]
    assert result.end_reason != 'error', result.error
    assert len(counts) == result.steps and counts[-1] == result.questions == len(qas)
    asked_at = [next(k for k, n in enumerate(counts) if n > j) for j in range(len(qas))]
    assert [(q.question_type, q.object_noun) for q in decided] == [(q.question_type, q.object_noun) for q in qas]
    return result, [(t, q.question_type, q.object_noun, q.valid, q.answer) for t, q in zip(asked_at, qas)]


@pytest.mark.parametrize('timing, perturb', [('anytime', ''), pytest.param('anytime', 'direction', marks=pytest.mark.slow),
                                             pytest.param('confusion', '', marks=pytest.mark.slow)],
                         ids=['anytime', 'anytime, withholding oracle', 'confusion'])
def test_the_same_episode_in_process_in_the_eval_and_through_the_graph(checkpoint, mc_checkpoint, tmp_path,
                                                                       monkeypatch, timing, perturb):
    from dialfred_oracle.answers import WITHHELD, Perturbation
    torch.set_num_threads(1)          # as the nodes (torch_threads=1): the same arithmetic
    checkpoint = mc_checkpoint if timing == 'confusion' else checkpoint
    kw = dict(perturb_type=perturb, perturb_probability=0.5) if perturb else {}
    played = in_process_episode(checkpoint, Perturbation(perturb, 0.5, seed=0) if perturb else None)
    expected = (played.steps, questions_of(played), played.success)
    asked = questions_of(played)
    steps = [t for t, *_ in asked]
    assert len(asked) >= 3 and {q[1] for q in asked} >= {'direction', 'appearance'}
    assert steps == sorted(set(steps))                                  # at most one question per step
    if timing == 'anytime':
        assert all(t % 2 == 0 for t in steps)                           # at the chances of gap 2
    else:
        assert len(steps) < played.steps                                # not before every action
    assert any(q[-1] == WITHHELD for q in asked) == bool(perturb)
    local, local_qas = eval_episode(checkpoint, tmp_path, monkeypatch, graph=False, **kw)
    assert (local.steps, local_qas, local.success) == expected
    assert (local.questions, local.invalid_questions) == (played.questions, played.invalid_questions)
    through, graph_qas = eval_episode(checkpoint, tmp_path, monkeypatch, graph=True, **kw)
    assert (through.steps, graph_qas, through.success) == expected
    assert (through.questions, through.invalid_questions, through.agent) == (
        local.questions, local.invalid_questions, local.agent)


# ---------------------------------------------------------------------------------------------- the node

def test_the_node_serves_a_learned_questioner_refuses_a_request_without_a_gap_and_keeps_serving(checkpoint):
    from dialfred_msgs.msg import QAPair, TaskDescription
    from dialfred_msgs.srv import QuestionerAsk
    from sensor_msgs.msg import Image

    from dialfred_sim.env import DialfredEnv
    env = DialfredEnv(resolution=128)
    obs, _ = env.reset(seed=0, options={'task_id': f'{SPLIT}/000000'})
    env.close()
    frame = obs['rgb']
    rgb = Image(height=frame.shape[0], width=frame.shape[1], encoding='rgb8', step=3 * frame.shape[1],
                data=frame.tobytes())
    task = TaskDescription(task_id=f'{SPLIT}/000000', instruction='Put the apple in the fridge.',
                           object_nouns=['apple', 'fridge'])
    nodes = [NodeProcess('dialfred_questioner', {'questioner': 'learned', 'checkpoint': str(checkpoint),
                                                 'timing': 'confusion', 'epsilon': 0.3}, namespace='/lc'),
             NodeProcess('dialfred_questioner', {'questioner': f'learned:{checkpoint}'}, namespace='/la')]
    with Graph(nodes) as graph:
        published = []
        graph.client_node.create_subscription(QAPair, '/la/questioner/question', published.append, 100)
        confusion = graph.client(QuestionerAsk, '/lc/questioner/ask')
        reply = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=0, rgb=rgb))
        assert not reply.ok and 'confusion_gap' in reply.error
        sure = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=0, rgb=rgb, confusion_gap=0.9))
        assert (sure.ok, sure.ask) == (True, False)          # no chance: the performer is sure (0.9 >= 0.3)
        unsure = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=1, rgb=rgb, confusion_gap=0.1))
        assert unsure.ok, unsure.error
        no_frame = graph.call(confusion, QuestionerAsk.Request(task=task, seed=1, step=2, confusion_gap=0.1))
        assert not no_frame.ok and 'rgb8' in no_frame.error

        anytime = graph.client(QuestionerAsk, '/la/questioner/ask')
        # Refused requests change nothing: the good request at step 0 still has its chance to ask.
        cut = Image(height=rgb.height, width=rgb.width, encoding='rgb8', step=rgb.step, data=frame.tobytes()[:-7])
        for bad, said in [(QuestionerAsk.Request(task=task, seed=1, step=0, rgb=cut), 'rgb: a 128x128 rgb8 image has'),
                          (QuestionerAsk.Request(task=task, seed=-5, step=0, rgb=rgb), 'seed must be a non-negative'),
                          (QuestionerAsk.Request(task=task, seed=1, step=0, rgb=rgb, confusion_gap=float('nan')),
                           'confusion_gap must be a number')]:
            reply = graph.call(anytime, bad)
            assert not reply.ok and said in reply.error and 'internal error' not in reply.error, reply.error
        local = LearnedQuestioner.from_checkpoint(checkpoint)
        local.reset(task, 1)
        replies = []
        for step in range(4):
            reply = graph.call(anytime, QuestionerAsk.Request(task=task, seed=1, step=step, rgb=rgb))
            assert reply.ok, reply.error
            replies.append((reply.ask, reply.question_type, reply.object_noun))
            q = local.ask(Observation(rgb=frame), step)
            assert replies[-1] == ((True, q.question_type, q.object_noun) if q else (False, '', ''))
        assert [r[0] for r in replies] == [True, False, True, False]    # chances at 0 and 2 (gap 2)
        deadline = time.monotonic() + 5
        while len(published) < 2 and time.monotonic() < deadline:
            graph.spin_until_any([], 0.1)
        assert [(m.question_type, m.object_noun) for m in published] == [r[1:] for r in replies if r[0]]
        graph.check()


@pytest.mark.parametrize('params, said', [
    ({'questioner': 'rl-mc'}, 'it is made by `python -m dialfred_questioner.finetune`'),
    ({'questioner': 'learned'}, 'needs the `checkpoint` parameter'),
    ({'questioner': 'all', 'gap': 3}, "not for the 'all' questioner"),
])
def test_bad_parameters_stop_the_node_with_one_line(params, said):
    if params['questioner'] == 'rl-mc' and policy.learned_checkpoint('rl-mc').exists():
        pytest.skip('rl_mc.pt is shipped')
    node = NodeProcess('dialfred_questioner', params)
    node.start()
    assert node.proc.wait(60) == 1
    time.sleep(0.2)
    assert any(said in line for line in node.tail), list(node.tail)
