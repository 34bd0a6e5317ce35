"""The oracle's rules (dialfred_oracle.answers, .colours) on simulated scenes, without ROS."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dialfred_oracle.answers import (DIRECTION_BINS, MAX_NOUN_CHARS, STAY, TURN_AROUND, TURN_LEFT,
                                     TURN_RIGHT, GO_STRAIGHT, Answer, Perturbation, answer, answer_now,
                                     check_answer, direction_bin, question_text, refusal_on_its_face,
                                     situation_key)
from dialfred_sim.protocol import PAPER_QUESTION_TYPES
from dialfred_oracle.colours import (SHADE_MAX, SHADE_MIN, _nearest_shaded_colour, colour_name,
                                     pixel_labels)
from dialfred_sim.ground_truth import (Appearance, ObjectFact, Snapshot, appearance, snapshot,
                                       task_object_ids)
from dialfred_sim.tasks import load_split
from dialfred_sim.palette import COLOUR_NAMES, PALETTE
from dialfred_sim.world.shading import measure_shade_range

from helpers import face, first_of, reset, rerender, spawn_held, spawn_on

COLOUR_AGREEMENT = 0.95


@pytest.fixture(scope='module')
def valid_unseen():
    return load_split('valid_unseen')


def only(env, type_name: str) -> None:
    """Remove every object of `type_name` from the scene (so a spawned one is the only one)."""
    for oid in [k for k, o in env.world.objects.items() if o.type_name == type_name]:
        env.world.remove(oid)


def fact(oid: str, noun: str, position=(1.0, 0.0, 1.0), parent: ObjectFact | None = None, held=False,
         colour='red', material='food', preposition='') -> ObjectFact:
    return ObjectFact(oid, oid.split('_')[0], noun, position, parent.object_id if parent else '',
                      parent.type_name if parent else '', parent.noun if parent else '',
                      preposition or ('on' if parent else ''), colour, material, True, False, False, False,
                      False, 'room', held)


def scene(*facts: ObjectFact, agent=(0.0, 0.0, 0.0, 30.0), expert_end=None, task_objects=None,
          appearances=None) -> Snapshot:
    """A hand-made snapshot: a task if `task_objects` is given, else free exploration."""
    task = task_objects is not None
    return Snapshot(agent, expert_end, 'test/000000' if task else '', 'Pick' if task else '',
                    'Pick up the apple.' if task else '', dict(task_objects or {}),
                    {f.object_id: f for f in facts}, dict(appearances or {}))


# ---------------------------------------------------------------------- questions and templates

def test_questions_read_as_in_the_paper():
    assert question_text('location', 'apple') == 'Where is the apple?'
    assert question_text('appearance', 'apple') == 'What does the apple look like?'
    assert question_text('direction', '') == 'Which direction should I turn to?'   # the paper's template
    with pytest.raises(ValueError):
        question_text('colour', 'apple')


def test_each_of_the_eight_direction_bins():
    for rotation in (0.0, 90.0, 180.0, 270.0, 37.0):
        for k, phrase in enumerate(DIRECTION_BINS):       # counter-clockwise from straight ahead
            for wiggle in (-20.0, 0.0, 20.0):
                a = math.radians(rotation + 45.0 * k + wiggle)
                target = (2.0 + 3.0 * math.cos(a), -1.0 + 3.0 * math.sin(a))
                assert direction_bin((2.0, -1.0), rotation, target) == phrase, (rotation, k, wiggle)
    # Facing +x, +y is on the left and -y on the right.
    assert direction_bin((0, 0), 0, (0, 1)) == 'to your left'
    assert direction_bin((0, 0), 0, (0, -1)) == 'to your right'
    assert direction_bin((0, 0), 90, (1, 0)) == 'to your right'
    assert direction_bin((0, 0), 180, (1, 0)) == 'behind you'


def test_a_location_answer_names_the_receptacle_and_in_or_on():
    fridge = fact('Fridge_0', 'fridge', (0.0, 2.0, 0.9))
    counter = fact('CounterTop_0', 'counter', (3.0, 0.0, 0.45))
    apple = fact('Apple_0', 'apple', (0.2, 2.0, 1.0), parent=fridge, preposition='in')
    mug = fact('Mug_0', 'mug', (3.0, 0.1, 0.95), parent=counter)
    s = scene(fridge, counter, apple, mug)
    assert answer(s, 'location', 'apple').text == 'The apple is to your left in the fridge.'
    assert answer(s, 'location', 'mug').text == 'The mug is in front of you on the counter.'
    assert answer(s, 'location', 'fridge').text == 'The fridge is to your left.'   # nothing holds it
    behind = scene(fridge, counter, apple, mug, agent=(4.0, 0.0, 0.0, 30.0))
    assert answer(behind, 'location', 'mug').text == 'The mug is behind you on the counter.'


def test_a_location_answer_points_at_the_part_of_an_object_the_agent_sees():
    # A counter whose centre is to the left, of which the agent sees the part ahead.
    counter = replace(fact('CounterTop_0', 'counter', (0.0, 2.0, 0.45)), seen_position=(2.0, 0.2, 0.9))
    shut_away = fact('CounterTop_1', 'counter', (0.0, -2.0, 0.45))
    s = scene(counter, shut_away)
    assert answer(s, 'location', 'counter').text == 'The counter is in front of you.'
    assert check_answer(s, answer(s, 'location', 'counter'))['direction_ok'] is True
    assert check_answer(s, Answer(True, 'The counter is to your left.', '', 'location', 'counter',
                                  'CounterTop_0'))['direction_ok'] is False
    far = scene(replace(counter, position=(0.0, 2.0, 0.45), seen_position=None), shut_away)
    assert answer(far, 'location', 'counter').text == 'The counter is to your left.'   # out of view: its centre


def test_a_large_object_in_view_is_where_most_of_its_pixels_are(env):
    """Seen from beside a counter, its centre is to the agent's right but most of what shows of it is
    front right: the answer says front right."""
    reset(env, 'FloorPlan1', seed=0)
    world = env.world
    counters = sorted(k for k, o in world.objects.items() if o.type_name == 'CounterTop')

    def nearest_counter() -> str:         # the one a question about "the counter" is about
        a = world.agent
        return min(counters, key=lambda k: (math.hypot(world.objects[k].position[0] - a.x,
                                                        world.objects[k].position[1] - a.y), k))

    def pixel_bins(oid: str) -> list[str]:
        """The direction bin of the point each of the object's pixels shows."""
        a = world.agent
        _, depth, seg = env._frame
        ys, xs = np.nonzero(seg == world.objects[oid].body)
        return [direction_bin((a.x, a.y), a.rotation, world.pixel_point(x, y, depth)[0][:2]) for x, y in zip(xs, ys)]

    # The first free point and heading (in order) where the nearest counter's centre is to the right and
    # over half of at least 100 of its pixels show it front right.
    found = None
    for i, j in sorted(world.layout.navigable):
        for rot in (0, 90, 180, 270):
            env.teleport(i, j, rot, 30)
            oid = nearest_counter()
            if direction_bin((world.agent.x, world.agent.y), rot, world.objects[oid].position[:2]) != 'to your right':
                continue
            bins = pixel_bins(oid)
            if len(bins) >= 100 and 2 * bins.count('to your front right') > len(bins):
                found = oid
                break
        if found:
            break
    assert found, 'no pose shows a counter mostly front right with its centre to the right'
    s = snapshot(env)
    agent = s.agent
    assert direction_bin(agent[:2], agent[2], s.objects[found].position[:2]) == 'to your right'
    bins = pixel_bins(found)
    most = max(set(bins), key=bins.count)
    assert most == 'to your front right'
    a = answer(s, 'location', 'counter')
    assert a.object_id == found and a.text == f'The counter is {most}.'


