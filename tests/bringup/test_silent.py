"""Episodes in which nobody asks are played once and replayed by the settings that ask nothing in them
(dialfred_bringup/silent.py): a replayed episode's result is the played one's field by field (but for the
wall time), a questioner that watches the performer is never replayed, and a damaged or foreign file is no
episode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dialfred_bringup import local
from dialfred_bringup.evaluation import EvalConfig, EvalRun, run_eval
from dialfred_bringup.silent import SilentEpisodes, replayable, silent_key
from dialfred_sim.chained import chain_episodes
from dialfred_sim.episode import EpisodeState
from dialfred_sim.protocol import Observation

BASE = dict(split='valid_unseen', agent='et', resolution=64, seed=1, local=True)


def comparable(results) -> list:
    return [dataclasses.replace(r, wall_s=0.0) for r in results]


def observations(n: int) -> list:
    rng = np.random.default_rng(0)
    return [Observation(rgb=rng.integers(0, 255, (8, 8, 3), dtype=np.uint8), pose=(0.25 * k, 1.5, 90.0, 30.0),
                        held_object='Apple_1' if k else '', last_action_success=bool(k % 2),
                        last_action_error='' if k % 2 else 'blocked', step_count=k, failed_actions=k // 2)
            for k in range(n)]


def test_a_kept_episode_comes_back_as_it_was_and_nothing_else_does(tmp_path):
    store = SilentEpisodes(tmp_path / 's', {'agent': 'et', 'seed': 1})
    seen = observations(4)
    state = EpisodeState(steps=4, failed_actions=2, goal_conditions_met=1, goal_conditions_total=2, last_action='Stop',
                         end_reason='stop')
    assert store.save('valid_unseen/000003', seen, state)
    back, again = store.load('valid_unseen/000003')
    fields = dataclasses.fields(Observation)
    assert fields[0].name == 'rgb'
    assert again == state and len(back) == 4
    for a, b in zip(seen, back):
        assert np.array_equal(a.rgb, b.rgb)
        assert [getattr(a, f.name) for f in fields[1:]] == [getattr(b, f.name) for f in fields[1:]]
    assert store.load('valid_unseen/000004') is None
    assert SilentEpisodes(tmp_path / 's', {'agent': 'et', 'seed': 2}).load('valid_unseen/000003') is None
    asked = dataclasses.replace(state, questions=1)
    assert not store.save('valid_unseen/000005', seen, asked) and store.load('valid_unseen/000005') is None
    path = next((tmp_path / 's').glob('*000003.npz'))
    path.write_bytes(path.read_bytes()[:200])                 # cut short: no episode, played instead
    assert store.load('valid_unseen/000003') is None


def play_in_process(settings: dict, tasks: int, silent=None) -> tuple[list, int]:
    """The local path's jobs played in this process (a worker's own calls): (results, replayed)."""
    run = EvalRun(EvalConfig(**BASE, **settings))
    local._init_worker(run, silent)
    out = [local._play_job((k, t)) for k, t in enumerate(run.split_tasks()[:tasks])]
    return [r for r, _ in out], sum(replayed for _, replayed in out)


@pytest.mark.parametrize('questioner', ['rl-anytime', pytest.param('random', marks=pytest.mark.slow)])
def test_a_replayed_episode_is_the_played_one(tmp_path, questioner):
    tasks, folder = 12, str(tmp_path / 'silent')
    play_in_process({}, tasks, ('record', folder))
    assert len(list((tmp_path / 'silent').glob('*.npz'))) == tasks
    played, none = play_in_process({'questioner': questioner}, tasks)
    replayed, n = play_in_process({'questioner': questioner}, tasks, ('replay', folder))
    assert none == 0
    assert comparable(replayed) == comparable(played)
    assert n == sum(not r.questions for r in played) > 0       # every silent episode replayed, and only those


def test_a_questioner_that_watches_the_performer_is_played(tmp_path):
    for watching in ('confusion', 'rl-mc'):                  # the model-confusion timing reads the performer
        assert replayable(EvalRun(EvalConfig(**BASE, questioner=watching)).make_agent()) is None
    assert replayable(EvalRun(EvalConfig(**BASE, questioner='rl-anytime')).make_agent()) is not None
    assert replayable(EvalRun(EvalConfig(**BASE, questioner='random')).make_agent()) is not None
    assert replayable(EvalRun(EvalConfig(**BASE)).make_agent()) is None      # no questioner: nothing to replay


def test_run_eval_refuses_silent_episodes_it_cannot_keep_or_replay(tmp_path):
    folder = tmp_path / 'silent'
    with pytest.raises(ValueError, match='without questions'):
        run_eval(EvalConfig(**BASE, limit=1, questioner='random', out=tmp_path / 'x.jsonl'), silent=('record', folder))
    with pytest.raises(ValueError, match='of a local run'):
        run_eval(EvalConfig(**{**BASE, 'local': False}, limit=1, out=tmp_path / 'y.jsonl'), silent=('replay', folder))
    assert not folder.exists()


@pytest.mark.slow   # worker processes end to end; the replay itself has fast tests above
def test_run_eval_records_then_replays_and_counts_them(tmp_path):
    folder = tmp_path / 'silent'
    run_eval(EvalConfig(**BASE, limit=4, workers=1, out=tmp_path / 'alone.jsonl'), progress=False,
             silent=('record', folder))
    key = silent_key(EvalRun(EvalConfig(**BASE, questioner='rl-anytime')))
    assert SilentEpisodes(folder, key).load('valid_unseen/000000') is not None    # the key ignores the questioner
    report = run_eval(EvalConfig(**BASE, limit=4, workers=1, questioner='rl-anytime', out=tmp_path / 'rl.jsonl'),
                      progress=False, silent=('replay', folder))
    assert report.replayed == sum(not r.questions for r in report.results) and report.to_json()['this_run']['replayed']


def play_chained_in_process(settings: dict, tasks: int, silent=None) -> tuple[list, int]:
    """The chained protocol's jobs (whole episodes of the first `tasks` tasks) played in this process."""
    run = EvalRun(EvalConfig(**{**BASE, **settings}, protocol='chained'))
    local._init_worker(run, silent)
    episodes = chain_episodes(list(enumerate(run.split_tasks()[:tasks])))
    out = [pair for episode in episodes for pair in local._play_any(episode)]
    return [r for r, _ in out], sum(replayed for _, replayed in out)


