"""The dataset card (docs/dataset.md) states the statistics of the shipped task data.

Plain pytest, no ROS: the statistics are recomputed from `load_split('valid_unseen')` (the navigation
twins in a simulator, which rebuilds each navigation task's first state) and compared with the
numbers written in the card's tables. If this fails after the splits were regenerated, rerun
`./dialfred env python3 scripts/dataset_card.py`.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from statistics import mean

import pytest

from dialfred_sim.tasks import SPLIT_SIZES, TASK_TYPES, load_split
from dialfred_sim.tasks.instructions import tokenize

ROOT = Path(__file__).resolve().parents[2]
CARD = ROOT / 'docs' / 'dataset.md'
SPLIT = 'valid_unseen'


def load_script():
    spec = importlib.util.spec_from_file_location('dataset_card', ROOT / 'scripts' / 'dataset_card.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


dataset_card = load_script()


def markdown_tables(text: str) -> dict[str, list[dict[str, str]]]:
    """Each table of a markdown text, keyed by its first header cell: rows as {header: cell}."""
    tables, lines = {}, text.splitlines()
    k = 0
    while k < len(lines):
        if lines[k].startswith('|') and k + 1 < len(lines) and re.match(r'^\|(\s*:?-+:?\s*\|)+$', lines[k + 1]):
            header = [c.strip() for c in lines[k].strip('|').split('|')]
            rows = []
            k += 2
            while k < len(lines) and lines[k].startswith('|'):
                rows.append(dict(zip(header, (c.strip() for c in lines[k].strip('|').split('|')))))
                k += 1
            tables[header[0]] = rows
        else:
            k += 1
    return tables


def number(cell: str) -> tuple[float, float]:
    """The value of a card cell ('1,363', '5.14', '53.1%', '**1,363**') and half its last digit."""
    text = cell.strip('*` ').replace(',', '')
    scale = 0.01 if text.endswith('%') else 1.0
    text = text.rstrip('%')
    decimals = len(text.split('.')[1]) if '.' in text else 0
    return float(text) * scale, 0.5 * 10 ** -decimals * scale + 1e-9


@pytest.fixture(scope='module')
def tasks():
    return load_split(SPLIT)


@pytest.fixture(scope='module')
def stats(tasks):
    return dataset_card.split_statistics(tasks)


@pytest.fixture(scope='module')
def card():
    assert CARD.exists(), f'{CARD} is missing; run `./dialfred env python3 scripts/dataset_card.py`'
    return markdown_tables(CARD.read_text())


def test_every_task_is_counted_once_in_its_type(tasks, stats):
    assert list(stats['task_types']) == list(TASK_TYPES)
    assert sum(stats['task_types'].values()) == stats['tasks'] == len(tasks) == SPLIT_SIZES[SPLIT]
    assert sum(stats['alfred_job_types'].values()) == stats['episodes']


def test_statistics_agree_with_a_direct_count(tasks):
    some = tasks[:60]
    s = dataset_card.split_statistics(some)
    lengths = [t.end - t.start for t in some]
    assert s['tasks'] == 60
    assert s['episodes'] == len({t.episode.episode_id for t in some})
    assert s['rooms'] == len({t.episode.scene for t in some})
    assert s['task_types'] == {name: sum(t.task_type == name for t in some) for name in TASK_TYPES}
    assert s['expert_length'] == {'mean': round(mean(lengths), 3), 'min': min(lengths), 'max': max(lengths)}
    assert s['main_instruction_words'] == pytest.approx(mean(len(tokenize(t.instruction)) for t in some), abs=1e-3)
    assert s['step_instructions_words'] == pytest.approx(
        mean(len(tokenize(' '.join(t.step_instructions))) for t in some), abs=1e-3)
    words = {w for t in some for w in tokenize(' '.join([t.instruction, *t.step_instructions]))}
    assert s['vocabulary_size'] == len(words)
    assert s['distractor_fraction'] == pytest.approx(mean(t.has_distractor for t in some), abs=1e-4)
    assert s['target_not_visible_fraction'] == pytest.approx(
        mean(not t.target_visible_at_start for t in some), abs=1e-4)


def test_card_summary_matches_the_shipped_split(stats, card):
    rows = {row['statistic']: row for row in card['statistic']}
    for label, value, _ in dataset_card.SUMMARY_ROWS:
        written, tolerance = number(rows[label][SPLIT])
        assert abs(written - value(stats)) <= tolerance, f'{label}: card says {written}, data gives {value(stats)}'


def test_card_counts_per_task_type_match_and_sum_to_the_split_size(stats, card):
    rows = card['#']
    per_type = {row['task type']: int(number(row[SPLIT])[0]) for row in rows if row['#']}
    assert list(per_type) == list(TASK_TYPES)
    assert per_type == stats['task_types']
    total = next(row for row in rows if not row['#'])
    assert int(number(total[SPLIT])[0]) == sum(per_type.values()) == SPLIT_SIZES[SPLIT]


def test_card_episodes_per_alfred_job_type_match(stats, card):
    rows = card['ALFRED job type (episodes)']
    written = {row['ALFRED job type (episodes)'].strip('`'): int(number(row[SPLIT])[0]) for row in rows}
    assert {job: n for job, n in written.items() if n} == stats['alfred_job_types']
    assert sum(written.values()) == stats['episodes']


def test_card_shows_six_examples_of_different_types():
    assert (ROOT / 'docs' / 'images' / 'task_examples.png').exists()
    rows = markdown_tables(CARD.read_text())['task']
    assert len(rows) == 6 and len({row['type'] for row in rows}) == 6


@pytest.fixture(scope='module')
def twins(tasks):
    return dataset_card.navigation_twins(tasks)


def test_97_of_the_262_navigation_goals_of_valid_unseen_have_a_same_type_same_colour_twin(tasks, twins):
    """Only a location answer tells such a target from its twin."""
    navigation = [t for t in tasks if t.task_type in ('Move', 'Pick & Move')]
    assert all(any(c.kind == 'near' for c in t.goal) for t in navigation)
    assert len(navigation) == twins['navigation_goals'] == 262 and twins['not_rebuilt'] == 0
    assert (twins['same_type'], twins['twins']) == (132, 97)
    assert sum(twins['twin_types'].values()) == 97


def test_card_counts_of_navigation_twins_match(twins, card):
    rows = {row['navigation goals']: row[SPLIT] for row in card['navigation goals']}
    written = [int(number(cell.split(' (')[0])[0]) for cell in rows.values()]
    assert written == [twins['navigation_goals'], twins['same_type'], twins['twins']]
