"""Episodes in which nobody asks, played once and replayed by every setting that asks nothing in them.

A performer that is told nothing plays a task the same way whichever questioner stands beside it, as long
as that questioner asks nothing: the performer sees the same frames and the same (empty) dialogue, so it
takes the same actions and the episode ends the same. Many episodes of the tables are such: an RL
questioner asks in about one episode in ten, Random QA draws "no question" in one in four. So the
evaluation stage keeps, for every task, what the no-question setting of a performer saw
(`SilentEpisodes.save`: the observation before each action and how the episode ended). Another setting
of the same performer first runs its questioner alone along those observations (`silent_throughout`:
reset, then `ask(observation, step)` before each action, exactly the calls the episode loop makes); if it
never asks, the kept episode is its episode, and no world is reset or rendered. If it asks, the episode is
played as usual.

Only questioners that read nothing but the observations qualify: one that decides from the performer's
confusion (the model-confusion timing: `protocol.GapQuestioner.needs_gap`) reads the performer's state,
which no one kept.
The replayed results are the played ones field by field but for the wall time (tests/bringup/test_silent.py
compares them; `./dialfred reproduce`'s check stage plays the first tasks of every setting through the graph
again and compares them too).

Under the chained protocol the unit is the chained episode, its tasks played in order in one world: the
no-question setting keeps every task of an episode in one file (`save_chain`), and another setting takes the
whole episode from there only if its questioner, reset for each task as the episode loop resets it, asks
nothing in any of them (a question in one task changes the world every later task starts from). The map
performer's map, carried from task to task, is a function of the same observations, so it is rebuilt the
same.

A store holds the episodes of one performer setup; `key` names it (agent, checkpoint, split, seed, camera,
goal rule, protocol) and a store of another key is not read. A missing or unreadable file is no episode:
that task (or chained episode) is played.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import zipfile
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from dialfred_performer.model_registry import PERFORMER_MODELS
from dialfred_questioner.baselines import QuestioningAgent
from dialfred_sim.episode import EpisodeObserver, EpisodeState
from dialfred_sim.protocol import GapQuestioner, Observation, PerformerAware

FORMAT = 'dialfred-silent/3'    # 2: the episode's state keeps its actions and question steps (traces); 3: segments
SMALL_FIELDS = ('pose', 'held_object', 'last_action_success', 'last_action_error', 'step_count', 'failed_actions')


class SeenBeforeActions(EpisodeObserver):
    """Keeps the observation an agent acts on at each step of an episode (the reset's, then each step's
    but the last)."""

    def __init__(self):
        self.seen: list[Observation] = []
        self.actions = 0

    def on_started(self, state, reply) -> None:
        self.seen, self.actions = [reply.observation], 0      # each task of a chained episode starts anew

    def on_action(self, state, action: str, x: int, y: int) -> None:
        self.actions += 1

    def on_stepped(self, state, reply, action: str, x: int, y: int) -> None:
        self.seen.append(reply.observation)

    @property
    def before_actions(self) -> list[Observation]:
        return self.seen[:self.actions]


def replayable(agent) -> Optional[object]:
    """The questioner of `agent` whose silence can be checked without playing (a questioning agent's,
    one that does not watch the performer), else None. A questioner watches the performer when it decides
    from its top-2 gap (a `GapQuestioner` that `needs_gap`: the confusion timing) or attaches to it
    without saying what it reads (`PerformerAware` alone)."""
    if not isinstance(agent, QuestioningAgent):
        return None
    q = agent.questioner
    if isinstance(q, GapQuestioner):
        return None if q.needs_gap else q
    return None if isinstance(q, PerformerAware) else q


def silent_key(run) -> dict:
    """What fixes an episode without questions besides the task: the performer (its kind and checkpoint),
    the tasks, the seed, the camera, the goal rule and the protocol of `run` (an eval_run.EvalRun)."""
    o = run.options
    source = run.tasks_source
    return {'agent': o.agent, 'checkpoint': run.checkpoint_sha256 if o.agent in PERFORMER_MODELS else None,
            'tasks': f'{source.split}-{source.sha256}' if source else o.split, 'seed': o.seed,
            'resolution': o.resolution, 'goal_rule': o.goal_rule, 'protocol': o.protocol}


def silent_throughout(agent: QuestioningAgent, told, seed: int, observations: Sequence[Observation]) -> bool:
    """Whether the questioner of `agent` (a `replayable` one), reset as the agent resets it for the task it
    is `told` with `seed`, asks nothing before any of the actions taken on `observations`. It is left
    reset: the episode loop resets it again before a played episode."""
    agent.reset_questioner(told, seed)
    return all(agent.questioner.ask(observation, step) is None for step, observation in enumerate(observations))


class SilentEpisodes:
    """A folder of no-question episodes of one performer setup (`key`), one file per task (per chained
    episode under the chained protocol)."""

    def __init__(self, folder: Path, key: dict):
        self.folder, self.key = Path(folder), key

    def _path(self, name: str) -> Path:
        return self.folder / (name.replace('/', '__') + '.npz')

    def save(self, task_id: str, observations: Sequence[Observation], state: EpisodeState) -> bool:
        """Keep one episode (written whole or not at all). False, nothing written, for an episode that
        is not silent or whose observations carry depth or segmentation (not kept here)."""
        return self._write(task_id, [(observations, state)])

    def load(self, task_id: str) -> Optional[tuple[list[Observation], EpisodeState]]:
        """(the observations before each action, the episode's end state), or None: no file, a damaged one,
        or one of another key."""
        kept = self._read(task_id, 1)
        return kept[0] if kept else None

    def save_chain(self, episode_id: str, tasks: Sequence[tuple[Sequence[Observation], EpisodeState]]) -> bool:
        """Keep a chained episode, its tasks' (observations before each action, end state) in order; False,
        nothing written, if any task of it is not `save`'s kind of episode."""
        return self._write(episode_id, tasks)

    def load_chain(self, episode_id: str, tasks: int) -> Optional[list[tuple[list[Observation], EpisodeState]]]:
        """`save_chain`'s tasks of an episode of `tasks` tasks, or None (as `load`; a file of another length too)."""
        return self._read(episode_id, tasks)

    def _write(self, name: str, segments: Sequence[tuple[Sequence[Observation], EpisodeState]]) -> bool:
        if not segments:
            return False
        for observations, state in segments:
            if state.questions or state.dialogue or not observations:
                return False
            if any(o.depth is not None or o.segmentation is not None for o in observations):
                return False
        meta = {'format': FORMAT, 'key': self.key,
                'segments': [{'state': {f.name: getattr(state, f.name) for f in dataclasses.fields(state)
                                        if f.name != 'dialogue'},
                              'steps': [{k: getattr(o, k) for k in SMALL_FIELDS} for o in observations]}
                             for observations, state in segments]}
        buffer = io.BytesIO()
        np.savez(buffer, rgb=np.stack([o.rgb for observations, _ in segments for o in observations]),
                 meta=np.array(json.dumps(meta)))
        self.folder.mkdir(parents=True, exist_ok=True)
        path = self._path(name)
        tmp = path.with_name(f'{path.name}.{os.getpid()}.tmp')
        tmp.write_bytes(buffer.getvalue())
        tmp.replace(path)
        return True

    def _read(self, name: str, segments: int) -> Optional[list[tuple[list[Observation], EpisodeState]]]:
        path = self._path(name)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                rgb, meta = data['rgb'], json.loads(str(data['meta']))
            parts = meta.get('segments') if meta.get('format') == FORMAT and meta.get('key') == self.key else None
            if parts is None or len(parts) != segments or sum(len(p['steps']) for p in parts) != len(rgb):
                return None
            kept, start = [], 0
            for part in parts:
                frames = rgb[start:start + len(part['steps'])]
                start += len(part['steps'])
                kept.append(([Observation(rgb=frame, **{**step, 'pose': tuple(step['pose'])})
                              for frame, step in zip(frames, part['steps'])], EpisodeState(**part['state'])))
            return kept
        except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):   # damaged or foreign: play it
            return None
