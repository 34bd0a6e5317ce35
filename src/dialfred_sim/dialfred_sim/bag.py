"""Episodes as ROS 2 bags: rosbag2 directories in MCAP storage, written and read without a ROS install.

Whoever drives an episode (the performer node playing a RunTask goal, the launcher's in-process
agent, the `dialogue` job) feeds an `EpisodeRecorder` what it sent and received, and `save` writes one
bag per episode: a rosbag2 directory (`metadata.yaml` + one `.mcap` file, written with the `rosbags`
library, the format `ros2 bag info/play` and Foxglove open). The messages are the project's own ROS
types, serialized as CDR, with their definitions stored in the file (so a reader needs no
dialfred_msgs install):

| topic | type | when |
|---|---|---|
| /task | dialfred_msgs/msg/TaskDescription | once, at the start (what the agent is told, never more) |
| /camera/image | sensor_msgs/msg/Image (rgb8) | after the reset and after every action |
| /camera/image/compressed | sensor_msgs/msg/CompressedImage (png or jpeg) | instead, with `image_format` |
| /agent/pose | dialfred_msgs/msg/AgentPose | with every frame |
| /agent/pose_stamped | geometry_msgs/msg/PoseStamped (frame `map`, yaw only) | with every frame, for 3D views |
| /dialogue/qa | dialfred_msgs/msg/QAPair | every question, the oracle's answer and what the performer took from it |
| /performer/action | dialfred_msgs/msg/Action | every action command |
| /performer/map | sensor_msgs/msg/Image (rgb8) | with every action command of a performer that keeps a map (the map performer): a picture of its belief |
| /performer/map/compressed | sensor_msgs/msg/CompressedImage | instead, with `image_format` |
| /performer/feedback | dialfred_msgs/action/RunTask_Feedback | every action's result (success, questions so far) |
| /episode/result | dialfred_msgs/action/RunTask_Result | once, at the end |

Time in a bag is the simulator's clock, not the wall clock: the reset is at 0 and each action takes
`STEP_NS` (0.1 s), so step k's frame is at k * 0.1 s, the questions asked before action k+1 at
k * 0.1 s + 1, 2, ... ms, the action command at + 50 ms and its feedback with the next frame. A bag of
a seeded episode is therefore the same bytes on every rerun. A bag is written whole under a temporary
name and renamed into place, so an interrupted run never leaves half a bag.

A chained episode (DialFRED's challenge protocol, dialfred_sim.chained) is one bag, `<first task>_chained`,
that holds its tasks in the order played: each task's /task message starts its stretch of the clock, one
step after the task before it ended, and each task ends with its own /episode/result. `read_bag` reads
such a bag as one RecordedEpisode a task (times counted from that task's start); `read_episode` reads a
bag of one task. The bag is written again after every task, so an interrupted episode keeps the tasks it
finished.

`./dialfred replay BAG` (dialfred_bringup.replay) prints a bag's dialogue and actions and renders it.
"""

from __future__ import annotations

import functools
import io
import math
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from .episode import EpisodeObserver
from .protocol import image_array

STEP_NS = 100_000_000          # one action of the simulator's clock: 0.1 s
QA_NS = 1_000_000              # questions before an action: 1 ms apart
ACTION_NS = 50_000_000         # an action command: half a step after the frame it was decided on
RESULT_NS = 90_000_000         # the result: after the last frame
IMAGE_FORMATS = ('raw', 'png', 'jpeg')
CAMERA_FRAME, MAP_FRAME = 'agent_camera', 'map'

TOPICS = {     # topic -> type, in the order their connections are written
    '/task': 'dialfred_msgs/msg/TaskDescription',
    '/camera/image': 'sensor_msgs/msg/Image',
    '/camera/image/compressed': 'sensor_msgs/msg/CompressedImage',
    '/agent/pose': 'dialfred_msgs/msg/AgentPose',
    '/agent/pose_stamped': 'geometry_msgs/msg/PoseStamped',
    '/dialogue/qa': 'dialfred_msgs/msg/QAPair',
    '/performer/map': 'sensor_msgs/msg/Image',
    '/performer/map/compressed': 'sensor_msgs/msg/CompressedImage',
    '/performer/action': 'dialfred_msgs/msg/Action',
    '/performer/feedback': 'dialfred_msgs/action/RunTask_Feedback',
    '/episode/result': 'dialfred_msgs/action/RunTask_Result',
}
RANK = {topic: k for k, topic in enumerate(TOPICS)}
OWN_MESSAGES = ('TaskDescription', 'AgentPose', 'QAPair', 'Action')
RESULT_FIELDS = ('success', 'steps', 'goal_conditions_met', 'goal_conditions_total', 'failed_actions', 'questions',
                 'invalid_questions', 'end_reason', 'error', 'last_action')


