#!/usr/bin/env python3
"""Dataset card of the DialFRED task splits: statistics as JSON, docs/dataset.md and an example image.

    ./dialfred env python3 scripts/dataset_card.py [--splits valid_seen valid_unseen train]
    ./dialfred env python3 scripts/dataset_card.py --tasks PATH     # a split file of your own, e.g. a test split

Prints the statistics of every split that exists (and names the absent ones) as JSON on stdout,
writes docs/dataset.md and renders docs/images/task_examples.png (first frames of six valid_unseen
tasks of different types). With --tasks it only prints the statistics of those files (a sealed test
split stays out of the card). `split_statistics` is plain Python over `Task` objects (no ROS, no
simulator); `navigation_twins` and the example image start a simulator.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path
from statistics import mean
from typing import Callable, Sequence

import jinja2
from PIL import Image, ImageDraw, ImageFont

from dialfred_sim.tasks import SPLIT_SIZES, TASK_TYPES, Task, load_split
from dialfred_sim.tasks.instructions import tokenize, vocabulary
from dialfred_sim.tasks.splits import TEST_SPLIT, TEST_UNSEEN_SCENES, VALID_UNSEEN_SCENES, read_tasks_file

ROOT = Path(__file__).resolve().parents[1]
CARD = ROOT / 'docs' / 'dataset.md'
IMAGE = ROOT / 'docs' / 'images' / 'task_examples.png'
SPLITS = ('train', 'valid_seen', 'valid_unseen')
# ALFRED's 7 job types, in the order of the ALFRED paper.
ALFRED_JOB_TYPES = ('pick_and_place_simple', 'pick_two_obj_and_place', 'look_at_obj_in_light',
                    'pick_clean_then_place_in_recep', 'pick_heat_then_place_in_recep',
                    'pick_cool_then_place_in_recep', 'pick_and_place_with_movable_recep')
# Types the example image tries first: long and short, with and without a receptacle.
EXAMPLE_TYPES = ('Move & Heat', 'Open & Pick & Close', 'Pick & Move & Put', 'Move & Clean',
                 'Turn on', 'Pick & Move & Slice')
EXAMPLE_SPLIT = 'valid_unseen'
EXAMPLE_RESOLUTION = 192
TWIN_RESOLUTION = 64          # the rebuilt worlds are only inspected, never shown: the smallest frame will do


# ---------------------------------------------------------------------- statistics (ROS-free)

def split_statistics(tasks: Sequence[Task]) -> dict:
    """Summary of a list of tasks (one split): counts, expert lengths, instruction lengths, vocabulary.

    Returns a JSON-ready dict: tasks, episodes, rooms; task_types (count per type, paper order, zeros
    kept); alfred_job_types (episodes per ALFRED job type); expert_length {mean, min, max} in
    low-level actions; main_instruction_words and step_instructions_words (means; a task's step
    sentences counted together); vocabulary_size (distinct tokens of main + step instructions);
    distractor_fraction (a same-class object besides the target) and target_not_visible_fraction.
    """
    if not tasks:
        raise ValueError('no tasks')
    episodes = {t.episode.episode_id: t.episode for t in tasks}
    type_counts = Counter(t.task_type for t in tasks)
    unknown = set(type_counts) - set(TASK_TYPES)
    if unknown:
        raise ValueError(f'tasks of unknown types {sorted(unknown)}')
    job_counts = Counter(e.alfred_type for e in episodes.values())
    jobs = [j for j in ALFRED_JOB_TYPES if j in job_counts] + sorted(set(job_counts) - set(ALFRED_JOB_TYPES))
    lengths = [t.expert_length for t in tasks]
    sentences = [s for t in tasks for s in [t.instruction, *t.step_instructions]]
    return {
        'tasks': len(tasks),
        'episodes': len(episodes),
        'rooms': len({e.scene for e in episodes.values()}),
        'task_types': {name: type_counts.get(name, 0) for name in TASK_TYPES},
        'alfred_job_types': {name: job_counts[name] for name in jobs},
        'expert_length': {'mean': round(mean(lengths), 3), 'min': min(lengths), 'max': max(lengths)},
        'main_instruction_words': round(mean(len(tokenize(t.instruction)) for t in tasks), 3),
        'step_instructions_words': round(mean(sum(len(tokenize(s)) for s in t.step_instructions)
                                              for t in tasks), 3),
        'vocabulary_size': len(vocabulary(sentences)),
        'distractor_fraction': round(sum(t.has_distractor for t in tasks) / len(tasks), 4),
        'target_not_visible_fraction': round(sum(not t.target_visible_at_start for t in tasks) / len(tasks), 4),
    }


def navigation_twins(tasks: Sequence[Task], resolution: int = TWIN_RESOLUTION) -> dict:
    """How many navigation goals have a twin: another object of the target's type and colour.

    A navigation goal is a Move or Pick & Move task: its go-to leads to an object (the 'near'
    condition's object under DialFRED's goal rule, 'reachable' under the visible one). Its target has a twin when, in the room as the
    task starts (rebuilt in a simulator), another object has the same type and the same colour: an
    appearance answer cannot tell the two apart, the location answer (which says where it is from the
    agent) can. Returns a JSON-ready dict: navigation_goals, same_type (another object of the type),
    twins (of those, one of the same colour too), twin_types (twins per target type, most first),
    not_rebuilt (goals whose first state the simulator refuses to rebuild: a split made under older
    rules than the simulator's now; left out of the other counts).
    """
    goals = [(t, c.obj) for t in tasks if t.task_type in ('Move', 'Pick & Move')
             for c in t.goal if c.kind in ('near', 'reachable')]
    from dialfred_sim.env import DialfredEnv  # lazy: --no-twins --no-image --no-world runs without the simulator
    same_type, twin_types, not_rebuilt = 0, Counter(), 0
    env = DialfredEnv(resolution=resolution)
    try:
        for task, target_id in goals:
            try:
                env.reset(options={'task': task})
            except ValueError:
                not_rebuilt += 1
                continue
            target = env.world.objects[target_id]
            others = [o for o in env.world.objects.values()
                      if o.object_id != target_id and o.type_name == target.type_name]
            same_type += bool(others)
            if any(o.colour == target.colour for o in others):
                twin_types[target.type_name] += 1
    finally:
        env.close()
    return {'navigation_goals': len(goals) - not_rebuilt, 'same_type': same_type, 'twins': sum(twin_types.values()),
            'twin_types': dict(sorted(twin_types.items(), key=lambda kv: (-kv[1], kv[0]))),
            'not_rebuilt': not_rebuilt}


def load_existing(splits: Sequence[str]) -> tuple[dict[str, list[Task]], list[str]]:
    """The tasks of each split that exists on this machine, and the names of the absent ones."""
    found, absent = {}, []
    for name in splits:
        try:
            found[name] = load_split(name)
        except FileNotFoundError:
            absent.append(name)
    return found, absent


# ---------------------------------------------------------------------- the card's tables

def _integer(v) -> str:
    return f'{v:,}'


def _decimal(v) -> str:
    return f'{v:.2f}'


def _percent(v) -> str:
    return f'{100 * v:.1f}%'


def _count_of(part: int, whole: int) -> str:
    return f'{part:,} ({100 * part / whole:.1f}%)' if whole else f'{part:,}'


# (row label, value from split_statistics, how the card writes it)
SUMMARY_ROWS: tuple[tuple[str, Callable[[dict], float], Callable[[float], str]], ...] = (
    ('tasks', lambda s: s['tasks'], _integer),
    ('episodes', lambda s: s['episodes'], _integer),
    ('rooms', lambda s: s['rooms'], _integer),
    ('expert actions per task, mean', lambda s: s['expert_length']['mean'], _decimal),
    ('expert actions per task, min', lambda s: s['expert_length']['min'], _integer),
    ('expert actions per task, max', lambda s: s['expert_length']['max'], _integer),
    ('words in the main instruction, mean', lambda s: s['main_instruction_words'], _decimal),
    ('words in the step-by-step instructions, mean', lambda s: s['step_instructions_words'], _decimal),
    ('vocabulary (main + step instructions)', lambda s: s['vocabulary_size'], _integer),
    ('tasks with a same-class distractor', lambda s: s['distractor_fraction'], _percent),
    ('tasks with the target not visible at start', lambda s: s['target_not_visible_fraction'], _percent),
)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]], align: str) -> list[str]:
    """A GitHub markdown table; `align` holds one 'l' or 'r' per column."""
    rule = ['---:' if a == 'r' else '---' for a in align]
    return ['| ' + ' | '.join(r) + ' |' for r in [list(header), rule, *map(list, rows)]]


def summary_table(stats: dict[str, dict]) -> list[str]:
    rows = [[label] + [fmt(value(s)) for s in stats.values()] for label, value, fmt in SUMMARY_ROWS]
    return markdown_table(['statistic', *stats], rows, 'l' + 'r' * len(stats))


def task_type_table(stats: dict[str, dict]) -> list[str]:
    rows = [[str(k), name] + [_integer(s['task_types'][name]) for s in stats.values()]
            for k, name in enumerate(TASK_TYPES, 1)]
    rows.append(['', '**total**'] + [f"**{_integer(sum(s['task_types'].values()))}**" for s in stats.values()])
    return markdown_table(['#', 'task type', *stats], rows, 'rl' + 'r' * len(stats))


def job_type_table(stats: dict[str, dict]) -> list[str]:
    jobs = list(ALFRED_JOB_TYPES)
    jobs += sorted({j for s in stats.values() for j in s['alfred_job_types']} - set(jobs))
    rows = [[f'`{j}`'] + [_integer(s['alfred_job_types'].get(j, 0)) for s in stats.values()] for j in jobs]
    return markdown_table(['ALFRED job type (episodes)', *stats], rows, 'l' + 'r' * len(stats))


def twin_table(twins: dict[str, dict]) -> list[str]:
    rows = [['navigation goals (`Move` and `Pick & Move` tasks)']
            + [_integer(t['navigation_goals']) for t in twins.values()],
            ['... whose target has another object of its type in the room']
            + [_count_of(t['same_type'], t['navigation_goals']) for t in twins.values()],
            ['... of its type and colour (a twin)']
            + [_count_of(t['twins'], t['navigation_goals']) for t in twins.values()]]
    return markdown_table(['navigation goals', *twins], rows, 'l' + 'r' * len(twins))


def world_table(world: dict) -> list[str]:
    """The world's figures (dialfred_sim.tasks.statistics.world_statistics) beside AI2-THOR's."""
    rows = []

    def row(name, fig, fmt):
        ref = fig.get('reference')
        rows.append([name, fmt(fig['value']), fmt(ref) if ref is not None else '', f'{fig["ratio"]:.2f}'
                     if fig.get('ratio') is not None else ''])
    for key, name in (('navigable_points', 'navigable grid points'), ('receptacles', 'receptacles'),
                      ('openable_fixtures', 'openable fixtures'), ('small_objects', 'small objects at the start')):
        for room, figures in world['rooms'].items():
            row(f'{name}: {room.replace("_", " ")}', figures[key], lambda v: f'{v:.1f}')
    split = world['per_split']
    for key, name, fmt in (('goto_actions', 'actions per go-to', _decimal), ('goto_moves', '... moves', _decimal),
                           ('goto_turns', '... turns', _decimal), ('goto_looks', '... looks', _decimal),
                           ('actions_before_first_interaction', 'expert actions before the first interaction',
                            _decimal),
                           ('small_objects', 'small objects at an episode\'s start', _decimal),
                           ('first_target_multi_instance', 'first target has a second instance of its type', _percent),
                           ('first_target_in_closed', 'first target starts in a closed receptacle', _percent),
                           ('first_target_distance_m', 'first target\'s distance from the start (m)', _decimal),
                           ('target_visible_at_task_start', 'a task\'s first object in the first frame', _percent)):
        row(name, split[key], fmt)
    return markdown_table(['figure', 'here', 'AI2-THOR / ALFRED', 'ratio'], rows, 'lrrr')


def card_text(stats: dict[str, dict], absent: Sequence[str], examples: Sequence[Task],
              twins: dict[str, dict] | None = None, world: dict | None = None) -> str:
    """docs/dataset.md: what the data is, how it differs from the paper's, its tables and examples (the
    words are templates/dataset.md.j2; the numbers and tables come from here)."""
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(Path(__file__).resolve().parent / 'templates'),
                             autoescape=False, keep_trailing_newline=True, undefined=jinja2.StrictUndefined)
    context = dict(
        test_split=TEST_SPLIT, sizes={k: f'{v:,}' for k, v in SPLIT_SIZES.items()},
        valid_unseen_scenes=', '.join(map(str, VALID_UNSEEN_SCENES)),
        test_unseen_scenes=', '.join(map(str, TEST_UNSEEN_SCENES)),
        present=', '.join(f'`{name}`' for name in stats),
        absent=', '.join(f'`{name}` ({SPLIT_SIZES[name]:,} tasks once generated)' for name in absent),
        summary_table='\n'.join(summary_table(stats)), task_type_table='\n'.join(task_type_table(stats)),
        job_type_table='\n'.join(job_type_table(stats)), twins=bool(twins), examples=bool(examples), world=bool(world),
        example_resolution=EXAMPLE_RESOLUTION, example_split=EXAMPLE_SPLIT)
    if twins:
        named = EXAMPLE_SPLIT if EXAMPLE_SPLIT in twins else next(iter(twins))
        left_out = {name: t['not_rebuilt'] for name, t in twins.items() if t.get('not_rebuilt')}
        context.update(twin_table='\n'.join(twin_table(twins)), twins_named=named,
                       twin_types=', '.join(f'{name} {n}' for name, n in twins[named]['twin_types'].items()),
                       left_out=', '.join(f'{n:,} navigation goals of `{name}`' for name, n in left_out.items()))
    if world:
        context.update(world_split=world['split'], world_episodes=world['episodes'],
                       world_gotos=world['per_split']['gotos'], world_table='\n'.join(world_table(world)))
    if examples:
        context['examples_table'] = '\n'.join(markdown_table(
            ['task', 'type', 'main instruction', 'step-by-step instructions'],
            [[f'`{t.task_id}`', t.task_type, t.instruction, ' '.join(t.step_instructions)] for t in examples], 'llll'))
    return env.get_template('dataset.md.j2').render(**context)


# ---------------------------------------------------------------------- example image

def pick_examples(tasks: Sequence[Task], count: int = 6) -> list[Task]:
    """`count` tasks of different types: EXAMPLE_TYPES first, then the rest in paper order; each the
    first task of its type in a room not yet shown (rooms repeat only when all have been used)."""
    by_type: dict[str, list[Task]] = {}
    for t in tasks:
        by_type.setdefault(t.task_type, []).append(t)
    order = [n for n in EXAMPLE_TYPES if n in by_type] + [n for n in TASK_TYPES
                                                          if n in by_type and n not in EXAMPLE_TYPES]
    chosen: list[Task] = []
    for name in order[:count]:
        rooms = {t.scene for t in chosen}
        candidates = by_type[name]
        chosen.append(next((t for t in candidates if t.scene not in rooms), candidates[0]))
    return chosen


def first_frames(tasks: Sequence[Task], resolution: int = EXAMPLE_RESOLUTION) -> list:
    """The agent's RGB frame (HxWx3 uint8) at the start of each task."""
    from dialfred_sim.env import DialfredEnv  # lazy: as in navigation_twins
    env = DialfredEnv(resolution=resolution)
    try:
        return [env.reset(options={'task': t})[0]['rgb'] for t in tasks]
    finally:
        env.close()


