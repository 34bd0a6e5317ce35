"""The synthetic annotator (dialfred_oracle/annotator.py) and its shipped dialogue data.

Plain pytest, no ROS. The protocol, noise model, paraphrasing and statistics are checked on
hand-made ground truth (the real Snapshot / ObjectFact dataclasses, filled in by hand) with the real
oracle; calibration and docs/dialogue_data.md are checked on the shipped valid splits; a few tests
reset a real simulator to shipped tasks. If the data tests fail after the tasks, the oracle or the
annotator changed, rerun `./dialfred env python3 scripts/annotate_dialogues.py --splits valid_seen valid_unseen`.
"""

from __future__ import annotations

import importlib.util
import re
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from dialfred_oracle.annotator import (
    PAPER_HUMAN, REAR_BINS, Annotation, ChoiceModel, Situation, categories, choice_model,
    annotate, answer_content, answer_words, dialogue_statistics, dialogue_path, expected_statistics,
    fit_choice_model, fleiss_kappa, load_dialogues)
from dialfred_oracle.answers import answer
from dialfred_sim.ground_truth import ObjectFact, Snapshot
from dialfred_sim.protocol import PAPER_QUESTION_TYPES
from dialfred_sim.tasks import SPLIT_SIZES, load_split
from dialfred_sim.tasks.schema import Primitive

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / 'docs' / 'dialogue_data.md'
VALID = ('valid_seen', 'valid_unseen')


