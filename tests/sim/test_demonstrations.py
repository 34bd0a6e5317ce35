"""Rendered expert demonstrations (dialfred_sim.tasks.demonstrations, no ROS).

Claims: each task's frames are what the agent sees along the expert's path (the first is the task's
initial frame), the expert reaches every goal, any number of workers writes the same bytes, and an
interrupted build resumes to the same result without replaying what it already wrote.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from dialfred_sim.env import DialfredEnv
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.demonstrations import build_demonstrations, load_demonstrations

N = 6
RES = 64


@pytest.fixture(scope='module')
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp('demo') / 'one_worker'
    meta = build_demonstrations('valid_unseen', RES, out, workers=1, limit=N, progress=False)
    return out, meta


def test_every_task_gets_its_frames_and_actions_in_split_order(built):
    out, meta = built
    demo = load_demonstrations(out)
    tasks = load_split('valid_unseen')[:N]
    assert len(demo) == N and meta['success_rate'] == 1.0 and meta['failed_tasks'] == []
    assert demo.frames.shape == (sum(len(t.expert_actions) + 1 for t in tasks), RES, RES, 3)
    env = DialfredEnv(resolution=RES)
    for k, (t, rec) in enumerate(zip(tasks, demo.tasks)):
        assert (rec['task_id'], rec['instruction'], rec['success']) == (t.task_id, t.instruction, True)
        assert [a[0] for a in rec['actions']] == [a.action for a in t.expert_actions]
        frames = demo.frames_of(k)
        assert len(frames) == len(t.expert_actions) + 1
        obs, _ = env.reset(options={'task': t})
        assert np.array_equal(frames[0], obs['rgb'])          # the task's initial view
        for a, (name, x, y, target) in zip(frames[1:], rec['actions']):
            obs = env.step({'action': name, 'pixel': (x, y)})[0]
            assert np.array_equal(a, obs['rgb'])
            assert (x < 0) == (target == '')
    env.close()


def test_two_workers_write_the_same_bytes(built, tmp_path):
    out, _ = built
    build_demonstrations('valid_unseen', RES, tmp_path, workers=2, limit=N, progress=False)
    assert (tmp_path / 'frames.npy').read_bytes() == (out / 'frames.npy').read_bytes()
    assert (tmp_path / 'tasks.jsonl').read_text() == (out / 'tasks.jsonl').read_text()


def test_an_interrupted_build_resumes_without_replaying_finished_tasks(built, tmp_path, monkeypatch):
    out, _ = built
    build_demonstrations('valid_unseen', RES, tmp_path, workers=1, limit=N, progress=False)
    # Interrupt it after two tasks: their records stay, a third was cut off mid-line, the rest is lost.
    done = (tmp_path / 'done-0.txt').read_text().splitlines()
    (tmp_path / 'done-0.txt').write_text('\n'.join(done[:2]) + '\n' + done[2][:25])
    for name in ('meta.json', 'tasks.jsonl'):
        (tmp_path / name).unlink()
    first_lost = json.loads((out / 'tasks.jsonl').read_text().splitlines()[2])['first_frame']
    frames = np.load(tmp_path / 'frames.npy', mmap_mode='r+')
    frames[first_lost:] = 0
    frames.flush()
    del frames
    import dialfred_sim.tasks.demonstrations as demonstrations
    played = []
    real = demonstrations.play_demonstration
    monkeypatch.setattr(demonstrations, 'play_demonstration', lambda env, t, f, *a, **kw: played.append(t.task_id) or real(env, t, f, *a, **kw))
    build_demonstrations('valid_unseen', RES, tmp_path, workers=1, limit=N, progress=False)
    assert played == [t.task_id for t in load_split('valid_unseen')[2:N]]
    assert (tmp_path / 'frames.npy').read_bytes() == (out / 'frames.npy').read_bytes()
    assert (tmp_path / 'tasks.jsonl').read_text() == (out / 'tasks.jsonl').read_text()
    played.clear()                                   # a finished build is not touched again
    build_demonstrations('valid_unseen', RES, tmp_path, workers=1, limit=N, progress=False)
    assert played == []


def test_another_resolution_or_limit_in_the_same_folder_starts_afresh(built, tmp_path):
    build_demonstrations('valid_unseen', RES, tmp_path, workers=1, limit=2, progress=False)
    meta = build_demonstrations('valid_unseen', 32, tmp_path, workers=1, limit=3, progress=False)
    demo = load_demonstrations(tmp_path)
    assert (meta['resolution'], meta['tasks'], len(demo), demo.frames.shape[1]) == (32, 3, 3, 32)


def test_an_unfinished_or_bad_build_is_refused_clearly(tmp_path):
    with pytest.raises(FileNotFoundError, match='no finished demonstrations'):
        load_demonstrations(tmp_path)
    with pytest.raises(ValueError, match='at least 16'):
        build_demonstrations('valid_unseen', 8, tmp_path, limit=1, progress=False)
    proc = subprocess.run([sys.executable, '-m', 'dialfred_sim.tasks.demonstrations', 'valid_unseen',
                           '--resolution', '4', '--limit', '1', '--out', str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and 'at least 16' in proc.stderr


def test_labels_say_what_each_pixel_is_and_leave_the_frames_alone(built, tmp_path):
    from dialfred_sim.tasks.demonstrations import DEPTH_STEP, label_classes
    out, _ = built
    build_demonstrations('valid_unseen', RES, tmp_path, workers=2, limit=N, progress=False, labels=True)
    assert (tmp_path / 'frames.npy').read_bytes() == (out / 'frames.npy').read_bytes()
    demo = load_demonstrations(tmp_path)
    assert load_demonstrations(out).labels is None
    classes, depth, targets = demo.labels['classes'], demo.labels['depth'], demo.labels['targets']
    names = label_classes()
    assert classes.shape == depth.shape == demo.frames.shape[:3] and targets.shape == (len(demo.frames), RES * RES // 8)
    env = DialfredEnv(resolution=RES)
    interactions = 0
    for t, rec in zip(load_split('valid_unseen')[:N], demo.tasks):
        obs, _ = env.reset(options={'task': t})
        for step, (name, x, y, target) in enumerate(rec['actions']):
            row = rec['first_frame'] + step
            mask = np.unpackbits(targets[row])[:RES * RES].reshape(RES, RES).astype(bool)
            assert np.allclose(depth[row] * DEPTH_STEP, np.minimum(obs['depth'], 255 * DEPTH_STEP), atol=DEPTH_STEP)
            assert {names[c] for c in np.unique(classes[row][obs['segmentation'] < 0])} <= {''}
            if target:
                interactions += 1
                assert mask[y, x]                                     # the expert's pixel is on its target
                assert {names[c] for c in np.unique(classes[row][mask])} == {target}
                assert mask.sum() == (obs['segmentation'] == env.world.objects[t.expert_actions[step].target].body).sum()
            else:
                assert not mask.any()
            obs = env.step({'action': name, 'pixel': (x, y)})[0]
    env.close()
    # every interaction of the expert in these tasks had its target mask checked, and there were some
    # (the first N tasks include navigation-only ones, which have none)
    assert interactions == sum(bool(a.target) for t in load_split('valid_unseen')[:N] for a in t.expert_actions) > 0
    # a build without labels in the same folder is made again, not mixed
    build_demonstrations('valid_unseen', RES, tmp_path, workers=1, limit=N, progress=False)
    assert load_demonstrations(tmp_path).labels is None and not (tmp_path / 'classes.npy').exists()