def test_a_held_object_is_being_held():
    plate = fact('Plate_0', 'plate', (0.4, -0.2, 1.0), held=True)
    apple = fact('Apple_0', 'apple', (0.4, -0.2, 1.05), parent=plate)
    knife = fact('Knife_0', 'knife', (0.4, -0.2, 1.0), held=True)
    assert answer(scene(knife), 'location', 'knife').text == 'You are holding the knife.'
    assert answer(scene(plate, apple), 'location', 'apple').text == 'The apple is on the plate you are holding.'


def test_location_answers_in_the_simulator(env):
    reset(env, 'FloorPlan1', seed=0)
    only(env, 'Apple')
    only(env, 'Mug')
    fridge = first_of(env, 'Fridge')
    apple = spawn_on(env, 'Apple', fridge.object_id)
    a = answer(snapshot(env), 'location', 'apple')
    assert a.valid and a.object_id == apple.object_id and a.text.endswith(' in the fridge.')
    counter = first_of(env, 'CounterTop')
    env.world.place(apple, counter)
    rerender(env)
    s = snapshot(env)
    a = answer(s, 'location', 'Apple')
    assert a.text.endswith(' on the counter.')
    assert check_answer(s, a) == {'receptacle_ok': True, 'direction_ok': True, 'colour_ok': None}
    mug = spawn_held(env, 'Mug')
    a = answer(snapshot(env), 'location', 'mug')
    assert (a.text, a.object_id) == ('You are holding the mug.', mug.object_id)