def load_script():
    spec = importlib.util.spec_from_file_location('annotate_dialogues', ROOT / 'scripts' / 'annotate_dialogues.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


script = load_script()


# ---------------------------------------------------------------------- hand-made ground truth

def fact(object_id, noun, position, parent='', parent_noun='', preposition='', colour='red', material='food',
         held=False, is_open=False):
    return ObjectFact(object_id, object_id.split('_')[0], noun, position, parent, parent.split('_')[0],
                      parent_noun, preposition, colour, material, True, is_open, False, False, False, 'room', held)


def kitchen(agent_rotation=0.0, apple_twin=True, apple_parent=('CounterTop_0', 'counter', 'on'), mug_held=False):
    """Agent at the origin facing +x; the task's apple ahead on the counter (a red look-alike behind the
    agent), a fridge to the left with an egg shut in it, a mug."""
    objects = [fact('CounterTop_0', 'counter', (1.0, 0.0, 0.45), material='stone', colour='gray'),
               fact('Apple_0', 'apple', (1.0, 0.0, 0.95), *apple_parent),
               fact('Fridge_0', 'fridge', (0.0, 1.5, 0.9), material='metal', colour='white'),
               fact('Egg_0', 'egg', (0.0, 1.5, 1.0), 'Fridge_0', 'fridge', 'in', colour='white'),
               fact('Mug_0', 'mug', (0.0, 0.0, 1.0) if mug_held else (1.0, 0.2, 0.95),
                    *(('', '', '') if mug_held else ('CounterTop_0', 'counter', 'on')), held=mug_held,
                    material='ceramic', colour='blue')]
    if apple_twin:
        objects.append(fact('Apple_1', 'apple', (-1.0, 0.0, 0.95), colour='green'))
    return Snapshot(agent=(0.0, 0.0, agent_rotation, 30.0), expert_end=(0.75, 0.0, 0.0, 30.0),
                    task_id='valid_unseen/000000', task_type='Move & Pick', instruction='Pick up the apple.',
                    task_objects={'counter': 'CounterTop_0', 'apple': 'Apple_0', 'egg': 'Egg_0', 'mug': 'Mug_0'},
                    objects={f.object_id: f for f in objects})


def pick_task(target='Apple_0', noun='apple', visible=True, nouns=None, instruction=None):
    return SimpleNamespace(task_id='valid_unseen/000000', task_type='Move & Pick',
                           instruction=instruction or f'Pick up the {noun}.', step_instructions=[],
                           object_nouns=nouns or ['counter', noun],
                           primitives=[Primitive('goto', 'CounterTop_0', 0, 3), Primitive('pickup', target, 3, 4)],
                           target_visible_at_start=visible, has_distractor=True)


def forced(question_type: str) -> ChoiceModel:
    """A choice model that always picks `question_type` (or none)."""
    return ChoiceModel(0.0, tuple(50.0 if c == (question_type or 'none') else -50.0 for c in categories()))


# ---------------------------------------------------------------------- Fleiss' kappa

def test_kappa_is_one_when_raters_always_agree():
    assert fleiss_kappa([[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 0, 2], [0, 0, 2, 0]]) == pytest.approx(1.0)
    assert fleiss_kappa([[3, 0], [3, 0]]) == 1.0      # one category only: agreement is perfect


def test_kappa_of_the_textbook_example_is_0_210():
    # Fleiss (1971) style example (Wikipedia): 10 subjects, 14 raters, 5 categories -> kappa 0.210.
    table = [[0, 0, 0, 0, 14], [0, 2, 6, 4, 2], [0, 0, 3, 5, 6], [0, 3, 9, 2, 0], [2, 2, 8, 1, 1],
             [7, 7, 0, 0, 0], [3, 2, 6, 3, 0], [2, 5, 3, 2, 2], [6, 5, 2, 1, 0], [0, 2, 2, 3, 7]]
    assert fleiss_kappa(table) == pytest.approx(0.2099, abs=1e-4)


def test_kappa_is_about_zero_for_independent_raters_and_negative_for_systematic_disagreement():
    rng = np.random.default_rng(0)
    choices = rng.choice(4, size=(20000, 2), p=[0.34, 0.47, 0.15, 0.04])
    table = np.stack([(choices == c).sum(1) for c in range(4)], axis=1)
    assert abs(fleiss_kappa(table)) < 0.02
    assert fleiss_kappa([[1, 1], [1, 1], [1, 1]]) < 0


def test_kappa_rejects_tables_with_unequal_or_too_few_raters():
    with pytest.raises(ValueError):
        fleiss_kappa([[2, 0], [1, 0]])
    with pytest.raises(ValueError):
        fleiss_kappa([[1, 0], [0, 1]])
    with pytest.raises(ValueError):
        fleiss_kappa([])


# ---------------------------------------------------------------------- statistics

def test_dialogue_statistics_of_a_hand_made_set():
    loc = Annotation(0, 'location', 'apple', 'Where is the apple?', 'On the counter.', True)
    app = Annotation(1, 'appearance', 'apple', 'What does the apple look like?', "It's red and shiny", False)
    tasks = [[loc, Annotation(1, None)], [Annotation(0, None), Annotation(1, None)], [loc, app]]
    s = dialogue_statistics(tasks)
    assert (s['tasks'], s['annotations'], s['questions']) == (3, 6, 3)
    assert s['questions_per_task'] == pytest.approx(0.5)
    assert s['type_shares'] == {'location': pytest.approx(2 / 3, abs=1e-4),
                                'appearance': pytest.approx(1 / 3, abs=1e-4), 'direction': 0.0}
    assert s['answer_words'] == pytest.approx((3 + 3 + 4) / 3, abs=1e-3)
    assert s['necessary_fraction'] == pytest.approx(2 / 3, abs=1e-4)
    table = [[1, 1, 0, 0], [2, 0, 0, 0], [0, 1, 1, 0]]
    assert s['fleiss_kappa'] == pytest.approx(fleiss_kappa(table), abs=1e-4)
    assert answer_words("It's on the counter, I think.") == 6


# ---------------------------------------------------------------------- the situation

def test_situation_reads_visibility_lookalikes_and_the_direction_of_the_target():
    s = Situation.of(pick_task(visible=False), kitchen())
    assert s.main_noun == 'apple' and s.nouns == ('apple', 'counter')
    assert not s.target_visible and s.main_has_distractor and s.distractor_nouns == ('apple',)
    assert s.target_direction == 'in front of you' and not s.target_behind and not s.clear
    turned = Situation.of(pick_task(), kitchen(agent_rotation=180.0, apple_twin=False))
    assert turned.target_behind and turned.target_direction in REAR_BINS and not turned.main_has_distractor
    clear = Situation.of(pick_task(instruction='Go to the counter and pick up the apple.'), kitchen(apple_twin=False))
    assert clear.clear and clear.instruction_complete


def test_situation_knows_a_target_shut_in_the_fridge_and_what_the_agent_holds():
    s = Situation.of(pick_task('Egg_0', 'egg', nouns=['fridge', 'egg', 'mug']), kitchen(mug_held=True))
    assert s.main_noun == 'egg' and s.target_enclosed and not s.target_held
    assert s.held_nouns == ('mug',)
    assert s == Situation.from_json(s.to_json())


def test_choices_follow_the_situation():
    p = {c: dict(zip(categories(), choice_model().probabilities(Situation.of(t, k))))
         for c, (t, k) in {'clear': (pick_task(instruction='Go to the counter, pick up the apple.'),
                                     kitchen(apple_twin=False)),
                           'hidden': (pick_task(visible=False), kitchen(apple_twin=False)),
                           'lookalike': (pick_task(instruction='Go to the counter, pick up the apple.'), kitchen()),
                           'behind': (pick_task(visible=False), kitchen(agent_rotation=180.0, apple_twin=False))
                           }.items()}
    assert max(p['clear'], key=p['clear'].get) == 'none'
    assert max(p['hidden'], key=p['hidden'].get) == 'location'
    assert p['lookalike']['appearance'] > 2 * p['clear']['appearance']
    assert p['behind']['direction'] > 3 * p['hidden']['direction']
    assert p['hidden']['none'] < p['clear']['none'] / 2


def test_fitted_model_reproduces_the_paper_shares_and_kappa_on_a_mix_of_situations():
    base = Situation('apple', ('apple', 'counter'), True, False, 'in front of you', False, False, (), True)
    rng = np.random.default_rng(1)
    situations = [Situation('apple', base.nouns, bool(v), bool(b), '', bool(e), False,
                            ('apple',) if d else (), bool(c))
                  for v, b, e, d, c in rng.random((400, 5)) < [0.64, 0.2, 0.1, 0.5, 0.8]]
    model = fit_choice_model(situations)
    shares, kappa = expected_statistics(model, situations)
    target = [1 - 0.66, 0.66 * 0.72, 0.66 * 0.22, 0.66 * 0.06]
    assert shares == pytest.approx(target, abs=1e-3)
    assert kappa == pytest.approx(PAPER_HUMAN['fleiss_kappa'], abs=2e-3)
    assert model.strength > 0


# ---------------------------------------------------------------------- questions and answers

def test_a_location_answer_names_the_receptacle_the_object_is_on_in_other_words():
    task, snap = pick_task(nouns=['apple']), kitchen()
    answers = set()
    for seed in range(60):
        a = annotate(task, snap, np.random.default_rng(seed), 0, model=forced('location'))
        assert (a.question_type, a.object_noun, a.question) == ('location', 'apple', 'Where is the apple?')
        assert a.oracle_answer == 'The apple is in front of you on the counter.' and a.valid
        assert 'counter' in a.answer.lower()
        answers.add(a.answer)
    assert len(answers) >= 20        # paraphrased, not one template


def test_an_object_shut_in_the_fridge_is_said_to_be_in_it():
    task = pick_task('Egg_0', 'egg', nouns=['egg'])
    for seed in range(20):
        a = annotate(task, kitchen(), np.random.default_rng(seed), 1, model=forced('location'))
        assert 'fridge' in a.answer.lower() and re.search(r'\b(in|inside)\b', a.answer.lower())


def test_appearance_and_direction_answers_keep_the_oracles_content():
    task, snap = pick_task(nouns=['apple']), kitchen()
    for seed in range(30):
        a = annotate(task, snap, np.random.default_rng(seed), 0, model=forced('appearance'))
        assert a.oracle_answer == 'The apple is red and made of food.'
        assert 'red' in a.answer.lower()
        d = annotate(task, snap, np.random.default_rng(seed), 0, model=forced('direction'))
        assert d.oracle_answer == 'You should go straight ahead.' and d.object_noun == ''
        assert re.search(r'straight|forward|ahead', d.answer.lower()), d.answer


def test_no_question_has_no_answer():
    a = annotate(pick_task(), kitchen(), np.random.default_rng(0), 1, model=forced(''))
    assert a == Annotation(1, None) and a.category == 'none'


def test_the_oracles_templates_are_all_understood():
    snap = kitchen(mug_held=True)
    for qtype, noun in (('location', 'apple'), ('location', 'egg'), ('location', 'mug'), ('location', 'counter'),
                        ('appearance', 'egg'), ('direction', '')):
        c = answer_content(answer(snap, qtype, noun), qtype, noun)
        assert c.valid and (c.where or c.receptacle or c.held or c.colour), (qtype, noun, c)


def test_annotating_the_same_task_twice_gives_the_same_annotation():
    task, snap = pick_task(visible=False), kitchen()
    first = [annotate(task, snap, np.random.default_rng(seed), 0) for seed in range(30)]
    again = [annotate(task, snap, np.random.default_rng(seed), 0) for seed in range(30)]
    assert first == again
    assert len({a.category for a in first}) >= 2      # and the seed matters


def test_answer_lengths_are_calibrated_around_the_papers_mean():
    task, snap = pick_task(visible=False), kitchen()
    words = [answer_words(a.answer) for seed in range(400)
             for a in [annotate(task, snap, np.random.default_rng(seed), 0, model=forced(PAPER_QUESTION_TYPES[seed % 3]))]]
    assert abs(np.mean(words) - PAPER_HUMAN['answer_words']) < 1.0
    assert min(words) <= 3 and max(words) >= 10


# ---------------------------------------------------------------------- the shipped data

@pytest.fixture(scope='module')
def shipped():
    for split in VALID:
        assert dialogue_path(split).exists(), f'{dialogue_path(split)} is missing; run scripts/annotate_dialogues.py'
    return {split: load_dialogues(split) for split in VALID}


@pytest.fixture(scope='module')
def shipped_stats(shipped):
    return {split: dialogue_statistics([r.annotations for r in rows]) for split, rows in shipped.items()}


def test_every_valid_task_has_two_annotations(shipped):
    for split, rows in shipped.items():
        assert [r.task_id for r in rows] == [t.task_id for t in load_split(split)]
        assert len(rows) == SPLIT_SIZES[split]
        for r in rows:
            assert [a.annotator_id for a in r.annotations] == [0, 1]
            for a in r.annotations:
                assert a.question_type in (None, *PAPER_QUESTION_TYPES)
                assert bool(a.question_type) == bool(a.question) == bool(a.answer) == (a.necessary is not None)


@pytest.mark.parametrize('split', VALID)
def test_valid_statistics_are_calibrated_to_the_papers_humans(shipped_stats, split):
    s = shipped_stats[split]
    assert s['type_shares']['location'] == pytest.approx(0.72, abs=0.05)
    assert s['type_shares']['appearance'] == pytest.approx(0.22, abs=0.05)
    assert s['type_shares']['direction'] == pytest.approx(0.06, abs=0.03)
    assert s['questions_per_task'] == pytest.approx(0.66, abs=0.05)
    assert s['answer_words'] == pytest.approx(6.73, abs=0.5)
    assert s['fleiss_kappa'] == pytest.approx(0.13, abs=0.05)     # a low-agreement regime, as the paper's


def test_shipped_location_answers_name_the_receptacle(shipped):
    checked = 0
    for rows in shipped.values():
        for r in rows:
            for a in r.annotations:
                if a.question_type == 'location' and a.valid:
                    c = answer_content(SimpleNamespace(valid=True, text=a.oracle_answer, object_noun=a.object_noun),
                                       'location', a.object_noun)
                    if c.receptacle:
                        assert c.receptacle in a.answer.lower(), (r.task_id, a)
                        checked += 1
    assert checked > 900          # 979 in the shipped valid splits: most location answers name one


def markdown_table(text: str, first_header: str) -> list[dict[str, str]]:
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith(f'| {first_header} |'))
    header = [c.strip() for c in lines[k].strip('|').split('|')]
    rows = []
    for line in lines[k + 2:]:
        if not line.startswith('|'):
            break
        rows.append(dict(zip(header, (c.strip() for c in line.strip('|').split('|')))))
    return rows


