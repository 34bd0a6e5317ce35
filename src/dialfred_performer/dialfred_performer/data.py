"""Training data for the performer: expert demonstrations with their dialogues, as padded batches.

`DemonstrationDataset` reads a demonstrations folder (`dialfred_sim.tasks.demonstrations`:
frames.npy + tasks.jsonl) and, if there is one, `dialogues.jsonl` beside it. An episode of a task
with n expert actions has n + 1 steps: the frame before each action with that action as the target,
then the frame after the last action with Stop (only where the expert reached the goal).

The paper's augmentation (DialFRED, "Performer": the performer is pre-trained "with instructions and
all possible questions, including a combination of question types and answers"): each task appears
once per combination of question types (`type_combinations()`: none; location; appearance; direction; each
pair; all three). A combination includes, for each of its types, every QA of that type (about each of
the instruction's objects) that the oracle gave at step 0 or at the middle step, drawn per sample from
the dataset's seed.

Stream items (`streams` per task, beside the paper's): a questioner that asks at any step
(`stream_dialogue`): some types, at every step or at some steps, from step 0 or from later on, each
answer the oracle's at its step, read from the task's log of answers (`AnswerLog`). A model trained on
them reads its language as an answer stream (`preprocess.encode_language(stream=True)`,
`PerformerConfig.stream_answers`): a repeated answer adds nothing, and a newer answer of a (type, noun)
supersedes the older one from its step on, so a long task's answers cost tokens only where they
change, and over `max_tokens` the superseded answers give way first.

Recovery examples (`recovery` > 0; the performer's `failure_input`): the expert never fails, so its
demonstrations never show what to do after a click that did nothing, and a performer that clicked a
little too far away goes on as if it had worked (it stops). A share of the items get one failed
interaction inserted a few steps before one of the expert's interactions: the performer clicks from
where the expert was still approaching (that step's action is not a target), and the same frame
follows (nothing moved) with the failed action as the previous one and the expert's approach as the
target. The frames are the demonstration's own: no render.

Bumps (`blocked` > 0, guided walks only; the performer's `failed_moves`): a guided walk never tries a move
that is blocked; it takes the expert's way round (`blocked_steps` finds where). A performer that does as it
is told walks into the obstacle, sees the same frame, and without being told it failed does it again until
the episode ends on failures. A share of the guided items get that failed MoveAhead inserted before each
sidestep (`insert_failed_action`), so the way round follows a bump as it will in a run.

`dialogues.jsonl`, one line per task: {"task_id": ..., "every_step": true, "qas": [{"question_type",
"object_noun", "valid", "answer", "reason", "step"}, ...]} (`preprocess.qa_to_dict`): the log of changes
(a line without "every_step", as folders made before the log, holds the QAs of step 0 and the middle).
`generate_dialogues` makes it by replaying the expert's recorded actions in `DialfredEnv` and asking the
real oracle core (`dialfred_oracle.answers.answer` over `dialfred_sim.ground_truth.snapshot`) at each step.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import zlib
from pathlib import Path
from typing import Callable, NamedTuple, Optional, Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from dialfred_oracle.annotator import ANNOTATION_RESOLUTION, annotate_task, answer_content, paraphrase
from dialfred_oracle.answers import answer
from dialfred_oracle.questions import Answer, oracle_question
from dialfred_oracle.questions.base import direction_bin
from dialfred_oracle.questions.direction import GO_STRAIGHT, STAY, TURN_AROUND, TURN_LEFT, TURN_RIGHT, advice
from dialfred_sim.ground_truth import snapshot, task_object_ids
from dialfred_sim.protocol import ACTIONS, BODY, QA, every_question, question_types
from dialfred_sim.tasks.demonstrations import load_demonstrations, probe_values
from dialfred_sim.tasks.detours import GUIDE_SIDESTEP

from .nn.enc_action import failed_id
from .nn.heads import pixel_cell
from .preprocess import (NEVER, AskedQA, Vocabulary, encode_language, frame_tensor, qa_from_dict, qa_key, qa_to_dict,
                         qa_tokens)



def type_combinations() -> tuple[tuple[str, ...], ...]:
    """Every combination of the registered question types, by size: (), ('location',), ..., all of them."""
    types = question_types()
    return tuple(c for r in range(len(types) + 1) for c in itertools.combinations(types, r))


DIALOGUES_FILE = 'dialogues.jsonl'
STOP = ACTIONS.index('Stop')
START = len(ACTIONS)          # the "previous action" of step 0 (ActionEmbedding's <start>)
NAVIGATION = frozenset(ACTIONS.index(a) for a in ('MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown'))
# Actions that name a target pixel (the pointer is trained and used on these only).
INTERACTIONS = ('Pickup', 'Put', 'Open', 'Close', 'ToggleOn', 'ToggleOff', 'Slice')
INTERACTION_IDS = tuple(ACTIONS.index(a) for a in INTERACTIONS)
MOVE_AHEAD = ACTIONS.index('MoveAhead')
RECOVERY_BEFORE = 3           # a failed click is inserted at most this many (navigation) steps before an interaction


# The tags a detour build's and a guided build's task ids get when their episodes join a plain build's
# (DemonstrationDataset's `detours` and `guided`).
DETOUR_TAG = '~detour'
GUIDED_TAG = '~guided'


def base_task_id(task_id: str) -> str:
    """The task a (maybe detoured or guided) episode's id names: such an episode is held out with its task."""
    return task_id.split(DETOUR_TAG)[0].split(GUIDED_TAG)[0]


