"""The performer is told when its click failed, and learns from recovery examples what to do next.

Claims: a recovery example inserts one failed click before an interaction, on a duplicate of the
frame the expert approached from, with the failed id as the next previous action, the click's own
action and pointer not targets, and the later QAs moved one step with their frames; the places it may
go are the navigation steps right before an interaction; the dataset makes them for the chosen share
of training items only (never for held-out tasks); the loss ignores the inserted click; the agent
feeds the failed id when the observation says its interaction failed (or, with failed_moves, its MoveAhead
was blocked, and then turns rather than walk into it again), and only then; training with
--recovery needs --failure-input; a run may start from a performer without it (--init).
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from dialfred_sim.protocol import ACTIONS, Observation
from dialfred_performer.agent import PerformerAgent
from dialfred_performer.data import (START, DemonstrationDataset, collate, insert_failed_interaction,
                                     recovery_places)
from dialfred_performer.model import Performer, PerformerConfig, load_checkpoint, performer_loss
from dialfred_performer.nn.enc_action import failed_id
from dialfred_performer.prepare import VOCABULARY_FILE, PrepareConfig, prepare
from dialfred_performer.preprocess import Vocabulary
from dialfred_performer.train import TrainConfig, train, warm_start

pytestmark = pytest.mark.usefixtures('restore_torch_globals')

A = {name: ACTIONS.index(name) for name in ACTIONS}
TINY = PerformerConfig(resolution=64, d_model=32, heads=2, layers=1, ff=64, dropout=0.0, max_steps=64,
                       failure_input=True)


def item_of(actions: list[str], qa_steps: list[int]) -> dict:
    n = len(actions)
    ids = torch.tensor([A[a] for a in actions])
    cells = torch.tensor([5 if a in ('Pickup', 'Put') else -1 for a in actions])
    return {'task_id': 't', 'frames': torch.arange(n, dtype=torch.float32).view(n, 1, 1, 1).expand(n, 3, 2, 2),
            'actions': ids, 'previous_actions': torch.cat([torch.tensor([START]), ids[:-1]]),
            'target_cells': cells, 'target_masks': torch.zeros(int((cells >= 0).sum()), 4, dtype=torch.bool),
            'lang_ids': torch.ones(len(qa_steps), dtype=torch.long), 'lang_types': torch.zeros(len(qa_steps), dtype=torch.long),
            'lang_steps': torch.tensor(qa_steps), 'action_valid': torch.ones(n, dtype=torch.bool)}


def test_a_failed_click_is_inserted_on_a_duplicate_frame_with_the_approach_as_the_target():
    item = item_of(['RotateLeft', 'MoveAhead', 'MoveAhead', 'Pickup', 'Stop'], [0, 0, 2, 3])
    out = insert_failed_interaction(item, at=2, interaction=3)
    frames = out['frames'][:, 0, 0, 0].tolist()
    assert frames == [0, 1, 2, 2, 3, 4]                                  # frame 2 again: nothing moved
    assert out['actions'].tolist() == [A['RotateLeft'], A['MoveAhead'], A['Pickup'], A['MoveAhead'], A['Pickup'],
                                       A['Stop']]
    assert out['previous_actions'].tolist() == [START, A['RotateLeft'], A['MoveAhead'],
                                                failed_id(A['Pickup'], len(ACTIONS)), A['MoveAhead'], A['Pickup']]
    assert out['action_valid'].tolist() == [True, True, False, True, True, True]   # the early click is no target
    assert out['target_cells'].tolist() == [-1, -1, -1, -1, 5, -1]                 # nor is its pixel
    assert torch.equal(out['target_masks'], item['target_masks'])
    assert out['lang_steps'].tolist() == [0, 0, 2, 4]                    # asked at step 3: one step later now
    assert item['frames'].shape[0] == 5                                  # the item itself is left alone


def test_places_are_the_navigation_steps_right_before_an_interaction():
    actions = [A[a] for a in ['MoveAhead', 'RotateLeft', 'MoveAhead', 'MoveAhead', 'MoveAhead', 'Pickup',
                              'Open', 'MoveAhead', 'Put', 'Stop']]
    assert recovery_places(actions) == [(4, 5), (3, 5), (2, 5), (7, 8)]    # at most 3 back; none before Open
    assert recovery_places([A['Pickup'], A['Stop']]) == []


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp('recovery') / 'valid_unseen_64'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=4, out=str(out), progress=False))
    return out


def test_the_dataset_makes_recovery_examples_for_its_share_of_training_items_only(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    plain = DemonstrationDataset(folder, vocab, 64)
    every = DemonstrationDataset(folder, vocab, 64, recovery=1.0)
    longer = [i for i in range(len(plain)) if len(every[i]['actions']) == len(plain[i]['actions']) + 1]
    with_place = [i for i in range(len(plain)) if recovery_places(plain[i]['actions'].tolist())]
    assert longer == with_place and longer                              # every item that can have one
    some = DemonstrationDataset(folder, vocab, 64, recovery=0.5)
    assert 0 < sum(len(some[i]['actions']) > len(plain[i]['actions']) for i in with_place) < len(with_place)
    assert [len(some[i]['actions']) for i in with_place] == [len(some[i]['actions']) for i in with_place]  # seeded
    every.no_recovery = set(range(len(every.task_indices)))            # all held out: none changed
    assert all(len(every[i]['actions']) == len(plain[i]['actions']) for i in range(len(plain)))
    with pytest.raises(ValueError, match='probability'):
        DemonstrationDataset(folder, vocab, 64, recovery=1.5)


def test_the_loss_ignores_the_inserted_click(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    ds = DemonstrationDataset(folder, vocab, 64)
    i = next(i for i in range(len(ds)) if recovery_places(ds[i]['actions'].tolist()))
    item = ds[i]
    at, interaction = recovery_places(item['actions'].tolist())[0]
    batch = collate([insert_failed_interaction(item, at, interaction)])
    torch.manual_seed(0)
    model = Performer(TINY, len(vocab)).eval()
    outputs = model(batch)
    loss, parts = performer_loss(outputs, batch)
    changed = dict(batch, actions=batch['actions'].clone())
    changed['actions'][0, at] = (changed['actions'][0, at] + 1) % len(ACTIONS)   # another wrong click: same loss
    assert performer_loss(outputs, changed)[1] == parts
    changed['actions'][0, at + 1] = (changed['actions'][0, at + 1] + 1) % len(ACTIONS)  # the recovery is a target
    assert performer_loss(outputs, changed)[1]['action'] != parts['action']


def test_the_agent_feeds_the_failed_id_only_after_a_failed_interaction_or_a_blocked_move_if_asked(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    frame = np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8)

    def after(first: str, success, incremental: bool = True, config=TINY) -> tuple[list[int], np.ndarray]:
        """The previous actions and the action probabilities at step 1, after `first` and a reply `success`."""
        torch.manual_seed(0)
        model = Performer(config, len(vocab))
        with torch.no_grad():
            model.action_head.linear.bias[A[first]] += 50.0          # the first action is `first`
        agent = PerformerAgent(model, vocab, incremental=incremental)
        agent.reset(SimpleNamespace(instruction='Pick up the apple.'))
        assert agent.act(Observation(rgb=frame))[0] == first
        seen = Observation(rgb=frame) if success is None else Observation(rgb=frame, last_action_success=success)
        probs = agent.action_probabilities(seen)
        return list(agent.state.previous_actions), probs

    failed, p_failed = after('Pickup', False)
    assert failed == [START, failed_id(A['Pickup'], len(ACTIONS))]
    ok, p_ok = after('Pickup', True)
    assert ok == [START, A['Pickup']] and not np.array_equal(p_failed, p_ok)
    assert np.allclose(after('Pickup', False, incremental=False)[1], p_failed, atol=1e-5)   # both paths alike
    assert after('Pickup', None)[0] == [START, A['Pickup']]               # no outcome given: the default, done
    assert after('MoveAhead', False)[0] == [START, A['MoveAhead']]       # a blocked move is not a failed click
    moves = dataclasses.replace(TINY, failed_moves=True)                   # unless blocked moves are failures too
    assert after('MoveAhead', False, config=moves)[0] == [START, failed_id(A['MoveAhead'], len(ACTIONS))]
    assert after('MoveAhead', True, config=moves)[0] == [START, A['MoveAhead']]
    assert after('RotateLeft', False, config=moves)[0] == [START, A['RotateLeft']]


def test_with_failed_moves_the_agent_does_not_walk_again_into_what_just_blocked_it(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    frame = np.random.default_rng(1).integers(0, 255, (64, 64, 3), dtype=np.uint8)

    def second(config, success: bool) -> str:
        torch.manual_seed(0)
        model = Performer(config, len(vocab))
        with torch.no_grad():
            model.action_head.linear.bias[A['MoveAhead']] += 50.0      # it always wants to walk on,
            model.action_head.linear.bias[A['Stop']] += 40.0           # else to stop
        agent = PerformerAgent(model, vocab)
        agent.reset(SimpleNamespace(instruction='Walk to the sofa.'))
        assert agent.act(Observation(rgb=frame))[0] == 'MoveAhead'
        return agent.act(Observation(rgb=frame, last_action_success=success))[0]

    moves = dataclasses.replace(TINY, failed_moves=True)
    assert second(moves, True) == 'MoveAhead'
    assert second(moves, False) in ('RotateLeft', 'RotateRight')      # the way round starts with a turn
    assert second(TINY, False) == 'MoveAhead'            # without failed_moves it does not know it was blocked


def test_recovery_needs_the_failure_input():
    with pytest.raises(ValueError, match='--failure-input'):
        TrainConfig(recovery=0.3)
    assert TrainConfig(recovery=0.3, model=PerformerConfig(failure_input=True)).recovery == 0.3
    with pytest.raises(ValueError, match='recovery must be'):
        TrainConfig(recovery=-0.1, model=PerformerConfig(failure_input=True))


def test_a_run_can_start_from_a_performer_without_the_failure_input(folder, tmp_path):
    plain_model = dataclasses.replace(TINY, failure_input=False)
    base = dict(demonstrations=str(folder), batch_size=4, bucket=2, warmup_updates=1, val_fraction=0.3, threads=1,
                device='cpu', progress=False, max_updates=2, log_every=1)
    train(TrainConfig(**base, out=str(tmp_path / 'plain'), model=plain_model))
    source, vocab, _ = load_checkpoint(tmp_path / 'plain' / 'last.pt')
    model = Performer(TINY, len(vocab))
    warm_start(model, vocab, tmp_path / 'plain' / 'last.pt')
    theirs, mine = source.state_dict(), model.state_dict()
    assert all(torch.equal(mine[k], theirs[k]) for k in theirs if k != 'actions.embedding.weight')
    rows, n = mine['actions.embedding.weight'], len(ACTIONS)
    assert torch.equal(rows[:n + 1], theirs['actions.embedding.weight'])
    assert torch.equal(rows[failed_id(A['Pickup'], n)], rows[A['Pickup']])     # a failed Pickup starts as Pickup
    summary = train(TrainConfig(**base, out=str(tmp_path / 'warm'), model=TINY, recovery=0.5,
                                init=str(tmp_path / 'plain' / 'last.pt')))
    assert summary['finished']
    with pytest.raises(ValueError, match='has the failure input'):
        warm_start(Performer(plain_model, len(vocab)), vocab, tmp_path / 'warm' / 'last.pt')
    with pytest.raises(ValueError, match='another model'):
        warm_start(Performer(dataclasses.replace(TINY, d_model=64, heads=2), len(vocab)), vocab,
                   tmp_path / 'plain' / 'last.pt')