def test_the_doc_says_synthetic_first_and_states_the_shipped_statistics(shipped_stats):
    assert DOC.exists(), f'{DOC} is missing; run scripts/annotate_dialogues.py'
    text = DOC.read_text()
    assert 'synthetic' in text.splitlines()[0].lower()
    rows = {row['statistic']: row for row in markdown_table(text, 'statistic')}
    for label, value, paper in script.STAT_ROWS:
        for split in VALID:
            assert rows[label][split] == value(shipped_stats[split]), (label, split)
        assert rows[label]['paper (human)'] == paper


def test_the_doc_shows_the_fitted_model():
    text = DOC.read_text()
    assert f'strength = {choice_model().strength}' in text
    assert all(f'{c} {b:+.3f}' in text for c, b in zip(categories(), choice_model().bias))


# ---------------------------------------------------------------------- with the real simulator

@pytest.fixture(scope='module')
def worker():
    script._init_worker('valid_unseen')
    yield script
    script._ENV.close()


def test_reannotating_shipped_tasks_in_the_simulator_gives_the_same_rows(worker, shipped):
    rows = shipped['valid_unseen']
    for k in range(0, len(rows), 97):
        assert worker._annotate_chunk((k, k + 1)) == [rows[k].to_json()], rows[k].task_id