class BagError(ValueError):
    """A bag that is missing, truncated or not an episode bag."""


def _interface_dir() -> Path:
    """dialfred_msgs' interface files: the installed share folder, else the source tree beside this package."""
    try:
        # lazy: ament, which the rest of this module does without
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory('dialfred_msgs'))
    except Exception:  # noqa: BLE001 - no ament index (a bare checkout): the source tree has the same files
        return Path(__file__).resolve().parents[2] / 'dialfred_msgs'


@functools.lru_cache(maxsize=1)
def typestore():
    """ROS 2 Jazzy's standard types and dialfred_msgs' (from their .msg / .action files)."""
    # lazy: rosbags, which the rest of this module does without
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    folder = _interface_dir()
    types = {}
    for name in OWN_MESSAGES:
        types.update(get_types_from_msg((folder / 'msg' / f'{name}.msg').read_text(), f'dialfred_msgs/msg/{name}'))
    goal, result, feedback = (folder / 'action' / 'RunTask.action').read_text().split('\n---\n')
    # the action's parts name the package's messages unqualified (Action, QAPair[]): qualify them
    for name in OWN_MESSAGES:
        result, feedback = (re.sub(rf'(?m)^{name}(\[\]|\s)', rf'dialfred_msgs/{name}\1', part) for part in (result, feedback))
    types.update(get_types_from_msg(result, 'dialfred_msgs/action/RunTask_Result'))
    types.update(get_types_from_msg(feedback, 'dialfred_msgs/action/RunTask_Feedback'))
    store.register(types)
    return store


def bag_name(task_id: str, chained: bool = False) -> str:
    """The folder name of a task's bag: valid_unseen/000012 -> valid_unseen_000012; with `chained`, the bag of
    the chained episode that starts with that task: valid_unseen_000012_chained."""
    return task_id.replace('/', '_') + ('_chained' if chained else '')


# --------------------------------------------------------------------------------------------- writing

