"""`launch eval --local` (dialfred_bringup/local.py) plays the episodes the ROS graph plays: for every kind of
questioner, a perturbed oracle, swapped answers, an answerer's words and the random agent, the results of both paths are equal field by field
(but for wall_s); and what cannot go without ROS is refused."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval

REPO = Path(__file__).resolve().parents[2]
CASES = {
    'random agent': dict(agent='random', resolution=64),
    'performer alone': dict(agent='et'),
    'performer + all QAs': dict(agent='et', questioner='all'),
    'performer + random QA, location withheld': dict(agent='et', questioner='random', perturb_type='location'),
    'performer + model confusion': dict(agent='et', questioner='confusion'),
    'performer + all QAs, answers swapped': dict(agent='et', questioner='all', answers='swapped'),
    'performer + all QAs, held-out wording': dict(agent='et', questioner='all',
                                                  answers='dialfred_oracle.wording:HeldOutWording'),
    # RL anytime with a chance at every step (the shipped rl-anytime asks about once in 25 episodes)
    'performer + RL anytime (learned)': dict(agent='et', questioner='rl-anytime-1'),
}


def comparable(results) -> list:
    return [dataclasses.replace(r, wall_s=0.0) for r in results]


# Every case with --all (slow). The fast tier plays a learned questioner's episode, every path of the loop
# (its chances, questions, answers), in process, locally and through the graph:
# tests/questioner/test_learned_questioner_node.py::test_the_same_episode_in_process_in_the_eval_and_through_the_graph.
@pytest.mark.slow
@pytest.mark.parametrize('case', list(CASES))
def test_local_episodes_equal_the_graphs(tmp_path, case):
    settings = {'split': 'valid_unseen', 'limit': 5, 'workers': 2, 'resolution': 64, 'seed': 3, **CASES[case]}
    n = settings['limit']
    graph = run_eval(EvalConfig(**settings, out=tmp_path / 'graph.jsonl'), progress=False)
    local = run_eval(EvalConfig(**settings, out=tmp_path / 'local.jsonl', local=True), progress=False)
    assert len(local.results) == n and local.ran == n
    assert comparable(local.results) == comparable(graph.results)
    if settings.get('questioner'):
        assert sum(r.questions for r in local.results) > 0
    assert local.to_json()['through'] == 'local processes (no ROS)'


def test_a_local_run_resumes_and_refuses_what_needs_ros(tmp_path):
    out = tmp_path / 'r.jsonl'
    first = run_eval(EvalConfig(split='valid_unseen', agent='random', limit=2, resolution=64, local=True, out=out),
                     progress=False)
    more = run_eval(EvalConfig(split='valid_unseen', agent='random', limit=4, resolution=64, local=True, out=out),
                    progress=False)
    assert more.ran == 2 and comparable(more.results[:2]) == comparable(first.results)
    for bad in (dict(record=tmp_path / 'bags'), dict(foxglove=8765)):     # --performer: test_front_door.py
        with pytest.raises(ValueError, match='--local'):
            EvalRun(EvalConfig(split='valid_unseen', agent=bad.pop('agent', 'random'), local=True, **bad))


def test_a_run_at_another_resolution_or_question_limit_is_refused_naming_the_difference(tmp_path):
    """Episodes played at 64 px are not resumed at 48 px (the lines themselves do not say): the results keep
    a record of the camera and the question limit, and a run that differs is refused before it plays."""
    from dialfred_sim.metrics import ResultsFileError
    out = tmp_path / 'r.jsonl'
    first = dict(split='valid_unseen', agent='random', limit=1, local=True, out=out, workers=1)
    assert run_eval(EvalConfig(**first, resolution=64), progress=False).ran == 1
    assert (tmp_path / 'r.run.json').exists()
    with pytest.raises(ResultsFileError, match='resolution 64, not 48'):
        run_eval(EvalConfig(**{**first, 'limit': 2}, resolution=48), progress=False)
    with pytest.raises(ResultsFileError, match='max_questions 20, not 5'):
        run_eval(EvalConfig(**{**first, 'limit': 2}, resolution=64, max_questions=5), progress=False)
    assert len(out.read_text().splitlines()) == 1                     # nothing was added
    assert run_eval(EvalConfig(**{**first, 'limit': 2}, resolution=64), progress=False).ran == 1