def test_an_appearance_answer_gives_colour_and_material(env):
    reset(env, 'FloorPlan1', seed=0)
    only(env, 'Apple')
    apple = spawn_on(env, 'Apple', first_of(env, 'CounterTop').object_id, colour='green')
    s = snapshot(env, [apple.object_id])
    a = answer(s, 'appearance', 'apple')
    assert a.valid and a.colour_from_pixels
    assert a.text == f'The apple is green and made of {apple.otype.material}.'
    assert check_answer(s, a)['colour_ok'] is True
    # Without pixels the colour comes from the metadata, and the answer says so.
    bare = snapshot(env)
    a = answer(bare, 'appearance', 'apple')
    assert a.text == f'The apple is green and made of {apple.otype.material}.' and not a.colour_from_pixels
    dark = scene(fact('Apple_0', 'apple'), appearances={'Apple_0': Appearance('Apple_0', np.zeros((0, 3), np.uint8),
                                                                              False)})
    assert not answer(dark, 'appearance', 'apple').colour_from_pixels


def test_the_one_rule_asks_for_looks_only_for_a_type_that_reads_them():
    """answer_now (the node's and the in-process oracle's rule) fetches the looks of the object the
    noun resolved to for an appearance question, and of nothing for the others."""
    apple = fact('Apple_0', 'apple')
    red = Appearance('Apple_0', np.full((40, 3), (200, 20, 20), np.uint8), True)
    fetched = []

    def with_looks(object_id):
        fetched.append(object_id)
        return scene(apple, appearances={object_id: red})

    now = scene(apple, expert_end=(1.0, 0.0, 0.0, 30.0))
    a = answer_now(now, 'app', 'the apples', with_looks)
    assert fetched == ['Apple_0'] and a.colour_from_pixels and a.text == answer(with_looks('Apple_0'), 'app', 'apple').text
    fetched.clear()
    for qtype, noun in (('location', 'apple'), ('direction', ''), ('appearance', 'banana')):
        assert answer_now(now, qtype, noun, with_looks) == answer(now, qtype, noun)
    assert fetched == []      # a location, a direction and an unresolved noun need no pixels


def test_a_question_malformed_on_its_face_is_refused_before_the_world_is_read():
    assert refusal_on_its_face('Location', 'apple') == ('location', None)
    qtype, refusal = refusal_on_its_face('smell', 'apple')
    assert qtype is None and not refusal.valid and 'unknown question type' in refusal.reason
    qtype, refusal = refusal_on_its_face('appearance', 'x' * (MAX_NOUN_CHARS + 1))
    assert qtype is None and not refusal.valid and 'longer than' in refusal.reason
    assert refusal_on_its_face('direction', 'x' * (MAX_NOUN_CHARS + 1)) == ('direction', None)   # names no object


# ---------------------------------------------------------------------- directions

def test_direction_answers_for_every_outcome():
    def advice(agent, end):
        return answer(scene(agent=agent, expert_end=end, task_objects={}), 'direction', '').text
    here = (1.0, 1.0, 90.0, 30.0)
    assert advice(here, (1.0, 1.0, 90.0, 0.0)) == STAY
    assert advice(here, (1.0, 1.0, 90.0, 30.0)) == STAY           # pitch does not matter
    assert advice(here, (1.25, 1.0, 90.0, 30.0)) != STAY          # one grid step away is not "here"
    assert advice(here, (1.0, 3.0, 0.0, 30.0)) == GO_STRAIGHT      # facing +y, the end is ahead
    assert advice(here, (1.5, 2.5, 0.0, 30.0)) == GO_STRAIGHT      # ... ahead and a little right
    assert advice(here, (-1.0, 1.0, 0.0, 30.0)) == TURN_LEFT       # -x is on the left facing +y
    assert advice(here, (3.0, 1.0, 0.0, 30.0)) == TURN_RIGHT
    assert advice(here, (1.0, -1.0, 0.0, 30.0)) == TURN_AROUND
    assert advice(here, (-1.0, -1.0, 0.0, 30.0)) == TURN_AROUND    # rear left
    # At the end position but facing elsewhere: turn towards the expert's heading.
    assert advice(here, (1.0, 1.0, 180.0, 30.0)) == TURN_LEFT
    assert advice(here, (1.0, 1.0, 0.0, 30.0)) == TURN_RIGHT
    assert advice(here, (1.0, 1.0, 270.0, 30.0)) == TURN_AROUND