def held_out(task_id: str, fraction: float) -> bool:
    """Whether a task is in the validation part: its id's hash (stable across runs) below `fraction`
    (the performer's training and the perception's hold out the same tasks)."""
    return int(hashlib.sha256(task_id.encode()).hexdigest()[:12], 16) / 16 ** 12 < fraction


class TaskDialogue(NamedTuple):
    """A task's line of dialogues.jsonl: its QAs, and whether they are a log of the answers at every step
    (`AnswerLog`; else QAs at step 0 and the middle only, as folders made before logged them)."""

    qas: list[AskedQA]
    every_step: bool


def load_dialogues(path: Path) -> dict[str, TaskDialogue]:
    """{task_id: TaskDialogue} from a dialogues.jsonl; {} if the file does not exist."""
    path = Path(path)
    if not path.exists():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        row = json.loads(line)
        out[row['task_id']] = TaskDialogue([qa_from_dict(d) for d in row['qas']], bool(row.get('every_step')))
    return out


def vocabulary_texts(demonstrations_dir: Path) -> list[str]:
    """Every text a performer reads in a demonstrations folder: instructions, nouns, and each QA of
    dialogues.jsonl as the model reads it (so the marker tokens are counted once as themselves)."""
    demo = load_demonstrations(demonstrations_dir)
    texts = [t['instruction'] for t in demo.tasks] + [n for t in demo.tasks for n in t['object_nouns']]
    by_id = {t['task_id']: t for t in demo.tasks}
    for tid, dialogue in load_dialogues(Path(demonstrations_dir) / DIALOGUES_FILE).items():
        # the QAs of the paper's items (steps 0 and the middle): a log's other steps add no word the
        # oracle's templates lack (prepare.oracle_texts), only counts
        steps = paper_steps(by_id[tid]) if tid in by_id else sorted({a.step for a in dialogue.qas})
        texts += [' '.join(qa_tokens(a.qa)) for s in steps for a in answers_at(dialogue.qas, s)]
    return texts