class EpisodeRecorder:
    """Collects one episode's messages as they happen; `save` writes them as a bag.

    Steps count actions: `observation(0, ...)` is the frame after the reset, `action(k + 1, ...)` the
    action decided on frame k, `question(k, ...)` a QA asked before that action. With `chained`, the
    recorder holds a chained episode: after a task's `result`, `next_task` starts the next one, its steps
    counted again from 0 on the bag's clock one step after the last task's end."""

    def __init__(self, task_id: str, scene: str, split: str, instruction: str, object_nouns: Sequence[str],
                 image_format: str = 'raw', chained: bool = False):
        if image_format not in IMAGE_FORMATS:
            raise ValueError(f'image_format must be one of {", ".join(IMAGE_FORMATS)}, got {image_format!r}')
        self.task_id, self.image_format, self.chained = task_id, image_format, bool(chained)
        self.first_task_id = task_id
        self.store = typestore()
        self.messages: list[tuple[int, str, int, object]] = []    # (time, topic, sequence, message)
        self.offset_ns = 0             # where the current task starts on the bag's clock
        self._ended_ns: Optional[int] = None   # the current task's result time, once recorded
        self._task_start = 0           # index in `messages` of the current task's /task message
        self._questions: dict[int, int] = {}
        self._task(task_id, scene, split, instruction, object_nouns)

    def _task(self, task_id: str, scene: str, split: str, instruction: str, object_nouns: Sequence[str]) -> None:
        self._task_start = len(self.messages)
        self._add(0, '/task', self._t('dialfred_msgs/msg/TaskDescription')(
            task_id=task_id, scene=scene, split=split, instruction=instruction, object_nouns=list(object_nouns)))

    def next_task(self, task_id: str, scene: str, split: str, instruction: str, object_nouns: Sequence[str]) -> None:
        """Start the next task of a chained episode (after the last one's `result`)."""
        if not self.chained:
            raise ValueError('next_task: this recorder holds one task (EpisodeRecorder(..., chained=True) holds a '
                             'chained episode)')
        if self._ended_ns is None:
            raise ValueError(f'next_task: {self.task_id} has no result yet (record it with result() first)')
        self.offset_ns = (self._ended_ns // STEP_NS + 1) * STEP_NS
        self.task_id, self._ended_ns, self._questions = task_id, None, {}
        self._task(task_id, scene, split, instruction, object_nouns)

    @property
    def name(self) -> str:
        """The bag's folder name: its task's, or `<first task>_chained` for a chained episode."""
        return bag_name(self.first_task_id, self.chained)

    def _t(self, name: str):
        return self.store.types[name]

    def _add(self, time_ns: int, topic: str, msg) -> None:
        """Add a message at `time_ns` of the current task (the bag's clock: plus the task's offset)."""
        self.messages.append((self.offset_ns + int(time_ns), topic, len(self.messages), msg))

    def _header(self, time_ns: int, frame_id: str):
        time_ns += self.offset_ns
        stamp = self._t('builtin_interfaces/msg/Time')(sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000)
        return self._t('std_msgs/msg/Header')(stamp=stamp, frame_id=frame_id)

    def observation(self, step: int, rgb: np.ndarray, pose: Sequence[float], camera_height: float) -> None:
        """The frame after `step` actions and the agent's pose (x, y, rotation_deg, horizon_deg)."""
        t = step * STEP_NS
        self._image(t, '/camera/image', CAMERA_FRAME, rgb)
        x, y, rotation, horizon = (float(v) for v in pose)
        self._add(t, '/agent/pose', self._t('dialfred_msgs/msg/AgentPose')(
            x=x, y=y, camera_height=float(camera_height), rotation_deg=rotation, horizon_deg=horizon))
        yaw = math.radians(rotation)
        point = self._t('geometry_msgs/msg/Point')(x=x, y=y, z=float(camera_height))
        quat = self._t('geometry_msgs/msg/Quaternion')(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
        self._add(t, '/agent/pose_stamped', self._t('geometry_msgs/msg/PoseStamped')(
            header=self._header(t, MAP_FRAME), pose=self._t('geometry_msgs/msg/Pose')(position=point, orientation=quat)))

    def _image(self, t: int, topic: str, frame_id: str, rgb: np.ndarray) -> None:
        """An rgb8 Image on `topic`, or a CompressedImage on `topic`/compressed in the recorder's format."""
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f'rgb must be H x W x 3, got shape {rgb.shape}')
        header = self._header(t, frame_id)
        if self.image_format == 'raw':
            h, w = rgb.shape[:2]
            self._add(t, topic, self._t('sensor_msgs/msg/Image')(
                header=header, height=h, width=w, encoding='rgb8', is_bigendian=0, step=w * 3,
                data=rgb.reshape(-1)))
        else:
            self._add(t, f'{topic}/compressed', self._t('sensor_msgs/msg/CompressedImage')(
                header=header, format=self.image_format, data=np.frombuffer(encode_image(rgb, self.image_format),
                                                                            np.uint8)))

    def belief_map(self, step: int, rgb: np.ndarray) -> None:
        """A picture of the performer's belief when it decided action `step` (1-based), on /performer/map."""
        if step < 1:
            raise ValueError(f'actions count from 1, got {step}')
        self._image((step - 1) * STEP_NS + ACTION_NS, '/performer/map', MAP_FRAME, rgb)

    def observation_msg(self, obs) -> None:
        """Record a dialfred_msgs/Observation (its rgb8 frame and pose, at its step_count)."""
        rgb = image_array(obs.rgb, 'rgb8')
        p = obs.pose
        self.observation(int(obs.step_count), rgb, (p.x, p.y, p.rotation_deg, p.horizon_deg), p.camera_height)

    def question_msg(self, step: int, qa) -> None:
        """Record a dialfred_msgs/QAPair asked on the frame after `step` actions."""
        self.question(step, qa.question_type, qa.object_noun, qa.question, qa.answer, qa.valid, qa.heard)

    def result_msg(self, result) -> None:
        """Record a dialfred_msgs RunTask result (or anything with its fields)."""
        self.result(**{k: getattr(result, k) for k in RESULT_FIELDS})

    def question(self, step: int, question_type: str, object_noun: str, question: str, answer: str,
                 valid: bool, heard: str = '') -> None:
        """A QA asked on the frame after `step` actions (before the next action); `heard`: what the performer
        took from it (QAPair.heard)."""
        k = self._questions.get(step, 0) + 1
        self._questions[step] = k
        self._add(step * STEP_NS + k * QA_NS, '/dialogue/qa', self._t('dialfred_msgs/msg/QAPair')(
            question_type=question_type, object_noun=object_noun, question=question,
            answer=answer if valid else '', valid=bool(valid), heard=heard))

    def action(self, step: int, name: str, x: int, y: int, success: bool, questions: int) -> None:
        """Action number `step` (1-based): its command, then its result (as the RunTask feedback says it)."""
        if step < 1:
            raise ValueError(f'actions count from 1, got {step}')
        command = self._t('dialfred_msgs/msg/Action')(action=name, x=int(x), y=int(y))
        self._add((step - 1) * STEP_NS + ACTION_NS, '/performer/action', command)
        self._add(step * STEP_NS, '/performer/feedback', self._t('dialfred_msgs/action/RunTask_Feedback')(
            step=step, action=command, action_success=bool(success), questions=int(questions)))

    def result(self, **fields) -> None:
        """The episode's end (RunTask.Result's fields: success, steps, ..., end_reason, error, last_action)."""
        unknown = set(fields) - set(RESULT_FIELDS)
        if unknown:
            raise ValueError(f'unknown result fields: {", ".join(sorted(unknown))}')
        values = {'success': False, 'end_reason': '', 'error': '', 'last_action': '',
                  **{k: 0 for k in RESULT_FIELDS if k not in ('success', 'end_reason', 'error', 'last_action')},
                  **fields}
        if self._ended_ns is not None:
            raise ValueError(f'{self.task_id}: its result is already recorded')
        mine = self.messages[self._task_start:]        # this task's
        dialogue = [m for _, topic, _, m in mine if topic == '/dialogue/qa']
        actions = [m for _, topic, _, m in mine if topic == '/performer/action']
        asked_at = np.array([(t - self.offset_ns) // STEP_NS for t, topic, _, _ in mine if topic == '/dialogue/qa'],
                            dtype=np.uint32)
        self._add(int(values['steps']) * STEP_NS + RESULT_NS, '/episode/result',
                  self._t('dialfred_msgs/action/RunTask_Result')(**values, dialogue=dialogue, actions=actions,
                                                                 asked_at=asked_at))
        self._ended_ns = max(t for t, *_ in self.messages[self._task_start:])    # the task's last message

    def save(self, folder: Path) -> Path:
        """Write the bag into `folder` (as `folder/<name>`, replacing an older one); returns its path."""
        folder = Path(folder)
        return write_bag(folder / self.name, self.messages, self.store)


def encode_image(rgb: np.ndarray, fmt: str) -> bytes:
    from PIL import Image  # lazy: PIL, which the rest of this module does without
    buf = io.BytesIO()
    if fmt == 'png':
        Image.fromarray(rgb).save(buf, format='PNG', compress_level=6)
    else:
        Image.fromarray(rgb).save(buf, format='JPEG', quality=90)
    return buf.getvalue()


def write_bag(path: Path, messages: list, store=None) -> Path:
    """Write (time, topic, sequence, message) tuples as the rosbag2/MCAP bag `path`, in time order
    (ties: the topic order of TOPICS, then the order they were added). Atomic: a temporary folder
    beside it is renamed into place."""
    from rosbags.rosbag2 import StoragePlugin, Writer  # lazy: rosbags, which the rest of this module does without
    store = store or typestore()
    path = Path(path)
    staging = path.parent / f'.{path.name}.{os.getpid()}.part'
    if staging.exists():
        shutil.rmtree(staging)
    staging.mkdir(parents=True)
    ordered = sorted(messages, key=lambda m: (m[0], RANK[m[1]], m[2]))
    try:
        with Writer(staging / path.name, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            connections = {}
            for topic in TOPICS:
                if any(m[1] == topic for m in ordered):
                    connections[topic] = writer.add_connection(topic, TOPICS[topic], typestore=store)
            for time_ns, topic, _, msg in ordered:
                writer.write(connections[topic], time_ns, store.serialize_cdr(msg, TOPICS[topic]))
        if path.exists():
            old = path.parent / f'.{path.name}.{os.getpid()}.old'
            path.rename(old)
            (staging / path.name).rename(path)
            shutil.rmtree(old)
        else:
            (staging / path.name).rename(path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return path


# --------------------------------------------------------------------------------------------- reading

@dataclass
class RecordedEpisode:
    """One bag read back: everything the agent was told, saw, asked, did and got."""

    path: Path
    task: dict
    frames: list = field(default_factory=list)       # (time_ns, step, rgb array)
    maps: list = field(default_factory=list)         # (step of the action decided on it, rgb array)
    poses: list = field(default_factory=list)        # (step, x, y, rotation_deg, horizon_deg)
    dialogue: list = field(default_factory=list)     # (step, question_type, object_noun, question, answer, valid, heard)
    actions: list = field(default_factory=list)      # (step, action, x, y, success, questions so far)
    result: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)       # topic -> messages
    offset_ns: int = 0       # where the task starts on the bag's clock (0 but in a chained episode's bag)
    place: int = 1           # the task's place in the bag (1: the first or only task) ...
    of: int = 1              # ... of this many (more than 1: a chained episode's bag)

    def frame(self, step: int) -> np.ndarray:
        """The frame after `step` actions (the newest one before it if there is none at `step`)."""
        seen = [f for f in self.frames if f[1] <= step] or self.frames[:1]
        return seen[-1][2]


def decode_image(msg, compressed: bool) -> np.ndarray:
    if compressed:
        from PIL import Image  # lazy: PIL, which the rest of this module does without
        return np.asarray(Image.open(io.BytesIO(bytes(msg.data))).convert('RGB'))
    if msg.encoding != 'rgb8':
        raise BagError(f'camera image encoding {msg.encoding!r}, expected rgb8')
    return image_array(msg)


def read_bag(path: Path) -> list[RecordedEpisode]:
    """Read a bag (a folder written by `write_bag`, or its .mcap file) as one RecordedEpisode per task, in the
    order played: one for a task's bag, one a task for a chained episode's (each task's times counted from its
    /task message). BagError if it is not an episode bag."""
    from rosbags.rosbag2 import Reader  # lazy: rosbags, which the rest of this module does without
    path = Path(path)
    folder = path.parent if path.suffix == '.mcap' else path
    if not (folder / 'metadata.yaml').is_file():
        raise BagError(f'{folder} is not a rosbag2 bag (no metadata.yaml)')
    store = typestore()
    try:
        with Reader(folder) as reader:
            rows = [(c.topic, c.msgtype, t, store.deserialize_cdr(raw, c.msgtype))
                    for c, t, raw in reader.messages()]
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a cut or foreign file
        raise BagError(f'{folder}: cannot be read ({type(exc).__name__}: {exc})') from exc
    rows.sort(key=lambda row: (row[2], RANK.get(row[0], len(RANK))))    # the clock's order (stable within a time)
    starts = [k for k, row in enumerate(rows) if row[0] == '/task']
    if not starts or starts[0] != 0:
        raise BagError(f'{folder}: {"no /task message" if not starts else "messages before the first /task"} '
                       '(not an episode bag?)')
    parts = []
    for n, (a, b) in enumerate(zip(starts, starts[1:] + [len(rows)]), start=1):
        offset, t = rows[a][2], rows[a][3]
        ep = RecordedEpisode(folder, dict(task_id=t.task_id, scene=t.scene, split=t.split, instruction=t.instruction,
                                          object_nouns=list(t.object_nouns)), offset_ns=offset, place=n)
        for topic, _, time_ns, m in rows[a:b]:
            ep.counts[topic] = ep.counts.get(topic, 0) + 1
            time_ns -= offset
            step = time_ns // STEP_NS
            if topic in ('/camera/image', '/camera/image/compressed'):
                ep.frames.append((time_ns, step, decode_image(m, topic.endswith('compressed'))))
            elif topic in ('/performer/map', '/performer/map/compressed'):
                ep.maps.append((step + 1, decode_image(m, topic.endswith('compressed'))))
            elif topic == '/agent/pose':
                ep.poses.append((step, m.x, m.y, m.rotation_deg, m.horizon_deg))
            elif topic == '/dialogue/qa':
                ep.dialogue.append((step, m.question_type, m.object_noun, m.question, m.answer, bool(m.valid),
                                    getattr(m, 'heard', '')))
            elif topic == '/performer/feedback':
                ep.actions.append((int(m.step), m.action.action, int(m.action.x), int(m.action.y),
                                   bool(m.action_success), int(m.questions)))
            elif topic == '/episode/result':
                ep.result = {k: getattr(m, k) for k in RESULT_FIELDS}
        parts.append(ep)
    for ep in parts:
        ep.of = len(parts)
    return parts


def read_episode(path: Path) -> RecordedEpisode:
    """Read the bag of one task (see `read_bag`); BagError if it is not one (a chained episode's bag holds
    several: `read_bag` reads them)."""
    parts = read_bag(path)
    if len(parts) != 1:
        raise BagError(f'{parts[0].path}: {len(parts)} /task messages, a chained episode\'s bag '
                       '(dialfred_sim.bag.read_bag reads it a task at a time)')
    return parts[0]


class RecordingObserver(EpisodeObserver):
    """Records the episode it observes (the episode loop's observer, `episode.play(observers=...)`) as a bag in
    `folder`: the simulator's replies (their `raw` dialfred_msgs/Observation), the questions, the actions with
    their feedback and, when `picture` is given (a performer that keeps a map: its `picture()`), the belief map
    each action was decided on, and with `heard` (qa -> str: protocol.heard_by), what the performer took
    from each answer. `finish(result)` writes the bag with the result (anything with RESULT_FIELDS:
    the episode's state, a RunTask result); with `save_on_end`, the episode's end does so itself. With
    `chained`, one observer sees the tasks of a chained episode in turn, and records them as one bag
    (`<first task>_chained`), written again as each task ends. The one recorder of the simulator-node and
    performer-node paths."""

    def __init__(self, folder: Path, image_format: str = 'raw', picture=None, save_on_end: bool = True,
                 chained: bool = False, heard=None):
        if image_format not in IMAGE_FORMATS:
            raise ValueError(f'image_format must be one of {", ".join(IMAGE_FORMATS)}, got {image_format!r}')
        self.folder, self.image_format, self.picture, self.save_on_end = Path(folder), image_format, picture, save_on_end
        self.chained, self.heard = bool(chained), heard
        self.recorder = None          # the episode's EpisodeRecorder, from its start to finish() (chained: to the last)
        self._open = False            # a task is being recorded (started, not finished)

    def on_started(self, state, reply) -> None:
        t = reply.raw.task            # what the agent is told
        if self.chained and self.recorder is not None:
            if self._open:            # the last task never finished (its goal was dropped): close it as it stands
                self.recorder.result(end_reason='error', error='the task was not finished')
            self.recorder.next_task(t.task_id, t.scene, t.split, t.instruction, t.object_nouns)
        else:
            self.recorder = EpisodeRecorder(t.task_id, t.scene, t.split, t.instruction, t.object_nouns,
                                            image_format=self.image_format, chained=self.chained)
        self._open = True
        self.recorder.observation_msg(reply.raw.observation)

    def on_question(self, state, qa, step: int) -> None:
        if self._open:
            q = qa.question
            self.recorder.question(step, q.question_type, q.object_noun, q.text, qa.answer if qa.valid else '',
                                   bool(qa.valid), self.heard(qa) if self.heard is not None else '')

    def on_action(self, state, action: str, x: int, y: int) -> None:
        if self._open and self.picture is not None:
            self.recorder.belief_map(state.steps + 1, self.picture())

    def on_stepped(self, state, reply, action: str, x: int, y: int) -> None:
        if self._open:
            obs = reply.raw.observation
            self.recorder.action(int(obs.step_count), action, x, y, obs.last_action_success, state.questions)
            self.recorder.observation_msg(obs)

    def on_ended(self, state) -> None:
        if self.save_on_end:
            self.finish(state)

    def finish(self, result) -> Optional[Path]:
        """Write the bag with the task's `result` (None: no task started). The recorder is done with either way,
        but a chained one, which keeps its episode for the next task."""
        recorder, was_open = self.recorder, self._open
        self._open = False
        if not self.chained:
            self.recorder = None
        if recorder is None or not was_open:
            return None
        recorder.result_msg(result)
        return recorder.save(self.folder)
