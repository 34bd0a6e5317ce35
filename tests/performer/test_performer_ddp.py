"""The performer's training on several processes (torchrun + DistributedDataParallel, gloo on CPU).

Claims: each process takes an interleaved share of every global batch, a process left without an
item plays a weightless stand-in, and a batch size that does not divide by the processes is refused;
the ranks' sharded losses add up to the single process's loss of the whole batch; 2 processes (1
thread each) train through the same per-update losses as 1 process with the same global batch,
within 1e-5 relative (measured here: at most 4.8e-7 absolute on losses of 5-8, i.e. float32 rounding:
the gradient all-reduce and each rank's padding sum in another order), with dropout 0: with dropout
each rank draws its own masks, and the curves then agree only in distribution (about 1% apart per
update here); only rank 0 writes (one metrics line per update); a 2-process run stopped twice and
resumed ends with the very weights and metrics of an uninterrupted 2-process run.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from dialfred_sim.dataclass_cli import to_argv
from dialfred_performer.data import DemonstrationDataset, collate
from dialfred_performer.distributed import Ranks, check_batch, rank_share, sharded_loss
from dialfred_performer.model import Performer, PerformerConfig, load_checkpoint, performer_loss
from dialfred_performer.prepare import PrepareConfig, prepare
from dialfred_performer.preprocess import Vocabulary
from dialfred_performer.train import TrainConfig, train

TINY_MODEL = PerformerConfig(resolution=64, d_model=32, heads=2, layers=1, ff=64, dropout=0.0, max_steps=64)
RELATIVE_TOLERANCE = 1e-5
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp('prepared') / 'valid_unseen_64'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=4, out=str(out), progress=False))
    return out


pytestmark = pytest.mark.usefixtures('restore_torch_globals')


def tiny(folder, out, **changes) -> TrainConfig:
    """3 training tasks, one question-type combination each per epoch, 2 per batch: every epoch has a
    batch of 2 (one each, of different lengths) and a batch of 1 (a stand-in on rank 1)."""
    base = dict(demonstrations=str(folder), out=str(out), model=TINY_MODEL, epochs=4, batch_size=2, bucket=2,
                every_combination=False, warmup_updates=2, log_every=1, checkpoint_every=3, val_fraction=0.3,
                threads=1, device='cpu', progress=False)
    return TrainConfig(**{**base, **changes})


def torchrun(cfg: TrainConfig, processes: int = 2) -> dict:
    """Run `python -m dialfred_performer.train` under torch.distributed.run (torchrun); its summary."""
    cmd = [sys.executable, '-m', 'torch.distributed.run', '--standalone', '--nproc_per_node', str(processes),
           '-m', 'dialfred_performer.train', *to_argv(cfg)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, cwd=REPO)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    lines = [line for line in done.stdout.splitlines() if line.startswith('{')]
    assert len(lines) == 1, done.stdout           # only rank 0 prints its summary
    return json.loads(lines[0])


def metrics(out: Path) -> list[dict]:
    return [json.loads(line) for line in (Path(out) / 'metrics.jsonl').read_text().splitlines()]


# ---------------------------------------------------------------------------------------------- in one process

def test_each_rank_takes_an_interleaved_share_and_an_empty_share_is_a_weightless_stand_in():
    batch = [10, 11, 12, 13, 14]
    assert rank_share(batch, Ranks(0, 2)) == ([10, 12, 14], False)
    assert rank_share(batch, Ranks(1, 2)) == ([11, 13], False)
    assert rank_share([10], Ranks(1, 2)) == ([10], True)
    assert rank_share(batch, Ranks()) == (batch, False)
    check_batch(4, Ranks(1, 2))
    with pytest.raises(ValueError, match='batch_size 3 does not divide by the 2 processes'):
        check_batch(3, Ranks(0, 2))


def test_a_batch_size_that_does_not_divide_is_refused_before_anything_starts(folder, tmp_path):
    with pytest.raises(ValueError, match='batch_size 3 does not divide by the 2 processes'):
        train(tiny(folder, tmp_path / 'run', batch_size=3), Ranks(0, 2, 0, 2))
    assert not (tmp_path / 'run').exists() and not torch.distributed.is_initialized()


def test_the_ranks_sharded_losses_add_up_to_the_whole_batchs_loss(folder):
    torch.manual_seed(0)
    vocab = Vocabulary.load(folder / 'vocabulary.json')
    ds = DemonstrationDataset(folder, vocab, 64, TINY_MODEL.max_tokens)
    model = Performer(TINY_MODEL, len(vocab)).eval()
    items = [0, 9, 17, 26, 30]                        # 4 tasks: episodes of different lengths
    whole = collate([ds[i] for i in items])
    with torch.no_grad():
        expected, _ = performer_loss(model(whole), whole)
    steps, targets = float(whole['step_valid'].sum()), float((whole['target_cells'] >= 0).sum())
    for world in (2, 3):
        total = 0.0
        for rank in range(world):
            share, stand_in = rank_share(items, Ranks(rank, world))
            batch = collate([ds[i] for i in share])
            with torch.no_grad():
                loss = sharded_loss(model(batch), batch, 1.0, steps, targets, world, 0.0 if stand_in else 1.0)
            total += float(loss)
        assert total / world == pytest.approx(float(expected), rel=1e-6)       # DDP averages over the ranks


# ---------------------------------------------------------------------------------------------- torchrun

@pytest.fixture(scope='module')
def one_process(folder, tmp_path_factory):
    out = tmp_path_factory.mktemp('one')
    return tiny(folder, out), train(tiny(folder, out))


@pytest.fixture(scope='module')
def two_processes(folder, tmp_path_factory):
    cfg = tiny(folder, tmp_path_factory.mktemp('two'))
    return cfg, torchrun(cfg)


@pytest.mark.slow   # torchrun with two ranks; fast: the sharded losses add up to the whole batch's
def test_two_processes_train_through_the_losses_of_one_with_the_same_global_batch(one_process, two_processes):
    (one, summary1), (two, summary2) = one_process, two_processes
    assert summary2['processes'] == 2 and summary1['processes'] == 1
    assert summary2['updates'] == summary1['updates'] == 8 and summary2['finished']
    rows1, rows2 = metrics(one.out), metrics(two.out)
    assert [(r['kind'], r['update']) for r in rows2] == [(r['kind'], r['update']) for r in rows1]   # rank 0 alone
    assert sum(r['kind'] == 'train' for r in rows2) == 8
    for a, b in zip(rows1, rows2):
        assert (a['steps'], a['episodes']) == (b['steps'], b['episodes'])       # the whole batch is counted
        for key in ('loss', 'action_loss', 'pointer_loss'):
            assert b[key] == pytest.approx(a[key], rel=RELATIVE_TOLERANCE), (a['kind'], a['update'], key)
        assert b['action_accuracy'] == a['action_accuracy']
    assert load_checkpoint(Path(two.out) / 'last.pt')[2]['extra']['progress']['update'] == 8


@pytest.mark.slow   # torchrun with two ranks; fast: the sharded losses add up to the whole batch's
def test_a_two_process_run_stopped_and_resumed_ends_as_an_uninterrupted_one(two_processes, tmp_path):
    whole, _ = two_processes
    parts = dataclasses.replace(whole, out=str(tmp_path / 'parts'), stop_after=3)
    assert not torchrun(parts)['finished']
    assert not torchrun(dataclasses.replace(parts, resume=True))['finished']
    assert torchrun(dataclasses.replace(parts, resume=True, stop_after=0))['finished']
    a = load_checkpoint(Path(whole.out) / 'last.pt')[0].state_dict()
    b = load_checkpoint(tmp_path / 'parts' / 'last.pt')[0].state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    strip = [{k: v for k, v in r.items() if k != 'frames_per_s'} for r in metrics(whole.out)]
    assert [{k: v for k, v in r.items() if k != 'frames_per_s'} for r in metrics(parts.out)] == strip