class DemonstrationDataset(Dataset):
    """Episodes of a demonstrations folder, each task once per combination of question types
    (`combinations`, default `type_combinations()`; once in all if there is no dialogues.jsonl). An item is a dict of tensors (see `collate`)."""

    def __init__(self, demonstrations_dir: Path, vocab: Vocabulary, resolution: int, max_tokens: int = 256,
                 combinations: Optional[Sequence[tuple[str, ...]]] = None, seed: int = 0,
                 only_successful: bool = True, grid_size: int = 0, recovery: float = 0.0,
                 streams: int = 0, stream: bool = False, reworded: float = 0.0, detours: Optional[Path] = None,
                 guided: Optional[Path] = None, blocked: float = 0.0, stream_directions: bool = True,
                 fresh: Sequence[str] = ()):
        self.demo = load_demonstrations(demonstrations_dir)
        self.dialogues = load_dialogues(Path(demonstrations_dir) / DIALOGUES_FILE)
        # Builds of the same tasks with detours, or with guided walks: their episodes join these.
        extras = [(Path(p), tag) for p, tag in ((detours, DETOUR_TAG), (guided, GUIDED_TAG)) if p is not None]
        builds = []
        for path, tag in extras:
            extra = load_demonstrations(path)
            if extra.meta['resolution'] != self.demo.meta['resolution']:
                raise ValueError(f'{path}: {extra.meta["resolution"]} px frames, {demonstrations_dir} has '
                                 f'{self.demo.meta["resolution"]} px')
            if tag == GUIDED_TAG and not extra.meta.get('guide'):
                raise ValueError(f'{path}: not a build with guided walks (prepare-performer --guided)')
            builds.append(extra)
            self.dialogues.update({tid + tag: d for tid, d in load_dialogues(path / DIALOGUES_FILE).items()})
        if builds:
            self.demo = self.demo.joined(builds, [tag for _, tag in extras])
        self.vocab, self.resolution, self.max_tokens, self.seed = vocab, resolution, max_tokens, seed
        combinations = type_combinations() if combinations is None else combinations
        self.combinations = tuple(combinations) if self.dialogues else ((),)
        if streams < 0:
            raise ValueError(f'streams is a number of items per task, got {streams}')
        if streams and not stream:
            raise ValueError('stream items need the stream encoding (stream=True: PerformerConfig.stream_answers)')
        if streams and self.dialogues and not all(d.every_step for d in self.dialogues.values()):
            raise ValueError(f'{demonstrations_dir}: its {DIALOGUES_FILE} has answers at step 0 and the middle only; '
                             'stream items need the answers of every step (make it again with prepare-performer)')
        self.streams = streams if self.dialogues else 0
        self.stream = stream                  # every item's language is encoded as an answer stream
        if fresh and not stream:
            raise ValueError('fresh answers are a kind of answer stream: they need stream=True')
        self.fresh = tuple(fresh)             # types whose answers hold for their own step only
        # False: the stream items of plain and detour episodes ask no direction (the expert's shortest way often
        # walks on where the answer says to turn); a guided walk's items still hear it at every step.
        self.stream_directions = stream_directions
        if not 0 <= reworded <= 1:
            raise ValueError(f'reworded is a probability, got {reworded}')
        self.reworded = reworded              # the share of answers said in the annotator's words (`reword`)
        # A guided build's task without a guided walk is the plain build's episode again: left out.
        self.task_indices = [k for k, t in enumerate(self.demo.tasks) if (t['success'] or not only_successful)
                             and (t.get('guided') is not None or not t['task_id'].endswith(GUIDED_TAG))]
        self.frame_size = self.demo.meta['resolution']
        if not 0 <= recovery <= 1:
            raise ValueError(f'recovery is a probability, got {recovery}')
        self.recovery = recovery
        if not 0 <= blocked <= 1:
            raise ValueError(f'blocked is a probability, got {blocked}')
        if blocked and guided is None:
            raise ValueError('blocked moves are read from guided walks: it needs a guided build')
        self.blocked = blocked                # the share of guided items that bump into what blocks a told move
        self.no_recovery: set[int] = set()    # task positions (index // per_task) never augmented: held out
        self.grid_size = grid_size or resolution // 8      # the pointer's cells per side
        # False: items carry their frames' ids only (`frame_ids`), for a run that gathers the frozen
        # network's output per block (blocks.BlockFeatures) instead of perceiving frames per batch.
        self.with_frames = True
        # A pointer over every pixel learns from every pixel of the target (the build's labels).
        self.pixel_targets = self.grid_size == self.resolution and self.demo.labels is not None
        if self.pixel_targets and self.frame_size != resolution:
            raise ValueError(f'a pixel pointer at {resolution} px needs demonstrations at {resolution} px, '
                             f'not {self.frame_size}')

    @property
    def per_task(self) -> int:
        """Items per task: one per combination, then the stream items."""
        return len(self.combinations) + self.streams

    def __len__(self) -> int:
        return len(self.task_indices) * self.per_task

    def dialogue(self, index: int) -> list[AskedQA]:
        """The QAs of item `index`. A paper item (the first len(combinations) of a task's): for each type
        of its combination, the oracle's answers of that type at step 0 or at the middle step (drawn from
        the seed and the index), in step order. A stream item (the task's other `streams`): see
        `stream_dialogue`. Every item of a guided walk's episode: see `guided_dialogue`."""
        k, c = divmod(index, self.per_task)
        task = self.demo.tasks[self.task_indices[k]]
        dialogue = self.dialogues.get(task['task_id'])
        qas = dialogue.qas if dialogue is not None else []
        rng = np.random.default_rng([self.seed, index])
        if task['task_id'].endswith(GUIDED_TAG):
            return guided_dialogue(qas, self.steps_of(self.task_indices[k]), rng)
        if c >= len(self.combinations):
            if not self.stream_directions:
                qas = [a for a in qas if a.qa.question.question_type != 'direction']
            return stream_dialogue(qas, self.steps_of(self.task_indices[k]), rng)
        chosen = []
        for qtype in self.combinations[c]:
            of_type = [a for a in qas if a.qa.question.question_type == qtype]
            if of_type:
                steps = paper_steps(task) if dialogue.every_step else sorted({a.step for a in of_type})
                chosen += answers_at(of_type, steps[int(rng.integers(len(steps)))])
        return sorted(chosen, key=lambda a: a.step)

    def steps_of(self, k: int) -> int:
        """The steps (and frames) of the demonstration of task k: its actions, and Stop if it succeeded."""
        task = self.demo.tasks[k]
        return len(task['actions']) + bool(task['success'])

    def __getitem__(self, index: int) -> dict:
        k = self.task_indices[index // self.per_task]
        task = self.demo.tasks[k]
        n = len(task['actions'])
        names = [a[0] for a in task['actions']] + (['Stop'] if task['success'] else [])
        actions = torch.tensor([ACTIONS.index(a) for a in names], dtype=torch.long)
        grid = self.grid_size
        cells = [pixel_cell(x, y, grid, self.frame_size) for _, x, y, _ in task['actions']] + [-1] * (len(names) - n)
        masks = torch.zeros(sum(c >= 0 for c in cells), grid * grid, dtype=torch.bool)
        for row, step in enumerate(t for t, c in enumerate(cells) if c >= 0):
            if self.pixel_targets:
                packed = self.demo.labels['targets'][task['first_frame'] + step]
                masks[row] = torch.from_numpy(np.unpackbits(packed)[:grid * grid].astype(bool))
            if not masks[row].any():              # no labels, or the target is not in view: the expert's cell
                masks[row, cells[step]] = True
        dialogue = self.dialogue(index)
        if self.reworded:
            dialogue = reword(dialogue, self.reworded, (self.seed, index))
        lang = encode_language(self.vocab, task['instruction'], dialogue, self.max_tokens, self.stream, fresh=self.fresh)
        item = {'task_id': task['task_id'], 'actions': actions,
                'frame_ids': torch.arange(task['first_frame'], task['first_frame'] + len(names)),
                'previous_actions': torch.cat([torch.tensor([START]), actions[:-1]]),
                'target_cells': torch.tensor(cells, dtype=torch.long), 'target_masks': masks,
                'lang_ids': torch.tensor(lang.ids, dtype=torch.long),
                'lang_types': torch.tensor(lang.types, dtype=torch.long),
                'lang_steps': torch.tensor(lang.steps, dtype=torch.long),
                'lang_positions': torch.tensor(lang.positions if lang.positions is not None else range(len(lang)),
                                               dtype=torch.long),
                'lang_until': torch.tensor(lang.until if lang.until is not None else (NEVER,) * len(lang),
                                           dtype=torch.long),
                'action_valid': torch.tensor([*task.get('targets', [True] * n), *[True] * (len(names) - n)],
                                             dtype=torch.bool)}
        if self.with_frames:
            item['frames'] = frame_tensor(np.asarray(self.demo.frames_of(k)[:len(names)]), self.resolution)
        if self.blocked > 0:
            item = self._bumps(index, item, task)
        return self._recovery(index, item) if self.recovery > 0 else item

    def _bumps(self, index: int, item: dict, task: dict) -> dict:
        """`item` of a guided walk's episode with a failed MoveAhead before each of its sidesteps (`blocked_steps`),
        for a `blocked` share of those items (drawn from the seed and the index): what a performer that does as
        it is told meets there, and the walk's way round after it."""
        if not task.get('guided') or index // self.per_task in self.no_recovery:
            return item
        if np.random.default_rng([self.seed, index, 11]).random() >= self.blocked:
            return item
        dialogue = self.dialogues.get(task['task_id'])
        for at in reversed(blocked_steps(task, dialogue.qas if dialogue is not None else [])):
            item = insert_failed_action(item, at, MOVE_AHEAD)
        return item

    def _recovery(self, index: int, item: dict) -> dict:
        """`item` with a failed interaction inserted (`insert_failed_interaction`), for a `recovery` share
        of the items (drawn from the seed and the index), where the expert approached an interaction."""
        if index // self.per_task in self.no_recovery:
            return item
        rng = np.random.default_rng([self.seed, index, 7])
        if rng.random() >= self.recovery:
            return item
        places = recovery_places(item['actions'].tolist())
        if not places:
            return item
        at, interaction = places[int(rng.integers(len(places)))]
        return insert_failed_interaction(item, at, interaction)


def recovery_places(actions: Sequence[int]) -> list[tuple[int, int]]:
    """(step j, its interaction's step i) where a failed click may be inserted: j is one of the
    RECOVERY_BEFORE navigation steps right before the interaction at i (a click from a little too far)."""
    out = []
    for i, a in enumerate(actions):
        if a not in INTERACTION_IDS:
            continue
        j = i - 1
        while j >= 0 and i - j <= RECOVERY_BEFORE and actions[j] in NAVIGATION:
            out.append((j, i))
            j -= 1
    return out


def insert_failed_interaction(item: dict, at: int, interaction: int) -> dict:
    """A recovery example made of an item (`DemonstrationDataset.__getitem__`'s dict): at step `at` the
    performer does the interaction of step `interaction` too early (`insert_failed_action`)."""
    return insert_failed_action(item, at, int(item['actions'][interaction]))


def insert_failed_action(item: dict, at: int, failed: int) -> dict:
    """`item` (`DemonstrationDataset.__getitem__`'s dict) with action `failed` done at step `at`, from frame
    `at`, failing (neither it nor its pointer is a target); then frame `at` again, with that failed action as
    the previous one (`failed_id`) and the expert's action of step `at` as the target; the rest follows as
    before. QAs asked after step `at` move one step later with their frames."""
    actions, previous = item['actions'], item['previous_actions']
    out = dict(item)
    for key in ('frames', 'frame_ids'):
        if key in item:
            out[key] = torch.cat([item[key][:at + 1], item[key][at:]])
    out['actions'] = torch.cat([actions[:at], torch.tensor([failed]), actions[at:]])
    out['previous_actions'] = torch.cat([previous[:at + 1], torch.tensor([failed_id(failed, len(ACTIONS))]),
                                         previous[at + 1:]])
    out['target_cells'] = torch.cat([item['target_cells'][:at], torch.tensor([-1]), item['target_cells'][at:]])
    out['action_valid'] = torch.cat([item['action_valid'][:at], torch.tensor([False]), item['action_valid'][at:]])
    steps = item['lang_steps']
    out['lang_steps'] = torch.where(steps > at, steps + 1, steps)
    if 'lang_until' in item:
        until = item['lang_until']
        out['lang_until'] = torch.where((until > at) & (until < NEVER), until + 1, until)
    return out


def collate(items: Sequence[dict]) -> dict:
    """Pad items to a batch: frames [B, T, 3, R, R] (if the items have them), frame_ids / actions /
    previous_actions / target_cells [B, T] (padding: -1 / Stop / <start> / -1), step_valid [B, T], action_valid [B, T] (the valid steps whose action is
    a target: not an inserted failed click); lang_ids / types / steps / positions [B, L] (padding 0), lang_until
    [B, L] (padding NEVER),
    lang_valid [B, L]; target_masks [K, C], the target's cells at each of the K steps with a target
    (row-major over [B, T], as `tensor[target_cells >= 0]` orders them)."""
    B = len(items)
    T = max(len(it['actions']) for it in items)
    L = max(max(len(it['lang_ids']) for it in items), 1)
    out = {'task_ids': [it['task_id'] for it in items], 'frame_ids': torch.full((B, T), -1, dtype=torch.long),
           'actions': torch.full((B, T), STOP, dtype=torch.long),
           'previous_actions': torch.full((B, T), START, dtype=torch.long),
           'target_cells': torch.full((B, T), -1, dtype=torch.long),
           'step_valid': torch.zeros(B, T, dtype=torch.bool), 'action_valid': torch.zeros(B, T, dtype=torch.bool),
           'lang_ids': torch.zeros(B, L, dtype=torch.long), 'lang_types': torch.zeros(B, L, dtype=torch.long),
           'lang_steps': torch.zeros(B, L, dtype=torch.long), 'lang_valid': torch.zeros(B, L, dtype=torch.bool),
           'lang_positions': torch.zeros(B, L, dtype=torch.long), 'lang_until': torch.full((B, L), NEVER, dtype=torch.long),
           'target_masks': torch.cat([it['target_masks'] for it in items])}
    with_frames = 'frames' in items[0]
    if with_frames:
        out['frames'] = torch.zeros(B, T, *items[0]['frames'].shape[1:])
    for b, it in enumerate(items):
        t, n = len(it['actions']), len(it['lang_ids'])
        if with_frames:
            out['frames'][b, :t] = it['frames']
        for key in ('frame_ids', 'actions', 'previous_actions', 'target_cells', 'action_valid'):
            out[key][b, :t] = it[key]
        out['step_valid'][b, :t] = True
        for key in ('lang_ids', 'lang_types', 'lang_steps', 'lang_positions', 'lang_until'):
            if key in it:
                out[key][b, :n] = it[key]
        out['lang_valid'][b, :n] = True
    return out


def oracle_qas(env, nouns: Sequence[str], step: int, looks: bool = True) -> list[AskedQA]:
    """The real oracle's answers now (env at some step of a task): location and appearance of each
    noun, and direction, each marked as asked at `step`. With `looks` False the types whose rule reads
    the rendered looks of the object (`OracleQuestion.reads_looks`: appearance) are left out, and
    nothing is rendered for them (most of a step's cost)."""
    questions = [q for q in every_question(nouns) if looks or not oracle_question(q.question_type).reads_looks]
    snap = snapshot(env, task_object_ids(env) if looks else ())
    out = []
    for q in questions:
        a = answer(snap, q.question_type, q.object_noun)
        out.append(AskedQA(QA(q, a.valid, a.text, a.reason), step))
    return out


class AnswerLog:
    """A task's answers at every step as a log of changes: every QA at step 0, then a QA at a later
    step only where its answer (valid, words, reason) differs from the last one logged for its
    (type, noun). `answers_at` reads back what the oracle said at any step."""

    def __init__(self):
        self.entries: list[AskedQA] = []
        self._last: dict[tuple[str, str], tuple] = {}

    def add(self, qas: Sequence[AskedQA]) -> None:
        for a in qas:
            key, value = qa_key(a), (a.qa.valid, a.qa.answer, a.qa.reason)
            if self._last.get(key) != value:
                self._last[key] = value
                self.entries.append(a)


def answers_at(entries: Sequence[AskedQA], step: int, types: Optional[Sequence[str]] = None) -> list[AskedQA]:
    """What the oracle said at `step` (of `types`, default all), read from a task's log of changes
    (`AnswerLog`; also from a dialogue of QAs at step 0 and the middle, at one of those steps): for each
    (type, noun), its last entry at or before `step`, re-marked as asked at `step`; in the order the
    keys first appear (the oracle's order of asking)."""
    now: dict[tuple[str, str], AskedQA] = {}
    for a in entries:
        if a.step <= step and (types is None or a.qa.question.question_type in types):
            now[qa_key(a)] = a
    return [AskedQA(a.qa, step) for a in now.values()]


def paper_steps(task: dict) -> tuple[int, ...]:
    """The steps a task's paper items draw their QAs from: 0 and the middle of its recorded actions."""
    return tuple(sorted({0, len(task['actions']) // 2}))


# How a stream item asks (`stream_dialogue`).
STREAM_EVERY_STEP = 0.4      # the share of stream items that ask at every step from their first
STREAM_P = (0.1, 0.6)        # the others ask at each step with a probability drawn from this range
STREAM_LATE_START = 0.5      # the share whose first question comes at a step of the task's first half (else step 0)
STREAM_NOUN_P = 0.7          # at a step that asks, an object type asks about each noun with this probability


def stream_dialogue(entries: Sequence[AskedQA], steps: int, rng: np.random.Generator) -> list[AskedQA]:
    """The QAs of a stream item: a questioner that asks at any step of the task's `steps`, heard from the
    task's log of answers (`AnswerLog`). Its types: each type the log has, with probability 1/2 (at
    least one). From its first step on (0, or a step of the task's first half for STREAM_LATE_START of
    the items) it asks at every step (STREAM_EVERY_STEP of the items) or at each step with a probability
    drawn from STREAM_P; a step that asks asks each of its types (an object type about each noun with
    STREAM_NOUN_P, at least one), and hears what the oracle said at that step (`answers_at`)."""
    kinds = [t for t in question_types() if any(a.qa.question.question_type == t for a in entries)]
    if not kinds:
        return []
    chosen = [t for t in kinds if rng.random() < 0.5] or [kinds[int(rng.integers(len(kinds)))]]
    p = 1.0 if rng.random() < STREAM_EVERY_STEP else float(rng.uniform(*STREAM_P))
    first = int(rng.integers(steps // 2 + 1)) if rng.random() < STREAM_LATE_START else 0
    out = []
    for step in range(first, steps):
        if rng.random() >= p:
            continue
        for kind in chosen:
            now = answers_at(entries, step, (kind,))
            if len(now) > 1:
                now = [a for a in now if rng.random() < STREAM_NOUN_P] or [now[int(rng.integers(len(now)))]]
            out += now
    return out


def guided_dialogue(entries: Sequence[AskedQA], steps: int, rng: np.random.Generator) -> list[AskedQA]:
    """The QAs of an item of a guided walk's episode (`dialfred_sim.tasks.detours.GuidedWalk`), whose moves are
    the direction answers': the direction at every step (without them the walk's turns have no reason), and
    with probability 1/2 the other types as a stream item asks them (`stream_dialogue`)."""
    others = [a for a in entries if a.qa.question.question_type != 'direction']
    out = stream_dialogue(others, steps, rng) if others and rng.random() < 0.5 else []
    out += [a for step in range(steps) for a in answers_at(entries, step, ('direction',))]
    order = {t: n for n, t in enumerate(question_types())}
    return sorted(out, key=lambda a: (a.step, order[a.qa.question.question_type]))


def reword(dialogue: Sequence[AskedQA], share: float, seed: tuple) -> list[AskedQA]:
    """`dialogue` with each valid answer said in the synthetic annotator's words (`annotator.paraphrase` of
    its parts) with probability `share`: whether, and the words, drawn from `seed` and the answer itself, so
    that an answer heard again in one item is worded again the same way (a repeat stays a repeat)."""
    out = []
    for a in dialogue:
        q = a.qa
        if q.valid:
            key = zlib.crc32(f'{q.question.question_type}|{q.question.object_noun}|{q.answer}'.encode())
            rng = np.random.default_rng([*seed, key, 13])
            if rng.random() < share:
                content = answer_content(Answer(True, q.answer, question_type=q.question.question_type,
                                                object_noun=q.question.object_noun),
                                         q.question.question_type, q.question.object_noun)
                q = QA(q.question, True, paraphrase(content, rng), q.reason)
        out.append(AskedQA(q, a.step))
    return out


def paraphrase_texts(demonstrations_dir: Path, every: int = 10, draws: int = 4) -> list[str]:
    """Answers of a demonstrations folder in the annotator's words (`reword` of every `every`-th task's
    paper QAs, `draws` times each), as the model reads them: the words a reworded training adds to the
    vocabulary."""
    demo = load_demonstrations(demonstrations_dir)
    dialogues = load_dialogues(Path(demonstrations_dir) / DIALOGUES_FILE)
    texts = []
    for k, task in enumerate(demo.tasks[::every]):
        d = dialogues.get(task['task_id'])
        if d is None:
            continue
        qas = [a for s in paper_steps(task) for a in answers_at(d.qas, s)]
        for n in range(draws):
            texts += [' '.join(qa_tokens(a.qa)) for a in reword(qas, 1.0, (k, n))]
    return texts


def generate_dialogues(demonstrations_dir: Path, limit: Optional[int] = None, out: Optional[Path] = None) -> Path:
    """Write dialogues.jsonl for (the first `limit` tasks of) a demonstrations folder: the oracle's
    answers at every step of each expert episode (`task_dialogue`), replaying the recorded actions in
    DialfredEnv at the demonstrations' resolution. Returns the file's path."""
    from dialfred_sim.env import DialfredEnv  # lazy: gymnasium, which the rest of this module does without
    demonstrations_dir = Path(demonstrations_dir)
    demo = load_demonstrations(demonstrations_dir)
    env = DialfredEnv(resolution=demo.meta['resolution'])
    out = Path(out) if out else demonstrations_dir / DIALOGUES_FILE
    lines = [dialogue_line(task, task_dialogue(env, task)) for task in demo.tasks[:limit]]
    env.close()
    out.write_text(''.join(lines))
    return out


def task_dialogue(env, task: dict, at_start: Optional[Callable] = None) -> list[AskedQA]:
    """The oracle's answers at every step of one task record of tasks.jsonl, as a log of changes
    (`AnswerLog`): `env` (a DialfredEnv at the demonstrations' resolution) replays the recorded actions;
    the looks (appearance) are asked at step 0 and at the middle step n // 2 only.
    `at_start(env)`, if given, is called right after the reset (e.g. to annotate the task there)."""
    env.reset(options={'task_id': task['task_id']})
    if at_start is not None:
        at_start(env)
    n = len(task['actions'])
    log = AnswerLog()
    for step in range(n + 1):
        log.add(oracle_qas(env, task['object_nouns'], step, looks=step in (0, n // 2)))
        if step < n:
            name, x, y, _ = task['actions'][step]
            env.step({'action': name, 'pixel': (x, y)})
    return log.entries


def dialogue_line(task: dict, qas: Sequence[AskedQA]) -> str:
    """One line of dialogues.jsonl (with its newline): the task's log of changes (`AnswerLog`)."""
    return json.dumps({'task_id': task['task_id'], 'every_step': True, 'qas': [qa_to_dict(a) for a in qas]}) + '\n'


class OracleProbe:
    """`task_dialogue`'s log asked while the demonstrations are rendered (a probe of
    `build_demonstrations`), which saves replaying every task a second time: the oracle at every step
    of the expert's recorded actions, the looks at step 0 and the middle n // 2. The middle is known
    only when the episode ends; it is taken to be len(expert actions) // 2, and a task that stopped
    early with another middle gets no QAs (prepare replays it with `task_dialogue`). `end` returns
    {'qas': the line's qas (qa_to_dict's form) or None}."""

    def begin(self, task) -> None:
        self.task = task
        self.nouns = list(task.object_nouns)
        self.middle = len(task.expert_actions) // 2
        self.log = AnswerLog()

    def looks_at(self, step: int) -> bool:
        """Whether the looks (appearance) are asked at `step`: at 0 and the middle."""
        return step in (0, self.middle)

    def __call__(self, env, step: int) -> None:
        self.log.add(oracle_qas(env, self.nouns, step, looks=self.looks_at(step)))

    def end(self, record: dict) -> dict:
        if len(record['actions']) // 2 != self.middle:
            return {'qas': None}
        return {'qas': [qa_to_dict(a) for a in self.log.entries]}


class DetourProbe(OracleProbe):
    """OracleProbe for a build with detours (`dialfred_sim.tasks.detours`), whose episodes' lengths are known
    only at their end: the oracle at every step, the looks at step 0 only, and always the log (a detour
    folder gives stream items, which read the looks of step 0 on; the paper's items, at the middle step,
    come from the plain build)."""

    def looks_at(self, step: int) -> bool:
        return step == 0

    def end(self, record: dict) -> dict:
        return {'qas': [qa_to_dict(a) for a in self.log.entries]}


class DirectionGuide:
    """A guided walk's `advise(env)` (`dialfred_sim.tasks.detours.GuidedWalk`): what the oracle's direction
    answer at the agent's pose says to do, as `examples/direction_follower.py` reads it: "go straight ahead"
    MoveAhead, "turn left" / "turn right" the turn, "turn around" a turn to the side the expert's end lies
    on (left when straight behind), "You don't need to move." Stop."""

    def __call__(self, env) -> str:
        a = env.world.agent
        i, j, rotation, horizon = env.task.expert_end_pose
        agent, end = (float(a.x), float(a.y), float(a.rotation)), (i * BODY.grid_step, j * BODY.grid_step, float(rotation))
        said = advice(agent, end)
        if said == TURN_AROUND:
            side = direction_bin(agent[:2], agent[2], end[:2])
            return 'RotateRight' if 'right' in side else 'RotateLeft'
        return GUIDED_ACTION[said]


# What each direction answer tells a guided walk to do (DirectionGuide; "turn around": by side).
GUIDED_ACTION = {GO_STRAIGHT: 'MoveAhead', TURN_LEFT: 'RotateLeft', TURN_RIGHT: 'RotateRight', STAY: 'Stop'}


def blocked_steps(task: dict, entries: Sequence[AskedQA]) -> list[int]:
    """The steps of a guided walk's record (`task['guided']`: [step, actions walked, moves back]) at which the
    way the direction answer said was blocked, and the walk took the expert's way round instead
    (`detours.GuidedWalk`'s sidestep): told "go straight ahead" (the one told move that a wall or furniture can
    block), it did something else. A sidestep's own steps are not looked at again."""
    if not task.get('guided'):
        return []
    at, walked, _ = task['guided']
    out, skip = [], 0
    for step in range(at, at + walked):
        if skip:
            skip -= 1
            continue
        said = answers_at(entries, step, ('direction',))
        if said and said[0].qa.answer == GO_STRAIGHT and task['actions'][step][0] != 'MoveAhead':
            out.append(step)
            skip = GUIDE_SIDESTEP - 1
    return out


def obeys(answer: str, action: str) -> bool:
    """Whether `action` does what the oracle's direction `answer` says: its move or turn ("turn around":
    either turn); for "You don't need to move.", anything but a move or a turn (a look, an interaction, Stop)."""
    if answer == TURN_AROUND:
        return action in ('RotateLeft', 'RotateRight')
    if answer == STAY:
        return action not in ('MoveAhead', 'RotateLeft', 'RotateRight')
    return GUIDED_ACTION.get(answer) == action


class AnnotatingProbe(OracleProbe):
    """OracleProbe, and at step 0 the synthetic annotators' row of the task as
    `scripts/annotate_dialogues.py` makes it (`annotator.annotate_task` on the task's start, seen at
    the annotators' resolution through `DialfredEnv.viewed_at`), which saves that script's own reset
    of every train task. `end` adds {'annotation': the row's JSON}."""

    def __call__(self, env, step: int) -> None:
        if step == 0:
            with env.viewed_at(ANNOTATION_RESOLUTION):
                self.annotation = annotate_task(env, self.task).to_json()
        super().__call__(env, step)

    def end(self, record: dict) -> dict:
        return {**super().end(record), 'annotation': self.annotation}


def probed_annotations(demonstrations_dir: Path) -> dict[str, dict]:
    """{task_id: annotator row JSON} that an AnnotatingProbe made while `demonstrations_dir` was built."""
    return {tid: v['annotation'] for tid, v in probe_values(demonstrations_dir).items()
            if isinstance(v, dict) and v.get('annotation') is not None}
