"""The performer's training entry point and data preparation (dialfred_performer.train, .prepare).

Claims: a tiny-budget run writes a loadable checkpoint (config, vocabulary, weights, commit and the
command that rebuilds its config), metrics.jsonl with training and validation lines, and curves.png;
a run stopped and resumed (twice, mid-epoch) ends with the very weights and metrics of an
uninterrupted run; bad config values and missing data get clear errors; prepared dialogues are the
bytes of `generate_dialogues` whatever the sharding and after an interruption cut a line.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shlex
import subprocess
from pathlib import Path

import pytest
import torch
from PIL import Image

from dialfred_sim.dataclass_cli import parse, to_argv
from dialfred_performer.data import DIALOGUES_FILE, OracleProbe, generate_dialogues
from dialfred_performer.model import PerformerConfig, load_checkpoint
from dialfred_performer.prepare import (VOCABULARY_FILE, PrepareConfig, _dialogue_worker, _part_path, prepare,
                                        write_dialogues)
from dialfred_performer.preprocess import Vocabulary, tokenize
from dialfred_performer.train import (TrainConfig, epoch_batches, epoch_items, load_data, load_vocabulary, lr_factor,
                                      main, train)

TINY_MODEL = PerformerConfig(resolution=64, d_model=32, heads=2, layers=1, ff=64, dropout=0.1, max_steps=64)


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp('prepared') / 'valid_unseen_64'
    report = prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=4, out=str(out),
                                   progress=False))
    assert report['tasks'] == 4 and report['vocabulary'] > 100
    return out


pytestmark = pytest.mark.usefixtures('restore_torch_globals')


def tiny(folder, out, **changes) -> TrainConfig:
    base = dict(demonstrations=str(folder), out=str(out), model=TINY_MODEL, epochs=2, batch_size=4, bucket=2,
                warmup_updates=2, log_every=2, checkpoint_every=3, val_fraction=0.3, threads=1, device='cpu',
                progress=False)
    return TrainConfig(**{**base, **changes})


def test_a_tiny_training_run_writes_a_checkpoint_a_log_and_curves(folder, tmp_path):
    cfg = tiny(folder, tmp_path / 'run')
    summary = train(cfg)
    # 4 tasks x 8 question-type combinations; one task held out for validation
    assert summary['finished'] and summary['train_episodes'] == 24 and summary['val_episodes'] == 8
    assert summary['updates'] == summary['total_updates'] == 2 * 6 and summary['threads'] == 1
    for name in ('last.pt', 'best.pt', 'epoch-001.pt', 'epoch-002.pt', 'metrics.jsonl', 'curves.png', 'config.json'):
        assert (tmp_path / 'run' / name).is_file(), name
    model, vocab, info = load_checkpoint(tmp_path / 'run' / 'last.pt')
    assert info['config'] == TINY_MODEL and vocab == Vocabulary.load(folder / VOCABULARY_FILE)
    assert info['git_commit'] and info['extra']['progress']['update'] == 12
    command = shlex.split(info['command'])
    assert command[:3] == ['python', '-m', 'dialfred_performer.train'] and parse(TrainConfig, command[3:]) == cfg
    rows = [json.loads(line) for line in (tmp_path / 'run' / 'metrics.jsonl').read_text().splitlines()]
    assert [r['update'] for r in rows if r['kind'] == 'train'] == [2, 4, 6, 8, 10, 12]
    val = [r for r in rows if r['kind'] == 'val']
    assert [r['update'] for r in val] == [6, 12] and all(0 <= r['action_accuracy'] <= 1 for r in val)
    assert Image.open(tmp_path / 'run' / 'curves.png').size[0] > 600


def test_stopped_and_resumed_runs_end_with_the_weights_of_an_uninterrupted_run(folder, tmp_path):
    whole = tiny(folder, tmp_path / 'whole')
    train(whole)
    parts = tiny(folder, tmp_path / 'parts', stop_after=5)             # stops inside epoch 1, off a checkpoint
    assert not train(parts)['finished']
    assert not train(dataclasses.replace(parts, resume=True, stop_after=4))['finished']   # inside epoch 2
    assert train(dataclasses.replace(parts, resume=True, stop_after=0))['finished']
    a = load_checkpoint(tmp_path / 'whole' / 'last.pt')[0].state_dict()
    b = load_checkpoint(tmp_path / 'parts' / 'last.pt')[0].state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)

    def numbers(run):
        rows = [json.loads(line) for line in (tmp_path / run / 'metrics.jsonl').read_text().splitlines()]
        return [{k: v for k, v in r.items() if k != 'frames_per_s'} for r in rows]
    assert numbers('whole') == numbers('parts')
    with pytest.raises(ValueError, match=r"differs.*'lr'"):
        train(dataclasses.replace(parts, resume=True, lr=0.5))


def test_bad_config_values_get_a_clear_error(capsys):
    for argv, message in ((['--batch-size', '0'], 'batch_size must be at least 1'),
                          (['--lr', '-1'], 'lr must be a positive number'),
                          (['--val-fraction', '1.5'], r'val_fraction must be in \[0, 1\)'),
                          (['--resolution', '60'], 'resolution must be a positive multiple of 8'),
                          (['--d-model', '30'], 'd_model'),
                          (['--device', 'tpu'], "device must be 'auto'"),
                          (['--epochs', 'many'], "invalid int value: 'many'")):
        with pytest.raises(SystemExit) as exit_info:
            parse(TrainConfig, argv)
        assert exit_info.value.code == 2
        assert re.search(message, capsys.readouterr().err), argv
    with pytest.raises(ValueError, match='dropout must be in'):
        TrainConfig(model=PerformerConfig(dropout=1.0))


def test_missing_data_gets_a_clear_error(folder, tmp_path, capsys):
    assert main(['--demonstrations', str(tmp_path / 'nowhere'), '--out', str(tmp_path / 'o'), '--no-progress']) == 2
    err = capsys.readouterr().err
    assert 'no finished training demonstrations' in err and 'prepare-performer' in err
    bare = tmp_path / 'bare'
    bare.mkdir()
    for name in ('meta.json', 'tasks.jsonl', 'frames.npy'):
        (bare / name).write_bytes((folder / name).read_bytes())
    assert main(['--demonstrations', str(bare), '--out', str(tmp_path / 'o'), '--no-progress']) == 2
    assert f'no {DIALOGUES_FILE}' in capsys.readouterr().err
    assert main(['--demonstrations', str(folder), '--out', str(tmp_path / 'o'), '--resume', '--no-progress']) == 2
    assert 'no ' in capsys.readouterr().err


def test_the_config_is_the_command_line():
    cfg = TrainConfig(model=dataclasses.replace(TINY_MODEL, layers=3), lr=3e-4, resume=True, dialogues=False)
    assert parse(TrainConfig, to_argv(cfg)) == cfg
    assert parse(TrainConfig, []) == TrainConfig()
    assert parse(TrainConfig, ['--layers', '3']).model.layers == 3


def test_prepared_dialogues_are_those_of_generate_dialogues_whatever_the_sharding(folder, tmp_path):
    reference = generate_dialogues(folder, out=tmp_path / 'reference.jsonl').read_bytes()
    assert (folder / DIALOGUES_FILE).read_bytes() == reference
    for name in ('meta.json', 'tasks.jsonl', 'frames.npy'):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    _dialogue_worker(str(tmp_path), 0, 2)                  # shard 0 of 2 finished ...
    part = _part_path(tmp_path, 1)
    part.write_text(reference.decode().splitlines()[1][:40])   # ... shard 1 cut off inside its first line
    assert write_dialogues(tmp_path, workers=1, progress=False).read_bytes() == reference
    assert not list(tmp_path.glob('dialogues-*.part'))


@pytest.mark.slow   # fast: prepared dialogues equal generate_dialogues whatever the sharding; the probe before the middle
def test_the_oracle_probe_asks_what_a_replay_asks_and_leaves_the_frames_alone(tmp_path, monkeypatch):
    """prepare asks the dialogues' QAs while rendering (OracleProbe): the same dialogues.jsonl as
    replaying every task afterwards (generate_dialogues), the same frames and records as a build
    without a probe, with two workers; a task whose probe gives nothing is replayed."""
    from dialfred_sim.tasks.demonstrations import build_demonstrations, probe_values
    probed = tmp_path / 'probed'
    prepare(PrepareConfig(split='train', resolution=64, workers=2, limit=12, out=str(probed), progress=False))
    plain = tmp_path / 'plain'
    build_demonstrations('train', 64, plain, workers=1, limit=12, progress=False)
    for name in ('frames.npy', 'tasks.jsonl'):
        assert (probed / name).read_bytes() == (plain / name).read_bytes(), name
    assert len(probe_values(probed)) == 12 and not probe_values(plain)
    assert all(set(v) == {'qas'} for v in probe_values(probed).values())     # no annotator rows unless asked
    reference = generate_dialogues(plain, out=tmp_path / 'reference.jsonl').read_bytes()
    assert (probed / DIALOGUES_FILE).read_bytes() == reference
    assert not list(probed.glob('dialogues-*.part'))

    end = OracleProbe.end
    skipped = {json.loads(line)['task_id'] for line in reference.decode().splitlines()[::3]}
    monkeypatch.setattr(OracleProbe, 'end', lambda self, record: {'qas': None} if record['task_id'] in skipped
                        else end(self, record))
    partly = tmp_path / 'partly'
    prepare(PrepareConfig(split='train', resolution=64, workers=1, limit=12, out=str(partly), progress=False))
    answered = {tid for tid, v in probe_values(partly).items() if v['qas'] is not None}
    assert answered == {json.loads(l)['task_id'] for l in reference.decode().splitlines()} - skipped
    assert (partly / DIALOGUES_FILE).read_bytes() == reference


def test_the_oracle_probe_gives_nothing_when_the_episode_stopped_before_its_middle():
    class Task:
        object_nouns = ('apple',)
        expert_actions = ('a',) * 4
    probe = OracleProbe()
    probe.begin(Task())
    assert probe.middle == 2
    assert probe.end({'actions': [0, 1, 2]}) == {'qas': None}    # the goal held after 3 of 4: middle 1, not 2
    assert probe.end({'actions': [0, 1, 2, 3]}) == {'qas': []}


def test_the_vocabulary_knows_every_word_the_oracle_says(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    for sentence in ("I don't know.", 'You should turn around.', 'The apple is to your rear left in the fridge.',
                     'The mug is maroon and made of ceramic.', 'You are holding the butter knife.'):
        assert all(w in vocab.index for w in tokenize(sentence)), sentence


def test_batches_cover_every_episode_once_and_the_schedule_warms_up_then_decays():
    lengths = [5, 9, 2, 7, 3, 8, 4, 6, 1, 10]
    for bucket in (1, 3):
        batches = epoch_batches(lengths, 3, seed=0, epoch=1, bucket=bucket)
        assert sorted(i for b in batches for i in b) == list(range(10))
        assert batches == epoch_batches(lengths, 3, seed=0, epoch=1, bucket=bucket)
    assert epoch_batches(lengths, 3, 0, 1, 3) != epoch_batches(lengths, 3, 0, 2, 3)
    f = [lr_factor(u, 4, 20, 0.1) for u in range(20)]
    assert f[:4] == [0.25, 0.5, 0.75, 1.0] and f[4] == 1.0 and all(a >= b for a, b in zip(f[4:], f[5:]))
    assert lr_factor(20, 4, 20, 0.1) == pytest.approx(0.1)


@pytest.mark.slow   # a training process through ./dialfred; fast: the tiny training runs above
def test_the_entry_script_runs_training_with_the_malloc_settings(folder, tmp_path):
    root = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if not k.startswith('MALLOC_')}
    run = subprocess.run([str(root / 'dialfred'), 'train-performer', '--demonstrations', str(folder), '--out',
                          str(tmp_path / 'run'), '--max-updates', '1', '--batch-size', '2', '--d-model', '32',
                          '--heads', '2', '--layers', '1', '--ff', '64', '--threads', '1', '--no-progress'],
                         capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary['updates'] == 1 and summary['malloc_settings'] and (tmp_path / 'run' / 'last.pt').is_file()


def test_without_every_combination_an_epoch_shows_each_training_task_once(folder, tmp_path):
    cfg = tiny(folder, tmp_path / 'run', every_combination=False)
    data = load_data(cfg, load_vocabulary(cfg))
    combos = len(data.train.combinations)
    train_tasks = sorted({i // combos for i in data.train_items})
    epochs = [epoch_items(data, cfg, e) for e in range(6)]
    assert all(sorted(i // combos for i in items) == train_tasks for items in epochs)
    assert len({tuple(items) for items in epochs}) > 1                  # combinations drawn anew each epoch
    assert epoch_items(data, cfg, 0) == epochs[0]
    assert train(dataclasses.replace(cfg, epochs=1))['updates'] == 1     # 3 tasks, batches of 4


def test_a_percent_sign_in_a_help_text_does_not_break_help():
    from dataclasses import dataclass

    from dialfred_sim.dataclass_cli import arg, parser_for

    @dataclass(frozen=True)
    class Config:
        share: float = arg(0.5, 'the 95% interval; 50% of the time')

    assert '95% interval' in ' '.join(parser_for(Config).format_help().split())