def silent_episodes(results) -> int:
    asked = {}
    for r in results:
        asked[r.episode_id] = asked.get(r.episode_id, False) or bool(r.questions)
    return sum(not a for a in asked.values())


@pytest.mark.parametrize('settings, tasks', [
    ({'questioner': 'rl-anytime-chained'}, 17),             # 2 episodes, the first of which asks
    pytest.param({'questioner': 'map-rl-anytime', 'agent': 'map', 'resolution': 128}, 30, marks=pytest.mark.slow)])
def test_a_replayed_chained_episode_is_the_played_one_task_by_task(tmp_path, settings, tasks):
    folder = str(tmp_path / 'silent')
    alone = {k: v for k, v in settings.items() if k != 'questioner'}
    recorded, _ = play_chained_in_process(alone, tasks, ('record', folder))
    assert len(list((tmp_path / 'silent').glob('*.npz'))) == len({r.episode_id for r in recorded})
    played, none = play_chained_in_process(settings, tasks)
    replayed, n = play_chained_in_process(settings, tasks, ('replay', folder))
    assert none == 0
    assert comparable(replayed) == comparable(played)
    silent = silent_episodes(played)
    assert 0 < silent < len({r.episode_id for r in played})           # some episodes ask, some do not
    # every task of an episode without a question replayed, and only those
    assert n == sum(len([r for r in played if r.episode_id == e]) for e in {r.episode_id for r in played}
                    if not any(r.questions for r in played if r.episode_id == e))


def test_a_chained_episode_is_kept_whole_or_not_at_all(tmp_path):
    store = SilentEpisodes(tmp_path / 's', {'agent': 'et', 'protocol': 'chained'})
    quiet = EpisodeState(steps=3, last_action='Stop', end_reason='stop')
    first, second = observations(3), observations(5)
    assert store.save_chain('valid_unseen/ep000001', [(first, quiet), (second, dataclasses.replace(quiet, steps=5))])
    back = store.load_chain('valid_unseen/ep000001', 2)
    assert [len(seen) for seen, _ in back] == [3, 5] and [s.steps for _, s in back] == [3, 5]
    assert np.array_equal(back[1][0][4].rgb, second[4].rgb)
    assert store.load_chain('valid_unseen/ep000001', 3) is None          # another length: played
    assert store.load('valid_unseen/ep000001') is None
    asked = dataclasses.replace(quiet, questions=1)
    assert not store.save_chain('valid_unseen/ep000002', [(first, quiet), (second, asked)])
    assert store.load_chain('valid_unseen/ep000002', 2) is None