def test_direction_needs_no_noun_but_needs_a_task():
    s = scene(agent=(0, 0, 0, 30), expert_end=(2.0, 0.0, 0.0, 30.0), task_objects={})
    for noun in ('', 'apple', 'x' * 10_000):
        a = answer(s, 'direction', noun)
        assert a.valid and a.text == GO_STRAIGHT and check_answer(s, a)['direction_ok'] is True
    a = answer(scene(), 'direction', '')
    assert not a.valid and 'no task' in a.reason


def test_a_task_direction_answer_agrees_with_the_experts_end(env, valid_unseen):
    for task in valid_unseen[:15]:
        env.reset(options={'task': task})
        s = snapshot(env)
        a = answer(s, 'dir', '')
        assert a.valid and a.question_type == 'direction'
        assert check_answer(s, a)['direction_ok'] is True


# ---------------------------------------------------------------------- which object is meant

def test_nouns_match_case_spacing_punctuation_and_type_names():
    basin = fact('SinkBasin_0', 'sink', (2.0, 0.0, 0.8))
    clock = fact('AlarmClock_0', 'alarm clock', (0.0, -2.0, 0.8))
    s = scene(basin, clock)
    for noun in ('sink', 'Sink', '  SINK? ', 'sink basin', 'SinkBasin', 'the sink', 'sink-basin'):
        a = answer(s, 'location', noun)
        assert a.valid and a.object_id == 'SinkBasin_0', noun
    for noun in ('alarm clock', 'AlarmClock', 'Alarm Clock.'):
        assert answer(s, 'location', noun).object_id == 'AlarmClock_0', noun
    assert answer(scene(fact('Sofa_0', 'sofa')), 'location', 'couch').object_id == 'Sofa_0'   # a common word


def test_free_exploration_answers_about_the_nearest_instance():
    near, far = fact('Apple_1', 'apple', (1.0, 0.0, 1.0)), fact('Apple_0', 'apple', (4.0, 0.0, 1.0))
    assert answer(scene(far, near), 'location', 'apple').object_id == 'Apple_1'


def test_a_task_answers_about_its_own_instance_not_a_look_alike(env, valid_unseen):
    task = next(t for t in valid_unseen if t.has_distractor and t.task_type == 'Move & Pick')
    env.reset(options={'task': task})
    target = task.primitives[-1].target
    noun = env.world.objects[target].otype.noun
    twins = [o for o in env.world.objects if env.world.objects[o].otype.noun == noun]
    assert len(twins) >= 2
    s = snapshot(env, task_object_ids(env))
    for qtype in ('location', 'appearance'):
        a = answer(s, qtype, noun)
        assert a.valid and a.object_id == target
        assert all(v in (True, None) for v in check_answer(s, a).values())


def test_questions_the_oracle_cannot_answer_are_invalid_with_a_reason(env, valid_unseen):
    apple = fact('Apple_0', 'apple')
    free = scene(apple)
    cases = [
        (free, 'colour', 'apple', 'unknown question type'),
        (free, None, 'apple', 'unknown question type'),
        (free, 'location', '', 'no object noun'),
        (free, 'appearance', '   ', 'no object noun'),
        (free, 'location', None, 'must be text'),
        (free, 'location', 42, 'must be text'),
        (free, 'location', 'a' * (1 << 20), f'longer than {MAX_NOUN_CHARS}'),
        (free, 'location', 'apple\x00', 'control characters'),
        (free, 'location', 'apple\nWhere', 'control characters'),
        (free, 'location', 'pomme épluchée', 'non-ASCII'),
        (free, 'appearance', '苹果', 'non-ASCII'),
        (free, 'location', '\ud800', 'non-ASCII'),
        (free, 'location', 'unicorn', 'there is no unicorn here'),
        (free, 'direction', '', 'no task'),
    ]
    task = next(t for t in valid_unseen if t.task_type == 'Move & Pick')
    env.reset(options={'task': task})
    s = snapshot(env)
    outsider = next(f for f in s.objects.values() if f.object_id not in s.task_objects.values()
                    and f.noun not in s.task_objects)
    cases.append((s, 'location', outsider.noun, 'not part of this task'))
    for snap, qtype, noun, why in cases:
        a = answer(snap, qtype, noun)
        assert isinstance(a, Answer) and not a.valid and a.text == ''
        assert why in a.reason, (qtype, str(noun)[:20], a.reason)
        assert check_answer(snap, a) == {'receptacle_ok': None, 'direction_ok': None, 'colour_ok': None}


