"""The performer's one language path (dialfred_performer.preprocess, no ROS).

Claims: QA markers are single vocabulary tokens that the word tokenizer never splits; an oracle
answer goes to the same ids through the training path (dialogues.jsonl -> DemonstrationDataset) and
the evaluation path (PerformerAgent.hear); every QA keeps the step at which it was asked; the
vocabulary round-trips through JSON; the dataset gives every combination of question types.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from dialfred_performer.agent import PerformerAgent
from dialfred_performer.data import type_combinations, DemonstrationDataset, collate, generate_dialogues, vocabulary_texts
from dialfred_performer.model import Performer, PerformerConfig
from dialfred_performer.preprocess import (FIXED_TOKENS, TYPE_INSTRUCTION, AskedQA, Vocabulary, type_of_question,
                                           encode_language, frame_tensor, qa_text, qa_tokens, tokenize)
from dialfred_sim.protocol import QA, Question
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.demonstrations import build_demonstrations

torch.set_num_threads(1)
RES = 64


@pytest.fixture(scope='module')
def demo_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp('performer_demo')
    build_demonstrations('valid_unseen', RES, out, workers=1, limit=3, progress=False)
    generate_dialogues(out)
    return out


def test_markers_are_single_tokens_never_split():
    assert tokenize('<q> <loc> apple <a> The apple is to your left, in the fridge.') == \
        ['<q>', '<loc>', 'apple', '<a>', 'the', 'apple', 'is', 'to', 'your', 'left', ',', 'in', 'the', 'fridge', '.']
    vocab = Vocabulary.build(['the apple'])
    qa = QA(Question('location', 'apple'), True, 'The apple is here.')
    toks = qa_tokens(qa)
    assert toks[:2] == ['<q>', '<loc>'] and '<a>' in toks
    ids = vocab.ids(toks)
    for marker in ('<q>', '<loc>', '<a>'):
        assert ids[toks.index(marker)] == FIXED_TOKENS.index(marker) != vocab.index['<unk>']
    assert tokenize(qa_text(qa)) == toks          # the readable string re-tokenizes to the same tokens
    assert qa_tokens(QA(Question('direction'), False, reason='no task'))[-2:] == ['<a>', '<invalid>']


def test_vocabulary_round_trips_through_json(tmp_path):
    vocab = Vocabulary.build(['Take the key chain.', "You don't need to move."])
    vocab.save(tmp_path / 'vocab.json')
    assert Vocabulary.load(tmp_path / 'vocab.json') == vocab
    assert vocab.words[:len(FIXED_TOKENS)] == FIXED_TOKENS and vocab.index['<pad>'] == 0
    assert vocab.ids(['zebra']) == [vocab.index['<unk>']]
    with pytest.raises(ValueError):
        Vocabulary(['apple', '<pad>'])


def test_each_qa_keeps_the_step_it_was_asked_at():
    vocab = Vocabulary.build(['open the fridge', 'the fridge is to your left', 'you should turn left'])
    dialogue = [AskedQA(QA(Question('location', 'fridge'), True, 'The fridge is to your left.'), 0),
                AskedQA(QA(Question('direction'), True, 'You should turn left.'), 5)]
    lang = encode_language(vocab, 'Open the fridge.', dialogue)
    n_ins = len(tokenize('Open the fridge.'))
    n_loc = len(qa_tokens(dialogue[0].qa))
    assert lang.types[:n_ins] == (TYPE_INSTRUCTION,) * n_ins and lang.steps[:n_ins] == (0,) * n_ins
    assert set(lang.types[n_ins:n_ins + n_loc]) == {type_of_question()['location']}
    assert set(lang.steps[n_ins + n_loc:]) == {5} and set(lang.types[n_ins + n_loc:]) == {type_of_question()['direction']}
    short = encode_language(vocab, 'Open the fridge.', dialogue, max_tokens=n_ins + len(qa_tokens(dialogue[1].qa)))
    assert short.steps[n_ins:] == (5,) * (len(short) - n_ins)      # the oldest QA is dropped first


def test_oracle_answer_gets_the_same_ids_in_training_and_in_evaluation(demo_dir):
    """An answer of the real oracle core, through dialogues.jsonl and the dataset (training) and
    through PerformerAgent.hear (evaluation), becomes the same token ids, types and steps."""
    vocab = Vocabulary.build(vocabulary_texts(demo_dir))
    rows = [json.loads(line) for line in (demo_dir / 'dialogues.jsonl').read_text().splitlines()]
    assert len(rows) == 3 and all(any(q['valid'] for q in r['qas']) for r in rows)
    everything = type_combinations().index(('location', 'appearance', 'direction'))
    ds = DemonstrationDataset(demo_dir, vocab, RES, combinations=type_combinations())
    task = load_split('valid_unseen')[0].public()
    index = everything          # task 0, all three types
    item, dialogue = ds[index], ds.dialogue(index)
    assert dialogue and {a.qa.question.question_type for a in dialogue} == {'location', 'appearance', 'direction'}
    agent = PerformerAgent(Performer(PerformerConfig(resolution=RES, d_model=32, heads=2, layers=1, ff=32), len(vocab)),
                           vocab)
    agent.reset(task, seed=0)
    frame = np.zeros((RES, RES, 3), np.uint8)
    for asked in dialogue:               # the agent hears each QA at the step it was asked
        while agent.step < asked.step:
            agent.act(frame)
        agent.hear(QA(Question(asked.qa.question.question_type, asked.qa.question.object_noun),
                      asked.qa.valid, asked.qa.answer, asked.qa.reason))
    lang = agent.language_input()
    assert list(lang.ids) == item['lang_ids'].tolist()
    assert list(lang.types) == item['lang_types'].tolist() and list(lang.steps) == item['lang_steps'].tolist()
    assert vocab.index['<unk>'] not in lang.ids


def test_dataset_gives_every_combination_of_question_types(demo_dir):
    vocab = Vocabulary.build(vocabulary_texts(demo_dir))
    ds = DemonstrationDataset(demo_dir, vocab, RES)
    assert len(type_combinations()) == 8 and len(ds) == 3 * 8
    for c, combo in enumerate(type_combinations()):
        types = {a.qa.question.question_type for a in ds.dialogue(c)}
        assert types == set(combo)
    steps = {a.step for i in range(len(ds)) for a in ds.dialogue(i)}
    assert 0 in steps and len(steps) > 1             # asked at the start and mid-episode
    batch = collate([ds[0], ds[9], ds[23]])
    T = batch['actions'].shape[1]
    assert batch['frames'].shape == (3, T, 3, RES, RES) and batch['step_valid'].sum(1).tolist() == \
        [len(ds[i]['actions']) for i in (0, 9, 23)]
    assert (batch['target_cells'][~batch['step_valid']] == -1).all()


def test_frames_are_resized_by_the_same_function():
    rgb = np.random.default_rng(0).integers(0, 256, (128, 128, 3), dtype=np.uint8)
    one = frame_tensor(rgb, 64)
    assert one.shape == (3, 64, 64) and torch.allclose(frame_tensor(rgb[None], 64)[0], one)
    assert torch.allclose(one[:, 0, 0], torch.tensor(rgb[:2, :2].reshape(-1, 3).mean(0) / 255.0, dtype=torch.float32))
