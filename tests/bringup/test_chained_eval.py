"""`launch eval --protocol chained` (DialFRED's challenge test): the expert does every task of every episode,
an agent that stops at once does none, a run cut off inside an episode resumes by playing that episode again,
protocols never mix in one results file, and the map performer carries its map from task to task."""

from __future__ import annotations

import dataclasses
import json

import pytest

from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_sim.metrics import ResultsFileError, load_results

STOP_AT_ONCE = '''
class StopAtOnce:
    name = 'stop-at-once'

    def __init__(self, resolution=128):
        pass

    def reset(self, task, seed):
        pass

    def act(self, observation):
        return ('Stop', -1, -1)
'''


def chained(tmp_path, name, **settings):
    return EvalConfig(**{'split': 'valid_unseen', 'local': True, 'workers': 2, 'protocol': 'chained',
                         'out': tmp_path / f'{name}.jsonl', **settings})


def comparable(results) -> list:
    return [dataclasses.replace(r, wall_s=0.0, code='') for r in results]


@pytest.mark.parametrize('split', ['valid_unseen', pytest.param('valid_seen', marks=pytest.mark.slow)])
def test_the_expert_does_every_task_of_every_chained_episode(tmp_path, split):
    report = run_eval(chained(tmp_path, split, split=split, agent='expert', limit=50), progress=False)
    expert_did_everything(report, 50)


def expert_did_everything(report, tasks: int) -> None:
    episodes = report.summary['episodes']
    assert len(report.results) == tasks and episodes['episodes'] >= tasks / 16
    assert report.summary['overall']['SR'] == 100.0 and report.summary['overall']['PWSR'] == 100.0
    assert episodes['all_succeeded'] == 100.0 and episodes['held_at_start'] == 0
    assert all(r.protocol == 'chained' and r.episode_id and r.end_reason == 'success' for r in report.results)
    assert json.loads(report.run.summary_path.read_text())['protocol'] == 'chained'


@pytest.mark.slow      # 4.5 min on 2 cores: every task of both validation splits, train's first 3,000, a sealed split
@pytest.mark.timeout(1200)   # train's 3,000 tasks: 4-5 min beside the rest of the slow tier
@pytest.mark.parametrize('split', ['valid_unseen', 'valid_seen', 'train', 'test_unseen'])
def test_the_expert_does_every_task_of_whole_splits_chained(tmp_path, split):
    settings = dict(split=split, agent='expert')
    if split == 'train':
        settings['limit'] = 3000
    if split == 'test_unseen':      # a sealed split of a seed of one's own, as docs/tasks.md draws one
        from dialfred_sim.tasks.splits import write_split
        path = tmp_path / 'sealed.jsonl.gz'
        write_split('test_unseen', path, size=300, split_seed=2024, progress=False, workers=2)
        settings = dict(agent='expert', tasks_file=path, split='valid_unseen')
    report = run_eval(chained(tmp_path, split, **settings), progress=False)
    expert_did_everything(report, settings.get('limit') or len(report.run.split_tasks()))