def test_check_answer_catches_wrong_answers():
    fridge = fact('Fridge_0', 'fridge', (0.0, 2.0, 0.9))
    apple = fact('Apple_0', 'apple', (0.2, 2.0, 1.0), parent=fridge, preposition='in', colour='red')
    s = scene(fridge, apple)
    good = answer(s, 'location', 'apple')
    assert check_answer(s, good) == {'receptacle_ok': True, 'direction_ok': True, 'colour_ok': None}
    for wrong, broken in [('The apple is to your left on the fridge.', 'receptacle_ok'),
                          ('The apple is to your left in the counter.', 'receptacle_ok'),
                          ('The apple is to your right in the fridge.', 'direction_ok')]:
        assert check_answer(s, Answer(True, wrong, '', 'location', 'apple', 'Apple_0'))[broken] is False
    assert check_answer(s, Answer(True, 'You are holding the apple.', '', 'location', 'apple',
                                  'Apple_0'))['receptacle_ok'] is False
    said_blue = Answer(True, 'The apple is blue and made of food.', '', 'appearance', 'apple', 'Apple_0')
    assert check_answer(s, said_blue)['colour_ok'] is False
    ended = scene(agent=(0, 0, 0, 30), expert_end=(0, 3.0, 0, 30), task_objects={})
    assert check_answer(ended, Answer(True, TURN_RIGHT, '', 'direction'))['direction_ok'] is False


# ---------------------------------------------------------------------- the perturbation ablation

def test_perturbation_withholds_one_type_at_the_given_rate_deterministically():
    keys = [f'valid_unseen/{k:06d}|apple|1.00,2.25,90,30' for k in range(20_000)]
    p = Perturbation('location', 0.5, seed=3)
    draws = [p.withhold('location', key) for key in keys]
    assert abs(np.mean(draws) - 0.5) < 0.015
    same, other = Perturbation('location', 0.5, seed=3), Perturbation('location', 0.5, seed=4)
    assert draws == [same.withhold('location', key) for key in reversed(keys)][::-1]   # order does not matter
    assert draws[:200] != [other.withhold('location', key) for key in keys[:200]]
    # The same question in the same situation: the same treatment, however often it is asked.
    assert len({p.withhold('location', keys[0]) for _ in range(50)}) == 1
    assert not any(p.withhold(q, key) for q in ('appearance', 'direction', 'bogus') for key in keys[:500])
    rare = Perturbation('app', 0.2, seed=0)
    assert abs(np.mean([rare.withhold('appearance', key) for key in keys]) - 0.2) < 0.015
    assert not any(Perturbation().withhold(q, key) for q in PAPER_QUESTION_TYPES for key in keys[:100])
    assert all(Perturbation('', 1.0).withhold(q, 'k') for q in PAPER_QUESTION_TYPES)
    answered = Answer(True, TURN_LEFT, question_type='direction')
    withheld = Perturbation('direction', 1.0).apply(answered, 'k')
    assert withheld.valid and withheld.text == "I don't know." and withheld.reason == ''
    assert Perturbation('location', 1.0).apply(answered, 'k') is answered
    for bad in ({'question_type': 'colour'}, {'probability': 1.5}, {'probability': -0.1}):
        with pytest.raises(ValueError):
            Perturbation(**bad)


def test_a_questions_situation_is_its_task_its_words_and_the_agents_pose(env, valid_unseen):
    task = valid_unseen[0]
    env.reset(options={'task': task})
    snap = snapshot(env)
    key = situation_key(snap, 'loc', 'The Apple?')
    assert key == situation_key(snap, 'location', 'apple')              # aliases and wording do not matter
    assert key != situation_key(snap, 'appearance', 'apple') and key.startswith(task.task_id + '|')
    env.step({'action': 'RotateLeft'})
    assert situation_key(snapshot(env), 'location', 'apple') != key      # the agent turned


# ---------------------------------------------------------------------- colour names from pixels

