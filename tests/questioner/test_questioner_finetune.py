"""Actor-critic fine-tuning of the learned questioner (dialfred_questioner.finetune, no ROS), tiny
budget: a tiny performer, a questioner pre-trained for one epoch on 16 tasks' (SYNTHETIC) dialogues,
8-step episodes.

Claims: a run writes a metrics line per update (return, SR, NQ, question mix, losses), curves.png,
last.pt and final.pt with the timing it was trained with, and changes the weights; the episodes do
not depend on the number of workers (the same weights after one or two workers); a run stopped and
resumed ends with the weights of an uninterrupted run; the episode plan covers every task once per
pass; bad settings are refused before anything runs.
"""

from __future__ import annotations

import json

import pytest
import torch

from dialfred_questioner.finetune import (FinetuneConfig, chained_episodes, chained_plan, episode_plan, finetune,
                                         rollout_chunks)
from dialfred_questioner.frames import build_first_frames
from dialfred_questioner.model import QuestionerConfig
from dialfred_questioner.policy import LearnedQuestioner
from dialfred_questioner.pretrain import PretrainConfig, pretrain
from helpers import tiny_checkpoint

TASKS = 12


@pytest.fixture(scope='module')
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp('qrl')
    build_first_frames('valid_unseen', 64, root / 'first.npz', workers=1, limit=16, progress=False)
    performer = tiny_checkpoint(root / 'performer.pt')
    pretrain(PretrainConfig(split='valid_unseen', frames=str(root / 'first.npz'), performer=str(performer),
                            out=str(root / 'pre'), model=QuestionerConfig(embedding=16, hidden=32, image=32),
                            epochs=1, batch_size=8, limit=16, threads=1, progress=False))
    return root / 'pre' / 'best.pt', performer


def config(setup, out, **changes) -> FinetuneConfig:
    init, performer = setup
    base = dict(init=str(init), performer=str(performer), split='valid_unseen', out=str(out), timing='anytime',
                gap=3, updates=2, episodes_per_update=4, samples_per_task=2, lr=1e-2, resolution=64, max_steps=8, limit=TASKS,
                workers=1, progress=False)
    return FinetuneConfig(**{**base, **changes})


def weights(path):
    return torch.load(path, weights_only=True)['state_dict']


def same(a, b) -> bool:
    return all(torch.equal(a[k], b[k]) for k in a)


def test_a_tiny_run_writes_its_curves_and_checkpoints_and_learns_something(setup, tmp_path):
    report = finetune(config(setup, tmp_path / 'one'))
    lines = [json.loads(l) for l in (tmp_path / 'one' / 'metrics.jsonl').read_text().splitlines()]
    assert [l['update'] for l in lines] == [1, 2]
    for l in lines:
        assert l['episodes'] == 4 and 0.0 <= l['sr'] <= 1.0 and l['nq'] >= 0 and l['decisions'] >= 4 * 1
        assert set(l['mix']) == {'location', 'appearance', 'direction'} and l['critic'] >= 0
    assert (tmp_path / 'one' / 'curves.png').stat().st_size > 1000
    final = torch.load(tmp_path / 'one' / 'final.pt', weights_only=True)
    assert final['timing'] == {'mode': 'anytime', 'gap': 3, 'epsilon': 0.5}
    assert 'dialfred_questioner.finetune' in final['command']
    assert not same(final['state_dict'], weights(setup[0]))
    q = LearnedQuestioner.from_checkpoint(tmp_path / 'one' / 'final.pt')
    assert q.timing.mode == 'anytime' and q.timing.gap == 3
    assert report['final'].endswith('final.pt')
    assert q.reads_dialogue and final['reads_dialogue'] is True


def test_the_instruction_only_ablation_is_stored_and_read_without_the_dialogue(setup, tmp_path):
    from dialfred_sim.protocol import QA, Question
    from dialfred_performer.preprocess import AskedQA
    finetune(config(setup, tmp_path / 'blind', updates=1, dialogue=False))
    q = LearnedQuestioner.from_checkpoint(tmp_path / 'blind' / 'final.pt')
    assert not q.reads_dialogue and not torch.load(tmp_path / 'blind' / 'final.pt', weights_only=True)['reads_dialogue']
    import numpy as np
    rgb = np.zeros((64, 64, 3), np.uint8)
    said = [AskedQA(QA(Question('location', 'apple'), True, 'the apple is in the fridge'), 0)]
    assert q.record_of(rgb, 'pick up the apple', said, 3).lang_ids == q.record_of(rgb, 'pick up the apple', [], 3).lang_ids
    q.reads_dialogue = True
    assert q.record_of(rgb, 'pick up the apple', said, 3).lang_ids != q.record_of(rgb, 'pick up the apple', [], 3).lang_ids


def test_the_critic_baseline_trains_too(setup, tmp_path):
    finetune(config(setup, tmp_path / 'critic', baseline='critic', samples_per_task=1, updates=1))
    assert not same(weights(tmp_path / 'critic' / 'final.pt'), weights(setup[0]))