def _wrap(draw, text: str, font, width: int) -> list[str]:
    lines, line = [], ''
    for word in text.split():
        trial = f'{line} {word}'.strip()
        if line and draw.textlength(trial, font=font) > width:
            lines.append(line)
            line = word
        else:
            line = trial
    return lines + [line] if line else lines


def example_sheet(tasks: Sequence[Task], frames: Sequence, cols: int = 3, label_lines: int = 4):
    """A PIL image: each frame with its task type (and id) and main instruction written under it."""
    font = ImageFont.load_default(size=12)
    bold = ImageFont.load_default(size=13)
    px, pad, line_h = frames[0].shape[1], 6, 15
    cell_w, cell_h = px + 2 * pad, px + pad + (label_lines + 1) * line_h + pad
    rows = -(-len(frames) // cols)
    sheet = Image.new('RGB', (cols * cell_w, rows * cell_h), 'white')
    draw = ImageDraw.Draw(sheet)
    for k, (task, rgb) in enumerate(zip(tasks, frames)):
        x, y = (k % cols) * cell_w + pad, (k // cols) * cell_h + pad
        sheet.paste(Image.fromarray(rgb), (x, y))
        y += px + 3
        draw.text((x, y), task.task_type, font=bold, fill=(20, 60, 140))
        number = task.task_id.split('/')[-1]
        draw.text((x + px - draw.textlength(number, font=font), y + 1), number, font=font, fill=(130, 130, 130))
        for line in _wrap(draw, f'"{task.instruction}"', font, px)[:label_lines]:
            y += line_h
            draw.text((x, y), line, font=font, fill='black')
    return sheet


# ---------------------------------------------------------------------- entry point

def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--splits', nargs='+', choices=SPLITS, default=list(SPLITS),
                    help='splits to describe (absent ones are listed as absent)')
    ap.add_argument('--card', default=str(CARD), help='markdown file to write')
    ap.add_argument('--image', default=str(IMAGE), help='example image to write')
    ap.add_argument('--no-image', action='store_true', help='keep the existing image (no simulator)')
    ap.add_argument('--no-twins', action='store_true',
                    help='leave out the navigation-twin count (it rebuilds every navigation task: minutes for train)')
    ap.add_argument('--no-world', action='store_true',
                    help='leave out the table of the world against AI2-THOR (it rebuilds every episode of '
                         f'{EXAMPLE_SPLIT})')
    ap.add_argument('--tasks', nargs='+', metavar='PATH', default=None,
                    help='only print the statistics of these split files of your own (e.g. a test split) '
                         'as JSON; the card and image are not written')
    args = ap.parse_args(argv)
    if args.tasks:
        try:
            files = [read_tasks_file(path) for path in args.tasks]
        except (FileNotFoundError, ValueError) as exc:
            print(f'error: {exc}', file=sys.stderr)
            return 1
        described = {str(f.path): {**f.describe(), 'statistics': split_statistics(f.tasks),
                                   'navigation_twins': navigation_twins(f.tasks)} for f in files}
        print(json.dumps(described, indent=2))
        return 0
    splits = [s for s in SPLITS if s in args.splits]        # always in the card's order
    found, absent = load_existing(splits)
    if not found:
        print(f'none of {", ".join(splits)} exists; generate one with '
              '`./dialfred env python3 -m dialfred_sim.tasks.splits <split>`', file=sys.stderr)
        return 1
    stats = {name: split_statistics(tasks) for name, tasks in found.items()}
    twins = {} if args.no_twins else {name: navigation_twins(tasks) for name, tasks in found.items()}
    world = None
    if not args.no_world and EXAMPLE_SPLIT in found:
        from dialfred_sim.tasks.statistics import world_statistics  # lazy: it builds rooms (--no-world: none)
        world = {'split': EXAMPLE_SPLIT, **world_statistics(found[EXAMPLE_SPLIT])}
    examples = pick_examples(found[EXAMPLE_SPLIT]) if EXAMPLE_SPLIT in found else []
    if examples and not args.no_image:
        image = Path(args.image)
        image.parent.mkdir(parents=True, exist_ok=True)
        example_sheet(examples, first_frames(examples)).save(image, optimize=True)
    card = Path(args.card)
    card.parent.mkdir(parents=True, exist_ok=True)
    card.write_text(card_text(stats, absent, examples, twins, world))
    print(json.dumps({'splits': stats, 'navigation_twins': twins, 'world': world, 'absent': absent,
                      'examples': [t.task_id for t in examples],
                      'card': str(card), 'image': str(args.image) if examples else None}, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