def test_the_renderers_shading_range_is_the_one_the_colour_table_assumes():
    lo, hi = measure_shade_range()
    assert SHADE_MIN <= lo <= SHADE_MIN + 0.03 and SHADE_MAX - 0.03 <= hi <= SHADE_MAX


def test_every_shade_of_every_palette_colour_keeps_its_name():
    for name in COLOUR_NAMES:
        base = np.array(PALETTE[name], dtype=float)
        for s in np.linspace(0.6, 0.99, 14):
            assert colour_name(np.floor(base * s)[None].astype(np.uint8)) == name, (name, s)
    assert colour_name(np.zeros((0, 3), np.uint8)) is None


def test_labelling_each_distinct_colour_once_gives_every_pixel_its_own_label():
    rng = np.random.default_rng(0)
    palette = rng.integers(0, 256, size=(30, 3)).astype(np.uint8)
    pixels = palette[rng.integers(0, 30, size=400)]          # repeats, as a flat-shaded mask has
    labels, dist = pixel_labels(pixels)
    direct_labels, direct_dist = _nearest_shaded_colour(pixels)
    assert np.array_equal(labels, direct_labels) and np.allclose(dist, direct_dist)
    assert len(pixel_labels(np.zeros((0, 3), np.uint8))[0]) == 0


def test_the_main_colour_outvotes_fixed_colour_details():
    red = np.floor(np.array(PALETTE['red']) * np.linspace(0.6, 0.95, 60)[:, None])
    blade = np.floor(np.array(PALETTE['silver']) * np.linspace(0.6, 0.95, 40)[:, None])
    assert colour_name(np.concatenate([red, blade]).astype(np.uint8)) == 'red'


def _agreement(pairs) -> float:
    return sum(a == b for a, b in pairs) / len(pairs)


def test_rendered_objects_are_named_by_their_colour_in_view_and_close_up(env):
    reset(env, 'FloorPlan1', seed=0)
    counter = first_of(env, 'CounterTop')
    for oid in [o.object_id for o in env.world.objects.values() if o.parent == counter.object_id and not o.fixture]:
        if oid in env.world.objects:
            env.world.remove(oid)                  # room on the counter for each of the objects below
    kinds = ['Apple', 'Mug', 'Knife', 'Bowl', 'Pot', 'Kettle', 'CellPhone', 'Book', 'Spatula', 'Bread',
             'SoapBottle', 'Plate', 'ButterKnife', 'Egg']
    in_view, close_up = [], []
    for k, type_name in enumerate(kinds):
        colour = COLOUR_NAMES[(3 * k) % len(COLOUR_NAMES)]
        only(env, type_name)
        obj = spawn_on(env, type_name, counter.object_id, colour=colour)
        face(env, obj.object_id)
        look = appearance(env, obj.object_id, min_pixels=8)
        if look.from_current_view:
            in_view.append((colour_name(look.pixels), colour))
        a = env.world.agent
        env.teleport(a.i, a.j, (a.rotation + 180) % 360, a.horizon)     # look away: a close-up
        look = appearance(env, obj.object_id)
        assert not look.from_current_view
        close_up.append((colour_name(look.pixels), colour))
        env.world.remove(obj.object_id)
    assert len(in_view) >= len(kinds) // 2
    assert _agreement(in_view) >= COLOUR_AGREEMENT, in_view
    assert _agreement(close_up) >= COLOUR_AGREEMENT, close_up


@pytest.mark.parametrize('scene_name', ['FloorPlan5', 'FloorPlan210', 'FloorPlan315', 'FloorPlan420'])
def test_every_object_of_a_room_is_named_by_its_colour_variant(env, scene_name):
    reset(env, scene_name, seed=2)
    world = env.world
    close = []
    for oid, obj in sorted(world.objects.items()):
        look = appearance(env, oid)
        if not look.from_current_view:
            close.append((colour_name(look.pixels), obj.colour))
    seen = []
    for i, j in sorted(world.layout.navigable)[::7][:6]:
        for rotation in (0, 90, 180, 270):
            env.teleport(i, j, rotation, 30)
            shown = [oid for oid, o in world.objects.items() if (env._frame[2] == o.body).sum() >= 20]
            for oid in shown:
                look = appearance(env, oid)
                if look.from_current_view:
                    seen.append((colour_name(look.pixels), world.objects[oid].colour))
    assert len(close) >= 10 and len(seen) >= 20
    assert _agreement(close) >= COLOUR_AGREEMENT and _agreement(seen) >= COLOUR_AGREEMENT
