"""Answers at every step of a demonstration, and the items that teach the performer to act on them
(dialfred_performer.data: AnswerLog, answers_at, stream_dialogue; preprocess.encode_language(stream=True)).

Claims: the log of changes reads back, at every step of real valid_unseen demonstrations, exactly what
the oracle says there (the looks at step 0 and the middle); the paper's items of a logged folder are
those of a folder made the old way (QAs at step 0 and the middle only); a stream item asks only at or
after its first step, only types the log has, and hears the oracle of its step; the stream encoding
drops repeats, marks superseded answers and restarts positions, and its budget lets superseded answers
give way first; a tiny training run with stream items writes a model that reads streams; stream items
are refused without the stream encoding or on a folder logged the old way. A guided walk's blocked moves
(`blocked_steps`) are blocked in the world, and --blocked bumps into each before the walk's way round.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from dialfred_performer.data import (DIALOGUES_FILE, DemonstrationDataset, answers_at, load_dialogues, oracle_qas,
                                     paper_steps, qa_key, stream_dialogue)
from dialfred_performer.model import PerformerConfig, load_checkpoint
from dialfred_performer.prepare import VOCABULARY_FILE, PrepareConfig, prepare
from dialfred_performer.preprocess import NEVER, STREAM_SLOT, AskedQA, Vocabulary, encode_language, qa_to_dict
from dialfred_performer.train import TrainConfig, train
from dialfred_sim.protocol import QA, Question

pytestmark = pytest.mark.usefixtures('restore_torch_globals')


@pytest.fixture(scope='module')
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp('streams') / 'valid_unseen_64'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=5, out=str(out), progress=False))
    return out


def _as_text(qas):
    return [(a.step, *qa_key(a), a.qa.valid, a.qa.answer, a.qa.reason) for a in qas]


def test_the_log_reads_back_what_the_oracle_says_at_every_step(folder):
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.tasks.demonstrations import load_demonstrations
    demo = load_demonstrations(folder)
    dialogues = load_dialogues(folder / DIALOGUES_FILE)
    env = DialfredEnv(resolution=64)
    changes = 0
    for task in demo.tasks:
        log = dialogues[task['task_id']]
        assert log.every_step
        env.reset(options={'task_id': task['task_id']})
        n = len(task['actions'])
        for step in range(n + 1):
            looks = step in paper_steps(task)
            said = oracle_qas(env, task['object_nouns'], step, looks=looks)
            types = None if looks else ('location', 'direction')
            assert _as_text(answers_at(log.qas, step, types)) == _as_text(said), (task['task_id'], step)
            if step < n:
                name, x, y, _ = task['actions'][step]
                env.step({'action': name, 'pixel': (x, y)})
        changes += sum(a.step > 0 for a in log.qas)
    env.close()
    assert changes > 0                    # answers do change along the way, and only changes are stored


def test_paper_items_of_a_logged_folder_are_those_of_one_made_the_old_way(folder, tmp_path):
    """QAs at step 0 and the middle only (the format before the log): the same paper items."""
    for name in ('meta.json', 'tasks.jsonl', 'frames.npy', VOCABULARY_FILE):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    logged = load_dialogues(folder / DIALOGUES_FILE)
    tasks = [json.loads(line) for line in (folder / 'tasks.jsonl').read_text().splitlines()]
    lines = []
    for t in tasks:
        qas = [a for s in paper_steps(t) for a in answers_at(logged[t['task_id']].qas, s)]
        lines.append(json.dumps({'task_id': t['task_id'], 'qas': [qa_to_dict(a) for a in qas]}) + '\n')
    (tmp_path / DIALOGUES_FILE).write_text(''.join(lines))
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    new, old = (DemonstrationDataset(f, vocab, 64, seed=3) for f in (folder, tmp_path))
    assert not any(d.every_step for d in load_dialogues(tmp_path / DIALOGUES_FILE).values())
    assert len(new) == len(old) == 5 * 8
    for i in range(len(new)):
        assert _as_text(new.dialogue(i)) == _as_text(old.dialogue(i)), i
    with pytest.raises(ValueError, match='answers of every step'):
        DemonstrationDataset(tmp_path, vocab, 64, streams=2, stream=True)
    with pytest.raises(ValueError, match='stream encoding'):
        DemonstrationDataset(folder, vocab, 64, streams=2)


def test_a_stream_item_hears_the_oracle_of_each_step_it_asks_at(folder):
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    ds = DemonstrationDataset(folder, vocab, 64, seed=1, streams=6, stream=True)
    assert ds.per_task == 8 + 6 and len(ds) == 5 * 14
    logs = load_dialogues(folder / DIALOGUES_FILE)
    asked_steps, every_step_items = set(), 0
    for index in range(len(ds)):
        k, c = divmod(index, ds.per_task)
        if c < 8:
            continue
        task = ds.demo.tasks[ds.task_indices[k]]
        log = logs[task['task_id']].qas
        qas = ds.dialogue(index)
        assert qas == ds.dialogue(index)                 # drawn from (seed, index): the same every time
        steps = sorted({a.step for a in qas})
        assert all(0 <= s < ds.steps_of(ds.task_indices[k]) for s in steps)
        for a in qas:
            assert a in answers_at(log, a.step, (a.qa.question.question_type,))
        asked_steps |= set(steps)
        every_step_items += bool(steps) and steps == list(range(steps[0], ds.steps_of(ds.task_indices[k])))
        item = ds[index]
        assert item['lang_positions'].max() < 256 and (item['lang_until'] <= NEVER).all()
    assert every_step_items >= 3 and len(asked_steps) > 5


def test_the_stream_encoding_drops_repeats_and_lets_superseded_answers_give_way_first():
    vocab = Vocabulary.build(['pick up the apple', 'the apple is to your left in the fridge .',
                              'the apple is in front of you on the table .', 'you should turn left .'])
    left = QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.')
    ahead = QA(Question('location', 'apple'), True, 'The apple is in front of you on the table.')
    turn = QA(Question('direction'), True, 'You should turn left.')
    dialogue = [AskedQA(left, 0), AskedQA(turn, 0), AskedQA(left, 2), AskedQA(ahead, 3), AskedQA(turn, 5)]
    lang = encode_language(vocab, 'Pick up the apple.', dialogue, stream=True)
    ins = len(encode_language(vocab, 'Pick up the apple.'))
    spans = sorted({(s, u) for s, u in zip(lang.steps[ins:], lang.until[ins:])})
    assert spans == [(0, 3), (0, NEVER), (3, NEVER)]          # the repeats at 2 and 5 add nothing
    assert lang.positions[:ins] == tuple(range(ins)) and min(lang.positions[ins:]) == ins
    # each (type, noun) owns a slot, by first appearance: the location's answers restart at the instruction's
    # end, the direction's a slot later; what is heard together never shares a position
    starts = {(t, s): p for t, s, p in reversed(list(zip(lang.types[ins:], lang.steps[ins:], lang.positions[ins:])))}
    assert sorted(starts.values()) == [ins, ins, ins + STREAM_SLOT]
    for step in (0, 3, 5):
        seen = [p for s, u, p in zip(lang.steps, lang.until, lang.positions) if s <= step < u]
        assert len(seen) == len(set(seen))
    plain = encode_language(vocab, 'Pick up the apple.', dialogue)
    assert len(plain) > len(lang) and plain.positions is None and plain.until is None
    # over the budget: the superseded answer (step 0, until 3) goes first, the current ones stay
    size = len(lang) - (lang.until.count(3))
    cut = encode_language(vocab, 'Pick up the apple.', dialogue, max_tokens=size, stream=True)
    assert len(cut) == size and 3 not in cut.until and sorted(set(cut.steps[ins:])) == [0, 3]
    assert set(cut.positions[ins:]) <= set(lang.positions[ins:])      # slots are kept when answers give way
    # a table too small for a slot a key wraps them onto one another, and no position passes the table
    small = encode_language(vocab, 'Pick up the apple.', dialogue, stream=True, table=ins + STREAM_SLOT)
    assert max(small.positions) < ins + STREAM_SLOT


def test_stream_dialogue_asks_nothing_of_an_empty_log():
    assert stream_dialogue([], 10, np.random.default_rng(0)) == []


def test_a_tiny_run_with_stream_items_trains_a_model_that_reads_streams(folder, tmp_path):
    model = PerformerConfig(resolution=64, d_model=32, heads=2, layers=1, ff=64, max_steps=64, stream_answers=True)
    cfg = TrainConfig(demonstrations=str(folder), out=str(tmp_path / 'run'), model=model, epochs=1, batch_size=4,
                      bucket=2, warmup_updates=1, log_every=2, checkpoint_every=3, val_fraction=0.3, threads=1,
                      device='cpu', progress=False, streams=2)
    summary = train(cfg)
    assert summary['finished'] and summary['train_episodes'] + summary['val_episodes'] == 5 * 10
    net, _, info = load_checkpoint(tmp_path / 'run' / 'last.pt')
    assert info['config'].stream_answers
    with pytest.raises(ValueError, match='--stream-answers'):
        TrainConfig(demonstrations=str(folder), streams=2)


def test_reworded_answers_say_the_same_in_the_annotators_words_and_a_repeat_stays_a_repeat():
    from dialfred_performer.data import reword
    from dialfred_performer.mapper.words import read_answer
    left = QA(Question('direction'), True, 'You should turn left.')
    where = QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.')
    unknown = QA(Question('location', 'apple'), False, "I don't know.", 'not in the room')
    dialogue = [AskedQA(left, 0), AskedQA(where, 0), AskedQA(unknown, 1), AskedQA(left, 4)]
    said = reword(dialogue, 1.0, (0, 7))
    assert said == reword(dialogue, 1.0, (0, 7)) and said != reword(dialogue, 1.0, (0, 8))
    assert said[0].qa.answer != left.answer and said[0].qa.answer == said[3].qa.answer     # a repeat stays one
    assert read_answer('direction', said[0].qa.answer, '').turn_deg == 90                 # still "left"
    assert said[2].qa == unknown                                                          # invalid: as it was
    assert [a.step for a in said] == [0, 0, 1, 4]
    assert reword(dialogue, 0.0, (0, 7)) == dialogue
    shares = [sum(a.qa.answer != b.qa.answer for a, b in zip(reword(dialogue[:2], 0.5, (0, n)), dialogue[:2]))
              for n in range(200)]
    assert 0.35 < sum(shares) / 400 < 0.65


def test_a_reworded_training_extends_the_vocabulary_with_the_annotators_words_keeping_every_id(folder, tmp_path):
    from dialfred_performer.data import paraphrase_texts
    from dialfred_performer.train import load_vocabulary
    base = Vocabulary.load(folder / VOCABULARY_FILE)
    cfg = TrainConfig(demonstrations=str(folder), out=str(tmp_path), reworded=0.3)
    vocab = load_vocabulary(cfg)
    assert vocab.words[:len(base)] == base.words and len(vocab) > len(base)
    texts = paraphrase_texts(folder)
    assert texts and all(vocab.index['<unk>'] not in vocab.ids(t.split()) for t in texts)
    with pytest.raises(ValueError, match='reworded'):
        TrainConfig(demonstrations=str(folder), reworded=1.5)


def test_a_detour_builds_episodes_join_the_training_held_out_with_their_tasks(folder, tmp_path):
    """prepare-performer --detours: the same tasks with a detour each; DemonstrationDataset(detours=...)
    reads both builds as one (task ids tagged, frames joined), a detour's wrong moves are no targets, its
    answers are logged at every step, and a detour is held out with its task."""
    from dialfred_performer.data import DETOUR_TAG, base_task_id
    from dialfred_performer.train import load_data
    detours = tmp_path / 'detours'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=5, out=str(detours), progress=False,
                          detours=True))
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    ds = DemonstrationDataset(folder, vocab, 64, streams=2, stream=True, detours=detours)
    assert len(ds.demo.tasks) == 10 and ds.demo.tasks[5]['task_id'].endswith(DETOUR_TAG)
    strayed = [k for k, t in enumerate(ds.demo.tasks) if t.get('detour')]
    assert strayed and all(k >= 5 for k in strayed)
    k = strayed[0]
    item = ds[ds.task_indices.index(k) * ds.per_task]
    at, wrong, _ = ds.demo.tasks[k]['detour']
    assert item['action_valid'][at:at + wrong].tolist() == [False] * wrong and item['action_valid'][:at].all()
    from dialfred_sim.tasks.demonstrations import load_demonstrations
    own = load_demonstrations(detours)
    assert np.array_equal(np.asarray(ds.demo.frames_of(k)), np.asarray(own.frames_of(k - 5)))   # the joined rows
    assert ds.dialogues[ds.demo.tasks[k]['task_id']].every_step
    cfg = TrainConfig(demonstrations=str(folder), detours=str(detours), out=str(tmp_path / 'run'), val_fraction=0.3,
                      streams=2, model=PerformerConfig(stream_answers=True))
    data = load_data(cfg, vocab)
    held = {base_task_id(data.train.demo.tasks[data.train.task_indices[i // data.train.per_task]]['task_id'])
            for i in data.val_items}
    trained = {base_task_id(data.train.demo.tasks[data.train.task_indices[i // data.train.per_task]]['task_id'])
               for i in data.train_items}
    assert held and not held & trained


@pytest.fixture(scope='module')
def guided(tmp_path_factory):
    out = tmp_path_factory.mktemp('guided') / 'guided'
    prepare(PrepareConfig(split='valid_unseen', resolution=64, workers=1, limit=5, out=str(out), progress=False,
                          guided=True))
    return out


def test_a_guided_build_walks_as_the_direction_answers_say_and_its_items_hear_them_at_every_step(folder, guided,
                                                                                                   tmp_path):
    """prepare-performer --guided: each task's last go-to walked as the oracle's direction answer of each step
    says (a sidestep where the way it says is blocked); every item of such an episode hears the direction at
    every step; a task without a walk is left out; a guided episode is held out with its task."""
    from dialfred_performer.data import GUIDED_ACTION, GUIDED_TAG, base_task_id
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    ds = DemonstrationDataset(folder, vocab, 64, streams=2, stream=True, guided=guided)
    walked = [k for k, t in enumerate(ds.demo.tasks) if t.get('guided')]
    assert walked and all(ds.demo.tasks[k]['task_id'].endswith(GUIDED_TAG) for k in walked)
    told = obeyed = 0
    for k in walked:
        task = ds.demo.tasks[k]
        assert task['success'] and task['failed_actions'] == 0, task['task_id']
        at, n, _ = task['guided']
        log = ds.dialogues[task['task_id']].qas
        for step in range(at, at + n):
            said = answers_at(log, step, ('direction',))[0].qa.answer
            told += 1
            obeyed += task['actions'][step][0] == GUIDED_ACTION.get(said, task['actions'][step][0])
        for c in range(ds.per_task):
            heard = ds.dialogue(ds.task_indices.index(k) * ds.per_task + c)
            steps = [a.step for a in heard if a.qa.question.question_type == 'direction']
            assert steps == list(range(ds.steps_of(k)))        # the direction at every step, in step order
    assert told and obeyed / told >= 0.8
    left_out = [k for k, t in enumerate(ds.demo.tasks) if t['task_id'].endswith(GUIDED_TAG) and not t.get('guided')]
    assert not set(left_out) & set(ds.task_indices)
    assert base_task_id('valid_unseen/000001' + GUIDED_TAG) == 'valid_unseen/000001'
    from dialfred_performer.train import load_data
    cfg = TrainConfig(demonstrations=str(folder), guided=str(guided), out=str(tmp_path / 'run'), val_fraction=0.3,
                      streams=2, model=PerformerConfig(stream_answers=True))
    data = load_data(cfg, vocab)
    task_of = lambda i: base_task_id(data.train.demo.tasks[data.train.task_indices[i // data.train.per_task]]['task_id'])
    held, trained = {task_of(i) for i in data.val_items}, {task_of(i) for i in data.train_items}
    assert held and not held & trained
    with pytest.raises(ValueError, match='guided'):
        DemonstrationDataset(folder, vocab, 64, guided=folder)
    with pytest.raises(ValueError, match='not both'):
        PrepareConfig(split='valid_unseen', detours=True, guided=True)


def test_a_guided_item_bumps_into_each_blocked_move_then_takes_the_walks_way_round(folder, guided):
    """--blocked: the steps `blocked_steps` reads off a guided walk are those where MoveAhead, which the direction
    answer said, is blocked in the world (replayed); an item with bumps fails a MoveAhead there (no target, the
    same frame after it, its failed id the next previous action) before the walk's own action; the held-out
    tasks and the plain episodes get none; --blocked needs the failed-move input and a guided build."""
    from dialfred_performer.data import GUIDED_TAG, MOVE_AHEAD, base_task_id, blocked_steps
    from dialfred_performer.nn.enc_action import failed_id
    from dialfred_sim.env import DialfredEnv
    from dialfred_sim.protocol import ACTIONS
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    plain = DemonstrationDataset(folder, vocab, 64, streams=1, stream=True, guided=guided)
    bumped = DemonstrationDataset(folder, vocab, 64, streams=1, stream=True, guided=guided, blocked=1.0)
    env = DialfredEnv(resolution=64)
    found = 0
    for pos, k in enumerate(bumped.task_indices):
        task = bumped.demo.tasks[k]
        steps = blocked_steps(task, bumped.dialogues[task['task_id']].qas)
        assert not steps or task['task_id'].endswith(GUIDED_TAG)
        for at in steps:
            env.reset(options={'task_id': base_task_id(task['task_id'])})
            for name, x, y, _ in task['actions'][:at]:
                env.step({'action': name, 'pixel': (x, y)})
            assert not env.step({'action': 'MoveAhead', 'pixel': (-1, -1)})[4]['last_action_success']
        index = pos * bumped.per_task
        item, before = bumped[index], plain[index]
        assert len(item['actions']) == len(before['actions']) + len(steps)
        for n, at in enumerate(steps):
            here = at + n                                  # the earlier bumps' rows come first
            assert item['actions'][here] == MOVE_AHEAD and not item['action_valid'][here]
            assert item['frame_ids'][here] == item['frame_ids'][here + 1]
            assert item['previous_actions'][here + 1] == failed_id(MOVE_AHEAD, len(ACTIONS))
            assert item['actions'][here + 1] == before['actions'][at] != MOVE_AHEAD
        found += len(steps)
    env.close()
    assert found, 'no blocked move in the guided walks of the first tasks: take more tasks'
    bumped.no_recovery = set(range(len(bumped.task_indices)))          # every task held out: no bumps
    assert all(len(bumped[i]['actions']) == len(plain[i]['actions']) for i in range(len(bumped)))
    with pytest.raises(ValueError, match='guided build'):
        DemonstrationDataset(folder, vocab, 64, blocked=0.5)
    with pytest.raises(ValueError, match='--failed-moves'):
        TrainConfig(demonstrations=str(folder), guided=str(guided), blocked=0.5,
                    model=PerformerConfig(failure_input=True))
    with pytest.raises(ValueError, match='needs failure_input'):
        PerformerConfig(failed_moves=True)


def test_without_stream_directions_only_the_guided_walks_hear_the_direction_at_many_steps(folder, guided):
    """--no-stream-directions: the stream items of the plain episodes ask no direction; the paper's items and
    every item of a guided walk keep theirs, the same as with it."""
    from dialfred_performer.data import GUIDED_TAG
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    both = DemonstrationDataset(folder, vocab, 64, streams=3, stream=True, guided=guided)
    some = DemonstrationDataset(folder, vocab, 64, streams=3, stream=True, guided=guided, stream_directions=False)
    papers = len(both.combinations)
    heard_before = 0
    for index in range(len(both)):
        pos, c = divmod(index, both.per_task)
        walk = both.demo.tasks[both.task_indices[pos]]['task_id'].endswith(GUIDED_TAG)
        before, after = both.dialogue(index), some.dialogue(index)
        if c < papers or walk:
            assert _as_text(after) == _as_text(before)
        else:
            heard_before += any(a.qa.question.question_type == 'direction' for a in before)
            assert not any(a.qa.question.question_type == 'direction' for a in after)
    assert heard_before


def test_with_fresh_directions_a_guided_item_hears_each_steps_direction_at_that_step_only(folder, guided):
    """fresh_directions: the items' direction answers hold for their own step (the guided walk's at every step,
    the oldest giving way first over max_tokens); the other types' as before."""
    from dialfred_performer.data import GUIDED_TAG
    from dialfred_performer.preprocess import type_of_question
    vocab = Vocabulary.load(folder / VOCABULARY_FILE)
    ds = DemonstrationDataset(folder, vocab, 64, streams=1, stream=True, guided=guided, fresh=('direction',))
    plain = DemonstrationDataset(folder, vocab, 64, streams=1, stream=True, guided=guided)
    direction = type_of_question()['direction']
    walks = [pos for pos, k in enumerate(ds.task_indices) if ds.demo.tasks[k]['task_id'].endswith(GUIDED_TAG)]
    assert walks
    for pos in walks:
        item, before = ds[pos * ds.per_task], plain[pos * ds.per_task]
        spans = {(int(s), int(u)) for t, s, u in zip(item['lang_types'], item['lang_steps'], item['lang_until'])
                 if t == direction}
        assert spans and all(u == s + 1 for s, u in spans)
        last = ds.steps_of(ds.task_indices[pos]) - 1
        assert max(s for s, _ in spans) == last                  # the newest kept: the last step's
        others = lambda it: [(int(t), int(s)) for t, s in zip(it['lang_types'], it['lang_steps']) if t != direction]
        assert set(others(item)) <= set(others(before))
    with pytest.raises(ValueError, match='stream=True'):
        DemonstrationDataset(folder, vocab, 64, fresh=('direction',))
