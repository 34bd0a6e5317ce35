"""Instruction augmentation (no ROS): templated step-by-step sentences and a main-action instruction.

The claims follow the paper's "Instruction augmentation" paragraph and its table of the 25 tasks.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from dialfred_sim.tasks.instructions import StepPhrase, tokenize, vocabulary
from dialfred_sim.tasks.types import TASK_TYPES, make_instructions, task_types

S = StepPhrase


def put(obj, receptacle, prep='on'):
    return S('put', obj, receptacle, prep)


CLEAN = [put('ladle', 'sink basin', 'in'), S('toggle_on', 'faucet'), S('toggle_off', 'faucet'),
         S('pickup', 'ladle')]
COOL = [S('open', 'fridge'), put('potato', 'fridge', 'in'), S('close', 'fridge'), S('open', 'fridge'),
        S('pickup', 'potato'), S('close', 'fridge')]
HEAT = [S('open', 'microwave'), put('apple', 'microwave', 'in'), S('close', 'microwave'),
        S('toggle_on', 'microwave'), S('toggle_off', 'microwave'), S('open', 'microwave'),
        S('pickup', 'apple'), S('close', 'microwave')]
SINGLE = {
    'Clean': CLEAN, 'Close': [S('close', 'drawer')], 'Cool': COOL, 'Heat': HEAT, 'Move': [S('goto', 'cart')],
    'Open': [S('open', 'safe')], 'Pick': [S('pickup', 'egg')], 'Put': [put('mug', 'plate')],
    'Slice': [S('slice', 'lettuce')], 'Turn on': [S('toggle_on', 'desk lamp')],
    'Turn off': [S('toggle_off', 'microwave')],
}
EXAMPLES = {
    **SINGLE,
    'Move & Clean': [S('goto', 'sink basin')] + CLEAN,
    'Move & Close': [S('goto', 'laptop'), S('close', 'laptop')],
    'Move & Cool': [S('goto', 'fridge')] + COOL,
    'Move & Heat': [S('goto', 'microwave')] + HEAT,
    'Move & Open': [S('goto', 'microwave'), S('open', 'microwave')],
    'Move & Pick': [S('goto', 'counter top'), S('pickup', 'fork')],
    'Move & Put': [S('goto', 'counter top'), put('fork', 'counter top')],
    'Move & Slice': [S('goto', 'bread'), S('slice', 'bread')],
    'Move & Turn on': [S('goto', 'desk lamp'), S('toggle_on', 'desk lamp')],
    'Open & Pick & Close': [S('open', 'microwave'), S('pickup', 'cup'), S('close', 'microwave')],
    'Open & Put & Close': [S('open', 'fridge'), put('apple', 'fridge', 'in'), S('close', 'fridge')],
    'Pick & Move': [S('pickup', 'mug'), S('goto', 'side table')],
    'Pick & Move & Put': [S('pickup', 'keychain'), S('goto', 'armchair'), put('keychain', 'armchair')],
    'Pick & Move & Slice': [S('pickup', 'knife'), S('goto', 'bread'), S('slice', 'bread')],
}
COLOURS = {'gray', 'grey', 'black', 'maroon', 'tan', 'olive', 'red', 'brown', 'silver', 'green', 'purple',
           'pink', 'blue', 'teal', 'white', 'khaki', 'navy', 'beige', 'orange', 'gold', 'yellow'}
SEEDS = range(50)


def main_verb(sentence):
    words = tokenize(sentence)
    return words[1] if words[0] in ('please', 'now') else words[0]


def all_outputs():
    for task_type in TASK_TYPES:
        for seed in SEEDS:
            yield task_type, *make_instructions(task_type, EXAMPLES[task_type], np.random.default_rng(seed))


def mains(task_type):
    return [make_instructions(task_type, EXAMPLES[task_type], np.random.default_rng(s))[1] for s in SEEDS]


def test_the_25_task_types_in_the_papers_table_order():
    assert len(TASK_TYPES) == 25 == len(set(TASK_TYPES))
    assert TASK_TYPES[:3] == ('Clean', 'Close', 'Cool')
    assert TASK_TYPES[11] == 'Move & Clean' and TASK_TYPES[-1] == 'Pick & Move & Slice'
    assert tuple(kind.name for kind in task_types())[:25] == TASK_TYPES    # registered in that order
    assert set(TASK_TYPES) == set(EXAMPLES)


@pytest.mark.parametrize('task_type', TASK_TYPES)
def test_every_type_gives_one_sentence_per_primitive_and_a_main_instruction(task_type):
    steps, main = make_instructions(task_type, EXAMPLES[task_type], np.random.default_rng(0))
    assert len(steps) == len(EXAMPLES[task_type])
    assert main.strip() and main.endswith('.') and main[0].isupper()
    assert main.count('.') == 1    # one sentence


def test_step_sentences_are_capitalised_and_end_with_a_period():
    for _, steps, _ in all_outputs():
        for sentence in steps:
            assert sentence[0].isupper() and sentence.endswith('.'), sentence


def test_step_sentences_follow_the_primitive_templates():
    steps, _ = make_instructions('Clean', CLEAN, np.random.default_rng(3))
    assert steps[0].endswith(' the ladle in the sink basin.')
    assert steps[0].split(' the ')[0].lower() in ('put', 'place', 'leave')
    assert steps[1].endswith(' on the faucet.') and steps[2].endswith(' off the faucet.')
    assert steps[3].endswith(' the ladle.')


def test_clean_main_instruction_uses_several_synonyms_across_seeds():
    verbs = {main_verb(m) for m in mains('Clean')}
    assert len(verbs & {'wash', 'clean', 'rinse'}) >= 2
    assert all(m.endswith(' the ladle.') for m in mains('Clean'))


def test_main_instruction_names_only_the_main_action():
    assert all('microwave' in m and 'open' in m.lower() for m in mains('Move & Open'))
    assert all(m.endswith('the potato.') and 'fridge' not in m.split(',')[-1] for m in mains('Move & Cool'))
    assert all(m.endswith(' the apple.') and 'microwave' not in m for m in mains('Heat'))
    assert all(m.endswith(' the mug to the side table.') for m in mains('Pick & Move'))
    assert all(m.endswith(' the apple in the fridge.') for m in mains('Open & Put & Close'))
    assert all(m.endswith(' the keychain on the armchair.') for m in mains('Pick & Move & Put'))
    assert all(m.endswith(' the bread with a knife.') for m in mains('Pick & Move & Slice'))
    assert all(m.endswith(' the cart.') for m in mains('Move'))


def test_move_and_clean_sometimes_says_where_to_go_and_sometimes_not():
    said = [m for m in mains('Move & Clean') if 'sink basin' in m]
    assert 0 < len(said) < len(SEEDS)
    assert all(', ' in m and m.endswith(' the ladle.') for m in said)


def test_saying_the_landmark_twice_becomes_a_grammatical_pronoun():
    for task_type in ('Move & Open', 'Move & Turn on', 'Move & Slice', 'Move & Put'):
        for m in mains(task_type):
            if ' and ' in m:
                assert m.endswith((' it.', ' it up.', ' it on.', ' on it.')), m
                assert not re.search(r'\b(up|on) it\.$', m) or task_type == 'Move & Put', m


def test_same_inputs_and_rng_state_give_the_same_output():
    for task_type in TASK_TYPES:
        a = make_instructions(task_type, EXAMPLES[task_type], np.random.default_rng(7))
        b = make_instructions(task_type, EXAMPLES[task_type], np.random.default_rng(7))
        assert a == b


def test_no_colour_is_ever_mentioned():
    for _, steps, main in all_outputs():
        assert not vocabulary(steps + [main]) & COLOURS


def test_unknown_task_type_is_refused():
    with pytest.raises(ValueError, match='unknown task type'):
        make_instructions('Juggle', [S('pickup', 'apple')], np.random.default_rng(0))


@pytest.mark.parametrize('task_type, steps', [
    ('Clean', CLEAN[:-1]),
    ('Move & Open', [S('open', 'microwave')]),
    ('Pick & Move', [S('goto', 'side table'), S('pickup', 'mug')]),
    ('Put', [S('pickup', 'mug')]),
])
def test_steps_that_do_not_match_the_type_are_refused(task_type, steps):
    with pytest.raises(ValueError, match='expects step kinds'):
        make_instructions(task_type, steps, np.random.default_rng(0))


def test_malformed_step_phrases_are_refused():
    with pytest.raises(ValueError):
        S('jump', 'apple')
    with pytest.raises(ValueError):
        S('put', 'apple')              # no receptacle
    with pytest.raises(ValueError):
        put('apple', 'fridge', 'under')


def test_tokenize_and_vocabulary_strip_punctuation_and_case():
    assert tokenize('Go to the sink basin, wash the ladle.') == ['go', 'to', 'the', 'sink', 'basin', 'wash',
                                                                   'the', 'ladle']
    assert vocabulary(['Open the fridge.', 'Open up the Fridge!']) == {'open', 'up', 'the', 'fridge'}