@pytest.mark.slow   # two fine-tunings and a resumed one; fast: the tests above of one run
def test_the_weights_do_not_depend_on_the_workers_and_a_resumed_run_matches(setup, tmp_path):
    finetune(config(setup, tmp_path / 'one', updates=3))
    finetune(config(setup, tmp_path / 'two', updates=3, workers=2))
    assert same(weights(tmp_path / 'one' / 'final.pt'), weights(tmp_path / 'two' / 'final.pt'))
    finetune(config(setup, tmp_path / 'cut', updates=1))
    finetune(config(setup, tmp_path / 'cut', updates=3, resume=True))
    assert same(weights(tmp_path / 'one' / 'final.pt'), weights(tmp_path / 'cut' / 'final.pt'))
    lines = (tmp_path / 'cut' / 'metrics.jsonl').read_text().splitlines()
    assert [json.loads(l)['update'] for l in lines] == [1, 2, 3]
    seconds = [json.loads(l)['seconds'] for l in lines]
    # the resumed run's time goes on from the cut (update 2 took about as long as update 1, start-up included)
    assert seconds == sorted(seconds) and seconds[1] >= 1.4 * seconds[0] > 0, seconds
    assert torch.load(tmp_path / 'cut' / 'final.pt', weights_only=True)['extra']['seconds'] == seconds[-1]
    with pytest.raises(ValueError, match='lr'):
        finetune(config(setup, tmp_path / 'cut', updates=4, resume=True, lr=0.5))


def test_the_questioner_fine_tunes_against_the_map_performer_too(setup, tmp_path):
    from dialfred_performer.model import SHIPPED_CHECKPOINT
    finetune(config(setup, tmp_path / 'map', performer=str(SHIPPED_CHECKPOINT), model='map', updates=1,
                    max_steps=12))
    final = torch.load(tmp_path / 'map' / 'final.pt', weights_only=True)
    assert final['performer_model'] == 'map' and '--model map' in final['command']
    line = json.loads((tmp_path / 'map' / 'metrics.jsonl').read_text())
    assert line['episodes'] == 4 and line['decisions'] >= 4
    assert not same(final['state_dict'], weights(setup[0]))


def test_a_chained_run_plays_whole_episodes_from_the_performers_own_state(setup, tmp_path):
    cfg = config(setup, tmp_path / 'chained', protocol='chained', updates=2)
    finetune(cfg)
    lines = [json.loads(l) for l in (tmp_path / 'chained' / 'metrics.jsonl').read_text().splitlines()]
    sizes = [len(e.tasks) for e in chained_episodes(cfg)]
    for update, line in enumerate(lines):
        played = chained_plan(sizes, update, cfg.episodes_per_update, cfg.seed, cfg.samples_per_task)
        assert line['episodes'] == sum(sizes[e] for e, _, _ in played) >= cfg.episodes_per_update
    assert not same(weights(tmp_path / 'chained' / 'final.pt'), weights(setup[0]))


def test_the_chained_plan_takes_each_episode_once_per_pass_in_whole_episodes():
    sizes = [3, 5, 2, 6, 4, 3, 5, 2]
    taken = [chained_plan(sizes, u, 8, 0, 2) for u in range(12)]
    for played in taken:
        episodes = [e for e, _, _ in played]
        assert all(episodes[j] == episodes[j + 1] for j in range(0, len(episodes), 2))     # each played twice
        assert played[0][1] == played[1][1] and played[0][2] != played[1][2]   # same starts, other sampling
        assert 4 <= sum(sizes[e] for e in episodes[::2]) < 4 + max(sizes)
    stream = [e for played in taken for e, _, _ in played[::2]]
    first_pass = stream[:len(sizes)]
    assert sorted(first_pass) == list(range(len(sizes)))
    assert chained_plan(sizes, 5, 8, 0, 2) == taken[5]                 # a pure function of the update


def test_the_episode_plan_visits_every_task_once_per_pass():
    plan = [p for u in range(5) for p in episode_plan(10, u, 4, seed=1)]
    assert sorted(t for t, _, _ in plan[:10]) == list(range(10)) and sorted(t for t, _, _ in plan[10:20]) == list(range(10))
    assert plan[:10] != plan[10:20]
    assert len({s for _, s, _ in plan}) == len(plan) and len({z for _, _, z in plan}) == len(plan)
    assert episode_plan(10, 2, 4, seed=1) == episode_plan(10, 2, 4, seed=1)
    grouped = episode_plan(10, 1, 8, seed=1, samples=4)        # 2 tasks x 4 samples from one start each
    assert len(grouped) == 8 and len({(t, s) for t, s, _ in grouped}) == 2 and len({z for _, _, z in grouped}) == 8
    assert [t for t, _, _ in grouped] == [grouped[0][0]] * 4 + [grouped[4][0]] * 4


@pytest.mark.parametrize('changes, match', [({'timing': 'never'}, 'timing'), ({'gap': 0}, 'gap'),
                                            ({'rewards': 'lots'}, 'rewards'), ({'perturb_type': 'colour'}, 'perturb'),
                                            ({'gamma': 0.0}, 'gamma'), ({'updates': 0}, 'updates'),
                                            ({'baseline': 'mean'}, 'baseline'),
                                            ({'samples_per_task': 1}, 'samples_per_task'),
                                            ({'episodes_per_update': 10}, 'multiple'),
                                            ({'model': 'transformer'}, 'model')])
def test_bad_settings_are_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        FinetuneConfig(**changes)


def test_rollout_chunks_cover_every_episode_once_in_order():
    jobs = list(range(64))
    for workers in (1, 2, 3, 8):
        chunks = rollout_chunks(jobs, workers)
        assert [j for c in chunks for j in c] == jobs
        assert all(chunks)
        assert len(chunks) == (1 if workers == 1 else min(64, -(-64 // -(-64 // (8 * workers)))))
    assert [len(c) for c in rollout_chunks(jobs, 2)] == [4] * 16
    assert rollout_chunks(list(range(5)), 2) == [[0], [1], [2], [3], [4]]
    assert rollout_chunks([], 2) == [] and rollout_chunks([], 1) == []
