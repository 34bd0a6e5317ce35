"""The learned questioner's model (dialfred_questioner.model, no ROS).

Claims: the two decisions have the right shapes and are distributions; `log_prob` of a sampled
question is the log-probability `sample` returned (the path RL's policy gradient takes); direction
and none name no object; the dialogue so far and the step change the state (the original read only
the instruction); a tiny supervised run learns a handful of (situation -> question) pairs.
"""

from __future__ import annotations

import torch

from dialfred_performer.preprocess import AskedQA, Vocabulary, encode_language
from dialfred_questioner.model import Questioner, QuestionerConfig, needs_object, output_tokens, type_tokens
from dialfred_sim.protocol import QA, Question

torch.set_num_threads(1)
NOUNS = ('apple', 'fridge', 'mug', 'cabinet')
INSTRUCTIONS = ['put the apple in the fridge', 'pick up the mug', 'open the cabinet', 'go to the fridge']


def batch(vocab, items):
    """items: (instruction, dialogue, step) -> the encode() inputs of a padded batch."""
    langs = [encode_language(vocab, ins, dialogue) for ins, dialogue, _ in items]
    L = max(len(x) for x in langs)
    ids = torch.zeros(len(items), L, dtype=torch.long)
    types = torch.zeros_like(ids)
    valid = torch.zeros(len(items), L, dtype=torch.bool)
    for b, x in enumerate(langs):
        ids[b, :len(x)] = torch.tensor(x.ids)
        types[b, :len(x)] = torch.tensor(x.types)
        valid[b, :len(x)] = True
    return ids, types, valid, torch.tensor([s for *_, s in items])


def make(seed=0):
    vocab = Vocabulary.build(INSTRUCTIONS + ['the apple is to your left in the fridge .'])
    torch.manual_seed(seed)
    return Questioner(QuestionerConfig(embedding=16, hidden=32, image=8, dropout=0.0), len(vocab), NOUNS), vocab


def test_decisions_are_distributions_and_log_prob_matches_sample():
    model, vocab = make()
    ids, types, valid, steps = batch(vocab, [(i, [], 0) for i in INSTRUCTIONS])
    enc = model.encode(ids, types, valid, torch.randn(4, 8), steps)
    type_logp, noun_logp = model.decide(enc)
    assert type_logp.shape == (4, len(type_tokens())) and noun_logp.shape == (4, len(NOUNS))
    assert torch.allclose(type_logp.exp().sum(-1), torch.ones(4)) and torch.allclose(noun_logp.exp().sum(-1), torch.ones(4))
    g = torch.Generator().manual_seed(0)
    for _ in range(5):
        qtypes, nouns, lp = model.sample(enc, generator=g)
        assert ((nouns >= 0) == needs_object(qtypes)).all()
        assert torch.allclose(model.log_prob(enc, qtypes, nouns), lp, atol=1e-5)
    assert model.value(enc).shape == (4,)
    assert (model.entropy(enc, qtypes) >= 0).all()
    a = model.sample(enc, greedy=True)
    b = model.sample(enc, greedy=True)
    assert all(torch.equal(x, y) for x, y in zip(a, b))


def test_the_dialogue_so_far_and_the_step_change_the_state():
    model, vocab = make()
    qa = AskedQA(QA(Question('location', 'apple'), True, 'The apple is to your left in the fridge.'), 0)
    ids, types, valid, steps = batch(vocab, [(INSTRUCTIONS[0], [], 0), (INSTRUCTIONS[0], [qa], 0),
                                             (INSTRUCTIONS[0], [qa], 5)])
    enc = model.encode(ids, types, valid, torch.zeros(3, 8), steps)
    ctx = enc['context']
    assert not torch.allclose(ctx[0], ctx[1]) and not torch.allclose(ctx[1], ctx[2])


def test_output_tokens_refuse_nouns_named_like_type_tokens():
    assert output_tokens(['apple', 'apple'])[-1] == 'apple' and output_tokens(['apple']).count('apple') == 1
    try:
        output_tokens(['none'])
    except ValueError as exc:
        assert 'none' in str(exc)
    else:
        raise AssertionError('a noun named like a type token was accepted')


def test_a_tiny_supervised_run_learns_which_question_fits():
    model, vocab = make(1)
    # instruction k -> (type, noun): location of the apple, appearance of the mug, none, direction
    targets = [(1, 0), (2, 2), (0, -1), (3, -1)]
    ids, types, valid, steps = batch(vocab, [(i, [], 0) for i in INSTRUCTIONS])
    image = torch.randn(4, 8, generator=torch.Generator().manual_seed(2))
    qtypes = torch.tensor([t for t, _ in targets])
    nouns = torch.tensor([n for _, n in targets])
    opt = torch.optim.Adam(model.parameters(), lr=1e-2)
    for _ in range(150):
        loss = -model.log_prob(model.encode(ids, types, valid, image, steps), qtypes, nouns).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.05
    got_types, got_nouns, _ = model.sample(model.encode(ids, types, valid, image, steps), greedy=True)
    assert got_types.tolist() == qtypes.tolist() and got_nouns.tolist() == nouns.tolist()


def test_length_chunks_group_equal_lengths_within_the_budget_and_cover_every_row_once():
    from dialfred_questioner.policy import length_chunks
    lengths = [5, 3, 5, 9, 3, 5, 40, 5]
    chunks = length_chunks(lengths, token_budget=12)
    assert sorted(k for c in chunks for k in c) == list(range(len(lengths)))
    assert all(len({lengths[k] for k in c}) == 1 for c in chunks)           # one length per chunk
    assert all(len(c) * lengths[c[0]] <= 12 or len(c) == 1 for c in chunks)  # the budget, or a row alone
    assert [lengths[c[0]] for c in chunks] == sorted(lengths[c[0]] for c in chunks)
    assert chunks == [[1, 4], [0, 2], [5, 7], [3], [6]]
    assert length_chunks([]) == []


def test_scoring_records_by_length_chunks_gives_one_padded_batch_s_numbers_in_the_records_order():
    """The RL update scores its decisions over chunks of one length (a long dialogue beside short ones
    made the padded batch's backward pass grow with its length squared); the numbers, and their
    gradients, must be those of the single padded batch."""
    from dialfred_questioner.policy import Record, batch_records, score_records
    model, vocab = make()
    model.eval()
    g = torch.Generator().manual_seed(1)
    qa = AskedQA(QA(Question('location', 'apple'), True, 'the apple is to your left in the fridge .'), 0)
    records = []
    for k in range(9):
        lang = encode_language(vocab, INSTRUCTIONS[k % 4], [qa] * (k % 3 + (6 if k == 4 else 0)))
        records.append(Record(lang.ids, lang.types, torch.randn(8, generator=g), k, k % len(type_tokens()), k % 4))
    b = batch_records(records)
    enc = model.encode(b['lang_ids'], b['lang_types'], b['lang_valid'], b['image'], b['steps'])
    whole = (model.log_prob(enc, b['types'], b['nouns']), model.entropy(enc, b['types']), model.value(enc))
    whole[0].sum().backward()
    grad = model.encoder.weight_hh_l0.grad.clone()
    model.zero_grad()
    chunked = score_records(model, records, token_budget=40)
    for a, c in zip(whole, chunked):
        assert torch.allclose(a, c, atol=1e-5)
    chunked[0].sum().backward()
    assert torch.allclose(grad, model.encoder.weight_hh_l0.grad, atol=1e-5)
    assert [t.shape for t in score_records(model, [])] == [torch.Size([0])] * 3
