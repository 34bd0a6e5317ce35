"""The swap control (`--answers swapped`, dialfred_oracle/swap.py): every answer is the oracle's answer to the
same question in another task of the split, fixed by the split; invalid questions stay invalid; an
evaluation with it records what was said and names its results apart (no ROS; the graph's oracle node
plays the same episodes in tests/bringup/test_eval_local.py)."""

from __future__ import annotations

import pytest

from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_oracle.answers import answer as oracle_answer
from dialfred_oracle.in_process import answer_now
from dialfred_oracle.swap import AnswerSwap
from dialfred_sim.agents import task_nouns
from dialfred_sim.tasks import load_split

SPLIT = 'valid_unseen'


@pytest.fixture(scope='module')
def tasks():
    return load_split(SPLIT)


@pytest.fixture(scope='module')
def swap(tasks):
    s = AnswerSwap(tasks, resolution=64)
    yield s
    s.close()


def test_each_task_is_paired_with_one_of_another_episode_across_the_split(tasks, swap):
    n = len(tasks)
    for k in (0, 1, 2, n // 2, n - 1):
        own, partner = tasks[k], swap.partner(tasks[k].task_id)
        assert partner.episode.episode_id != own.episode.episode_id and task_nouns(partner)
        assert tasks.index(partner) >= (k + n // 2) % n or tasks.index(partner) < k    # at or after i + n/2, wrapping
    # the pairing is the split's: a swap over the same tasks pairs the same, whatever was asked before
    again = AnswerSwap(tasks, resolution=64)
    assert [again.partner(t.task_id).task_id for t in tasks[:20]] == [swap.partner(t.task_id).task_id for t in tasks[:20]]
    with pytest.raises(KeyError):
        swap.partner('valid_unseen/999999')


def test_a_swapped_answer_is_the_partners_answer_to_the_same_question_in_its_start_state(env, tasks, swap):
    differ = 0
    for task in tasks[:6]:
        env.reset(options={'task': task})
        own_nouns = task_nouns(task)
        partner = swap.partner(task.task_id)
        for qtype, noun in [('location', n) for n in own_nouns] + [('appearance', own_nouns[-1]), ('direction', '')]:
            mine = answer_now(env, qtype, noun)
            assert mine.valid
            swapped = swap.apply(mine, task.task_id, noun)
            # asked again, independently, of the partner's start state
            place = own_nouns.index(noun) if noun else 0
            theirs_noun = '' if qtype == 'direction' else task_nouns(partner)[min(place, len(task_nouns(partner)) - 1)]
            env.reset(options={'task': partner})
            theirs = answer_now(env, qtype, theirs_noun)
            env.reset(options={'task': task})
            assert swapped.valid and swapped.question_type == mine.question_type
            assert swapped.text == (theirs.text if theirs.valid else "I don't know.")
            differ += swapped.text != mine.text
    assert differ >= 6      # other rooms, other objects: most answers change


def test_an_invalid_question_stays_invalid(env, tasks, swap):
    env.reset(options={'task': tasks[0]})
    bad = answer_now(env, 'location', 'unicorn')
    assert not bad.valid
    assert swap.apply(bad, tasks[0].task_id, 'unicorn') == bad
    assert not oracle_answer(None, 'smell').valid


def test_an_evaluation_with_swapped_answers_hears_them_and_is_named_apart(tmp_path, tasks):
    with pytest.raises(ValueError, match='swapped needs a questioner'):
        EvalRun(EvalConfig(split=SPLIT, agent='random', answers='swapped', out=tmp_path / 'x.jsonl'))
    with pytest.raises(ValueError, match='swapped needs a questioner'):
        EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='all', answers='swapped', perturb_type='location',
                           out=tmp_path / 'x.jsonl'))
    run = EvalRun(EvalConfig(split=SPLIT, agent='random', questioner='all', answers='swapped', limit=2, workers=1,
                             resolution=64, local=True))
    assert run.results_path.name.endswith('_swapped.jsonl') and run.oracle == 'swapped'
    report = run_eval(EvalConfig(split=SPLIT, agent='random', questioner='all', answers='swapped', limit=2,
                                 workers=1, resolution=64, local=True, out=tmp_path / 'run.jsonl'), progress=False)
    swap = AnswerSwap(tasks, resolution=64)
    from dialfred_sim.env import DialfredEnv
    env = DialfredEnv(resolution=64)
    try:
        for result, task in zip(report.results, tasks[:2]):
            assert result.oracle == 'swapped' and result.questions == len(result.dialogue) > 0
            env.reset(options={'task': task})
            for entry in result.dialogue:
                said = swap.apply(answer_now(env, entry['type'], entry['noun']), task.task_id, entry['noun'])
                assert entry['answer'] == said.text
    finally:
        env.close()
        swap.close()
