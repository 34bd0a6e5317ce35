"""The oracle understands the words people use for objects (dialfred_oracle.nouns), without ROS.

Plurals, everyday names and the things Slice makes name the object of the catalog type a person
means; things that are not there still get "there is no ... here"."""

from __future__ import annotations

import pytest

from dialfred_oracle.answers import answer, check_answer
from dialfred_oracle.nouns import EVERYDAY_NAMES, key, meanings, singular
from dialfred_sim.ground_truth import ObjectFact, Snapshot, snapshot, task_object_ids
from dialfred_sim.tasks import load_split
from dialfred_sim.tasks.expert import replay
from dialfred_sim.catalog import load_catalog

from helpers import rerender

# What a person says -> the catalog type(s) meant. Several types where the words fit all of them
# equally (a sink is the Sink and its SinkBasin), and the nearest of those is answered about.
PHRASINGS = [
    # plurals
    ('apples', 'Apple'), ('Apples?', 'Apple'), ('the tomatoes', 'Tomato'), ('potatoes', 'Potato'),
    ('knives', 'Knife'), ('glasses', 'Cup'), ('dishes', 'Plate'), ('boxes', 'Box'), ('watches', 'Watch'),
    ('shelves', 'Shelf'), ('cell phones', 'CellPhone'), ('cellphones', 'CellPhone'), ('spoons', 'Spoon'),
    ('mugs', 'Mug'), ('pillows', 'Pillow'), ('eggs', 'Egg'), ('remote controls', 'RemoteControl'),
    ('credit cards', 'CreditCard'), ('alarm clocks', 'AlarmClock'), ('spray bottles', 'SprayBottle'),
    ('counters', 'CounterTop'), ('sofas', 'Sofa'), ('beds', 'Bed'), ('faucets', 'Faucet'), ('laptops', 'Laptop'),
    ('salt shakers', 'SaltShaker'), ('boxes of tissues', 'TissueBox'),
    # catalog plurals in the singular
    ('blind', 'Blinds'), ('curtain', 'Curtains'), ('boot', 'Boots'),
    # everyday names
    ('TV', 'Television'), ('the tv', 'Television'), ('telly', 'Television'), ('TVs', 'Television'),
    ('mobile phone', 'CellPhone'), ('my mobile', 'CellPhone'), ('phone', 'CellPhone'), ('smartphone', 'CellPhone'),
    ('kitchen counter', 'CounterTop'), ('countertop', 'CounterTop'), ('counter top', 'CounterTop'),
    ('counter', 'CounterTop'), ('worktop', 'CounterTop'),
    ('kitchen sink', ('Sink', 'SinkBasin')), ('bathroom sink', ('Sink', 'SinkBasin')),
    ('TV remote', 'RemoteControl'), ('remote', 'RemoteControl'), ('remote control', 'RemoteControl'),
    ('dustbin', 'GarbageCan'), ('rubbish bin', 'GarbageCan'), ('trash can', 'GarbageCan'), ('bins', 'GarbageCan'),
    ('notebook', 'Book'), ('notebook computer', 'Laptop'), ('couch', 'Sofa'), ('settee', 'Sofa'),
    ('arm chair', 'ArmChair'), ('armchair', 'ArmChair'), ('refrigerator', 'Fridge'), ('microwave oven', 'Microwave'),
    ('tap', 'Faucet'), ('bedside table', 'SideTable'), ('nightstand', 'SideTable'), ('keys', 'KeyChain'),
    ('teddy', 'TeddyBear'), ('houseplant', 'HousePlant'), ('toilet roll', 'ToiletPaper'), ('loo', 'Toilet'),
    ('coffee maker', 'CoffeeMachine'), ('frying pan', 'Pan'), ('cupboard', 'Cabinet'), ('bin', 'GarbageCan'),
    # with a determiner or a plain adjective
    ('my keys', 'KeyChain'), ('the small bowl', 'Bowl'), ('a dirty plate', 'Plate'), ('that big sofa', 'Sofa'),
    # what Slice makes
    ('sliced tomato', 'TomatoSliced'), ('tomato slices', 'TomatoSliced'), ('apple slice', 'AppleSliced'),
    ('slice of bread', 'BreadSliced'), ('slices of bread', 'BreadSliced'), ('sliced potatoes', 'PotatoSliced'),
    ('piece of lettuce', 'LettuceSliced'), ('bread slices', 'BreadSliced'),
]

ABSENT = ['unicorn', 'dog', 'cars', 'wardrobe', 'oven', 'computer mouse', 'red wine', 'spaceship', 'the bananas']


def _types(expected) -> tuple[str, ...]:
    return expected if isinstance(expected, tuple) else (expected,)


def fact(object_id: str, position) -> ObjectFact:
    t = load_catalog()[object_id.split('_')[0]]
    return ObjectFact(object_id, t.name, t.noun, position, '', '', '', '', t.colours[0], t.material, t.pickupable,
                      False, False, False, False, 'room', False)


def every_type_scene(*leave_out: str) -> Snapshot:
    """A room holding one object of every catalog type (slices too), each at its own spot."""
    names = [n for n in sorted(load_catalog()) if n not in leave_out]
    facts = [fact(f'{n}_0', (1.0 + 0.1 * k, 0.05 * k, 0.5)) for k, n in enumerate(names)]
    return Snapshot((0.0, 0.0, 0.0, 30.0), None, '', '', '', {}, {f.object_id: f for f in facts})


def test_there_are_at_least_forty_phrasings_covering_plurals_everyday_names_and_slices():
    assert len(PHRASINGS) >= 40
    assert len({p for p, _ in PHRASINGS}) == len(PHRASINGS)