def test_an_agent_that_stops_at_once_scores_nothing(tmp_path, monkeypatch):
    (tmp_path / 'my_stop.py').write_text(STOP_AT_ONCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    report = run_eval(chained(tmp_path, 'stop', agent='my_stop:StopAtOnce', limit=40), progress=False)
    row = report.summary['overall']
    assert row['n'] == 40 and row['SR'] == 0.0 and row['PWSR'] == 0.0 and row['GC'] == 0.0
    assert report.summary['episodes']['all_succeeded'] == 0.0 and report.summary['episodes']['in_order'] == 0.0
    assert all(r.steps == 1 and r.end_reason == 'stop' for r in report.results)
    # "Close the fridge" when the agent never opened it: the goal holds already, and scores as not done
    held = [r for r in report.results if r.held_at_start]
    assert held and report.summary['episodes']['held_at_start'] == len(held)
    assert all(r.goal_conditions_total == 0 and not r.success for r in held)
    assert {r.task_type for r in held} <= {'Close', 'Turn off', 'Open & Pick & Close', 'Open & Put & Close',
                                           'Move & Close'}


def test_a_chained_run_cut_off_inside_an_episode_plays_it_again_and_writes_only_what_is_missing(tmp_path):
    whole = run_eval(chained(tmp_path, 'whole', agent='random', resolution=64, limit=14, seed=5), progress=False)
    out = tmp_path / 'cut.jsonl'
    cut = chained(tmp_path, 'cut', agent='random', resolution=64, limit=14, seed=5)
    run_eval(cut, progress=False)
    lines = out.read_text().splitlines()
    rows = load_results(out)
    first_episode = rows[0].episode_id
    keep = [ln for ln, r in zip(lines, rows) if r.episode_id != first_episode or r.task_id != max(
        x.task_id for x in rows if x.episode_id == first_episode)]
    assert len(keep) == len(lines) - 1
    out.write_text('\n'.join(keep) + '\n')                           # the episode's last task is missing
    again = run_eval(cut, progress=False)
    assert again.ran == 1 and len(out.read_text().splitlines()) == len(lines)
    by_id = {r.task_id: r for r in again.results}
    assert comparable(by_id[t] for t in sorted(by_id)) == comparable(sorted(whole.results, key=lambda r: r.task_id))


def test_protocols_never_mix_in_one_results_file(tmp_path):
    out = tmp_path / 'expert.jsonl'
    run_eval(EvalConfig(split='valid_unseen', agent='random', resolution=64, limit=2, local=True, workers=1, out=out),
             progress=False)
    with pytest.raises(ResultsFileError, match="'expert' protocol, not 'chained'"):
        run_eval(chained(tmp_path, 'expert', agent='random', resolution=64, limit=2), progress=False)
    assert EvalRun(chained(tmp_path, 'x', out=None), check=False).results_path.name == 'valid_unseen_expert_chained.jsonl'


def test_the_map_performer_carries_its_map_to_the_next_task_and_the_performer_starts_afresh(tmp_path):
    from dialfred_performer.mapper.agent import MapAgent
    from dialfred_sim.protocol import Continuing
    run = EvalRun(chained(tmp_path, 'map', agent='map', limit=1))
    agent = run.make_performer()
    assert isinstance(agent, MapAgent) and isinstance(agent, Continuing)
    assert not isinstance(EvalRun(chained(tmp_path, 'et', agent='et', limit=1)).make_performer(), Continuing)
    from dialfred_bringup.local import play_chain
    from dialfred_sim.chained import chain_episodes
    from dialfred_sim.env import DialfredEnv
    episode = next(e for e in chain_episodes(enumerate(run.split_tasks()[:12])) if len(e.tasks) >= 2)
    env = DialfredEnv(resolution=run.options.resolution)
    maps, plans = [], []
    try:
        for _, _, state in play_chain(run, env, agent, None, dataclasses.replace(episode, tasks=episode.tasks[:2])):
            maps.append(agent.map)
            plans.append(agent.reading)
            assert state.end_reason in ('success', 'stop', 'max_failures', 'max_steps')
    finally:
        env.close()
    assert maps[0] is maps[1] and plans[0] is not plans[1]
    assert len(maps[1].visited) >= 1


GRAPH_CASES = {
    'random agent, random QA': dict(agent='random', questioner='random', resolution=64, limit=56),
    'performer nodes (map performer), all QAs': dict(agent='map', performer='map', questioner='all', limit=56),
    'map performer, all QAs': dict(agent='map', questioner='all', limit=56),
    'performer, RL anytime at every step': dict(agent='et', questioner='rl-anytime-1', limit=56),
}


@pytest.mark.parametrize('case', [pytest.param(c, marks=[] if c.startswith('random') else pytest.mark.slow)
                                  for c in GRAPH_CASES])
def test_the_same_chained_episodes_locally_and_through_the_graph(tmp_path, case):
    """At least 10 episodes: the simulator node goes on from task to task (carry_on), the oracle node answers
    about the current task, and every field but wall_s is the local path's."""
    settings = GRAPH_CASES[case]
    graph = run_eval(chained(tmp_path, 'graph', local=False, **settings), progress=False)
    local = run_eval(chained(tmp_path, 'local', **{k: v for k, v in settings.items() if k != 'performer'}),
                     progress=False)
    assert graph.summary['episodes']['episodes'] >= 10
    assert comparable(graph.results) == comparable(local.results)
    assert sum(r.questions for r in local.results) > 0
    assert graph.to_json()['through'] == ('performer node' if settings.get('performer') else 'in-process agent')


@pytest.mark.slow   # three chained runs and a replay; merging's rules have fast tests in tests/bringup/test_shards.py
def test_the_shards_of_a_chained_run_take_whole_episodes_and_merge_into_a_file_score_replays(tmp_path):
    from dialfred_bringup.score import score
    from dialfred_bringup.shards import merge_shards, write_merged
    whole = run_eval(chained(tmp_path, 'whole', agent='random', resolution=64, limit=30, seed=2), progress=False)
    shards = [run_eval(chained(tmp_path, f'part_shard{k}of2', agent='random', resolution=64, limit=30, seed=2,
                               shard=(k, 2)), progress=False) for k in range(2)]
    episodes = [{r.episode_id for r in s.results} for s in shards]
    assert episodes[0] and episodes[1] and not episodes[0] & episodes[1]         # whole episodes each
    merged = merge_shards([s.run.results_path for s in shards], tmp_path / 'merged.jsonl')
    write_merged(merged, tmp_path / 'merged.jsonl')
    assert comparable(merged.results) == comparable(whole.results)
    assert score(tmp_path / 'merged.jsonl', workers=1, progress=False)['refused'] is None