def test_location_answers_in_the_simulator_name_the_receptacle_of_the_task_object(worker):
    from dialfred_sim.ground_truth import snapshot
    tasks = load_split('valid_unseen')
    for task in tasks[:12]:
        worker._ENV.reset(options={'task': task})
        snap = snapshot(worker._ENV)
        for noun, oid in snap.task_objects.items():
            f = snap.objects[oid]
            if not f.parent_noun or f.held:
                continue
            a = annotate(task, snap, np.random.default_rng(3), 0, model=forced('location'),
                         situation=replace(Situation.of(task, snap), main_noun=noun, nouns=(noun,)))
            assert f.parent_noun in a.answer.lower(), (task.task_id, noun, a)


@pytest.mark.slow   # fast: reannotating shipped tasks in the simulator gives the same rows
def test_rows_made_while_rendering_are_the_scripts_own(tmp_path):
    """prepare --annotate makes each train task's annotator row while rendering its demonstration
    (AnnotatingProbe, the task's start seen at 128 px through DialfredEnv.viewed_at); the script's
    --from-demonstrations writes them: the same train.jsonl.gz bytes as the script's own pass (first
    16 train tasks), and a task without a probed row is annotated as usual."""
    import gzip
    import json

    from dialfred_performer.prepare import PrepareConfig, prepare
    from dialfred_sim.tasks.demonstrations import _done_rows
    import os
    import subprocess
    import sys

    def run(name: str, *extra: str) -> bytes:
        env = {**os.environ, 'DIALFRED_DIALOGUE_DIR': str(tmp_path / name)}
        subprocess.run([sys.executable, str(ROOT / 'scripts' / 'annotate_dialogues.py'), '--splits', 'train',
                        '--limit', '16', '--doc', str(tmp_path / f'{name}.md'), *extra], env=env, check=True,
                       capture_output=True)
        return (tmp_path / name / 'train.jsonl.gz').read_bytes()

    demos = tmp_path / 'demos'
    prepare(PrepareConfig(split='train', resolution=64, workers=2, limit=16, out=str(demos), progress=False,
                          annotate=True))
    own = run('own', '--workers', '1')
    assert run('probed', '--from-demonstrations', str(demos)) == own
    assert len(gzip.decompress(own).splitlines()) == 16
    # a task the probe gave no row for (a build resumed from one made without --annotate)
    path = sorted(demos.glob('done-*.txt'))[0]
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    del rows[0]['probe']['annotation']
    path.write_text(''.join(json.dumps(r) + '\n' for r in rows))
    assert rows[0]['index'] in _done_rows(demos)
    assert run('mixed', '--from-demonstrations', str(demos)) == own


def test_the_scripts_progress_in_a_log_is_plain_lines(tmp_path):
    """stderr is not a terminal here (a log, CI): progress comes as whole lines, never carriage-return redraws
    that pile up into one endless line. (3 train tasks, into a folder of the test's own.)"""
    import os
    import subprocess
    import sys
    done = subprocess.run([sys.executable, str(ROOT / 'scripts' / 'annotate_dialogues.py'), '--splits', 'train',
                           '--limit', '3', '--workers', '1', '--doc', str(tmp_path / 'd.md')],
                          env={**os.environ, 'DIALFRED_DIALOGUE_DIR': str(tmp_path)}, capture_output=True,
                          text=True, timeout=240)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / 'train.jsonl.gz').exists()
    assert '\r' not in done.stderr and 'train' in done.stderr and '3/3' in done.stderr