@pytest.mark.parametrize('phrase, expected', PHRASINGS)
def test_a_phrasing_a_person_would_use_names_the_right_object_among_all_types(phrase, expected):
    s = every_type_scene()
    a = answer(s, 'location', phrase)
    assert a.valid, (phrase, a.reason)
    assert s.objects[a.object_id].type_name in _types(expected), (phrase, a.object_id)
    # The answer names the object by the catalog's noun, whatever words were used.
    assert a.text.startswith(f'The {s.objects[a.object_id].noun} is ')


@pytest.mark.parametrize('phrase, expected', PHRASINGS)
def test_a_phrasing_finds_the_object_in_a_room_that_has_only_it(phrase, expected):
    t = _types(expected)[0]
    s = Snapshot((0.0, 0.0, 0.0, 30.0), None, '', '', '', {}, {f'{t}_0': fact(f'{t}_0', (2.0, 0.0, 0.5))})
    assert answer(s, 'appearance', phrase).object_id == f'{t}_0', phrase


@pytest.mark.parametrize('phrase', ABSENT)
def test_something_that_is_not_there_is_still_not_there(phrase):
    a = answer(every_type_scene(), 'location', phrase)
    shown = phrase.removeprefix('the ')
    assert not a.valid and a.reason == f'there is no {shown} here'


def test_an_everyday_name_is_not_there_when_its_type_is_not():
    kitchen = every_type_scene('Television', 'RemoteControl', 'CellPhone')
    for phrase in ('tv', 'TV remote', 'mobile phone', 'phones'):
        a = answer(kitchen, 'location', phrase)
        assert not a.valid and a.reason == f'there is no {phrase.lower()} here'


def test_the_most_literal_reading_wins():
    s = every_type_scene()
    # A type's own noun before another type's variant: 'chair' is the Chair, not the ArmChair ...
    assert s.objects[answer(s, 'location', 'chair').object_id].type_name == 'Chair'
    assert s.objects[answer(s, 'location', 'lamp').object_id].type_name == 'Lamp'
    # ... the catalog's word before the singular: ALFRED's annotators called the Dresser 'drawers'.
    assert s.objects[answer(s, 'location', 'drawers').object_id].type_name == 'Dresser'
    assert s.objects[answer(s, 'location', 'drawer').object_id].type_name == 'Drawer'
    # Without the more literal type, the next reading: the ArmChair is a chair, drawers are drawers.
    no_chair = every_type_scene('Chair')
    assert no_chair.objects[answer(no_chair, 'location', 'chair').object_id].type_name == 'ArmChair'
    no_dresser = every_type_scene('Dresser')
    assert no_dresser.objects[answer(no_dresser, 'location', 'drawers').object_id].type_name == 'Drawer'
    # A whole food is its slices once it has been sliced, and only then.
    no_tomato = every_type_scene('Tomato')
    assert no_tomato.objects[answer(no_tomato, 'location', 'tomato').object_id].type_name == 'TomatoSliced'
    assert s.objects[answer(s, 'location', 'tomato').object_id].type_name == 'Tomato'
    assert not answer(every_type_scene('TomatoSliced'), 'location', 'sliced tomato').valid


def test_singular_of_regular_and_irregular_plurals():
    cases = {'apples': 'apple', 'knives': 'knife', 'glasses': 'glass', 'dishes': 'dish', 'tomatoes': 'tomato',
             'boxes': 'box', 'batteries': 'battery', 'shelves': 'shelf', 'watches': 'watch', 'vases': 'vase',
             'keys': 'key', 'tvs': 'tv', 'loaves': 'loaf', 'shoes': 'shoe'}
    for plural, one in cases.items():
        assert singular(plural) == one
    for word in ('glass', 'lettuce', 'tennis', 'bus', 'cd', 'news', 'apple', 'dress'):
        assert singular(word) == word


def test_everyday_names_name_catalog_nouns_and_never_shadow_the_catalog():
    catalog = load_catalog()
    words = {key(n) for t in catalog.values() for n in (t.noun, *t.nouns)} | {key(n) for n in catalog}
    for phrase, nouns in EVERYDAY_NAMES.items():
        assert key(phrase) not in words, f'{phrase!r} is already a catalog noun'
        assert nouns and all(key(n) in words for n in nouns), phrase


def test_readings_are_listed_once_and_most_literal_first():
    readings = meanings('cell phones')
    assert len(readings) == len(set(readings))
    assert readings[0].by_name == 'cellphones' and not readings[0].singular


# ---------------------------------------------------------------------- what Slice makes, in the simulator

def test_after_a_slice_task_its_slices_are_the_task_objects_and_answer_to_their_names(env):
    tasks = [t for t in load_split('valid_unseen') if t.task_type in ('Slice', 'Move & Slice')][:4]
    assert tasks
    for task in tasks:
        env.reset(options={'task': task})
        target = task.primitives[-1].target
        whole = env.world.objects[target].otype
        replay(env.world, task.expert_actions)
        rerender(env)
        assert target not in env.world.objects
        s = snapshot(env)
        piece_noun = load_catalog()[whole.sliced_type].noun
        slices = sorted(o for o, f in s.objects.items() if f.type_name == whole.sliced_type
                        and env.world.objects[o].sliced_from == target)
        assert slices and set(slices) <= set(task_object_ids(env)) and s.task_objects[piece_noun] == slices[0]
        piece = piece_noun
        for phrase in (piece, f'sliced {whole.noun}', f'{whole.noun} slices', f'the {whole.noun}'):
            a = answer(s, 'location', phrase)
            assert a.valid and a.object_id in slices, (task.task_id, phrase, a.reason)
            assert a.text.startswith(f'The {piece} is ') and check_answer(s, a)['receptacle_ok'] is True
