"""The dialogue protocol between the simulator, the oracle, a questioner and a performer (no ROS).

Everything two packages must agree on is defined here once, and every package imports it from here:

- `ACTIONS`: ALFRED's 13 low-level actions (as dialfred_msgs/msg/Action.msg lists them); a decision is
  `(action, x, y)`, the target pixel in the simulator's frame or -1, -1 for actions without one.
- `question_kinds()`: the registered question types (`QuestionType`: name, wording, whether a question of
  it names an object, its short token), the paper's first (`PAPER_QUESTION_TYPES`); everything that lists
  the types calls it (or `question_types()`, `object_question_types()`) when it needs them: the
  questioner's outputs, the performer's marks, the oracle's aliases, the annotator's choices.
  `question_text` fills one in; `register_question_type` adds one (docs/questioner.md, "Adding a
  question type"). The oracle's rules of each type are in `dialfred_oracle.questions`.
- `Question` and `QA`: a question for the oracle and what it said.
- `PROTOCOLS`: how a split's tasks are played: `expert` (each task from the expert's state at its first
  action, the paper's tables) or `chained` (an episode's tasks in order, each from the state the agent's
  own actions left: DialFRED's challenge test; `dialfred_sim.chained`).
- `MAX_QUESTIONS`: how many questions an agent may ask in a row without acting before its episode ends
  with an error.
- `Observation`: what an agent is given after a reset or a step, whichever path served it (made once
  from the graph's message by `messages.observation_from_msg`, from a DialfredEnv's reset or step by
  `env_observation`, which `EnvServer` calls).
- `Agent`, `DialogueAgent` and `Questioner`: what the episode loop calls. An agent is told the task at
  the start (`reset(task, seed)`: a `tasks.PublicTask`, never the expert's plan) and names its next
  action (`act(observation)`); a dialogue agent may first `ask(observation)` and `hear(qa)` the answer,
  until `ask` returns None. A questioner decides for an agent what to ask (`ask(observation, step)`).
- The optional capabilities, each a `Protocol` checked with isinstance: `Listener` (hears answers),
  `ConfusionSource` (action probabilities, for the model-confusion questioner), `MapPainter` (a picture
  of what it knows, for the live view and the GIFs), `Privileged` (told the whole task: the expert),
  `Continuing` (an agent that keeps what it knows from one chained task to the next: the map performer),
  `PerformerAware` (a questioner that attaches to its performer) and `GapQuestioner` (a questioner that
  may ask given the performer's top-2 gap).
- `Body` and `BODY`: the robot's body, the one description of its camera (field of view, default resolution,
  height, look limits), its grid step, turn and look steps and its reach, with the camera's ray geometry. The
  simulator is built from it and agents read it from here (docs/simulator.md, "Another simulator").
- `episode_seed`, `scale_pixel`, `top2_gap`: small rules every driver of an episode applies the same way.
- `image_array` / `fill_image`: the one conversion between sensor_msgs/Image and arrays (duck-typed: no rclpy).
"""

from __future__ import annotations

import array as pyarray
import functools
import math
from dataclasses import dataclass
from typing import Any, Optional, Protocol, runtime_checkable

import numpy as np

# ALFRED's 13 low-level actions, as in dialfred_msgs/msg/Action.msg.
ACTIONS = ('MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown', 'Pickup', 'Put', 'Open', 'Close',
           'ToggleOn', 'ToggleOff', 'Slice', 'Stop')

Decision = tuple[str, int, int]


@dataclass(frozen=True)
class QuestionType:
    """A question type: `name` (what /oracle/answer takes), `template` (its wording; '{noun}' where the
    object goes), `names_object` (a question of it is about an object of the instruction), `token` (its
    short name: the oracle accepts it, the performer's input marks its QAs with '<token>')."""

    name: str
    template: str
    names_object: bool
    token: str


# The paper's question types (dialfred_msgs/srv/OracleAnswer), in its order, with its templates
# (DialFRED, section III-B); direction questions name no object. Its tables have a column for each.
PAPER_QUESTION_KINDS: tuple[QuestionType, ...] = (
    QuestionType('location', 'Where is the {noun}?', True, 'loc'),
    QuestionType('appearance', 'What does the {noun} look like?', True, 'app'),
    QuestionType('direction', 'Which direction should I turn to?', False, 'dir'))
PAPER_QUESTION_TYPES: tuple[str, ...] = tuple(q.name for q in PAPER_QUESTION_KINDS)

_KINDS: list[QuestionType] = list(PAPER_QUESTION_KINDS)


def question_kinds() -> tuple[QuestionType, ...]:
    """Every registered question type: the paper's, then the others as registered. Everything that lists
    the types (the questioner's outputs, the performer's marks, the oracle's aliases, the annotator's
    choices) calls this when it needs them, so a type registered at any time is seen everywhere after."""
    return tuple(_KINDS)


def question_types() -> tuple[str, ...]:
    """The names of `question_kinds()`."""
    return tuple(q.name for q in _KINDS)


def object_question_types() -> tuple[str, ...]:
    """The registered types whose questions name an object."""
    return tuple(q.name for q in _KINDS if q.names_object)


def question_kind(question_type: str) -> QuestionType:
    """The registered type `question_type` (ValueError naming the registered ones otherwise)."""
    for q in _KINDS:
        if q.name == question_type:
            return q
    raise ValueError(f'unknown question type {question_type!r}; expected one of {question_types()}')


def register_question_type(kind: QuestionType) -> None:
    """Add a question type after the paper's, for every part that lists the types from then on
    (docs/questioner.md, "Adding a question type"). ValueError for a name or token that is taken."""
    if any(kind.name == q.name or kind.token == q.token for q in _KINDS):
        raise ValueError(f'a question type named {kind.name!r} or with the token {kind.token!r} exists')
    _KINDS.append(kind)


def unregister_question_type(question_type: str) -> None:
    """Remove a type registered after the paper's (ValueError for one of the paper's or an unknown one)."""
    if question_type in PAPER_QUESTION_TYPES:
        raise ValueError(f"{question_type!r} is one of the paper's question types and stays registered")
    _KINDS.remove(question_kind(question_type))


def names_object(question_type: str) -> bool:
    """Whether a question of `question_type` names an object (False for a type that is none)."""
    return question_type in object_question_types()


def every_question(nouns) -> list['Question']:
    """The paper's All QAs about a task whose instruction names `nouns`: each object question type of each
    noun in turn (location, appearance), then each type that names no object (direction)."""
    return [Question(t, n) for n in nouns for t in object_question_types()] + \
        [Question(t) for t in question_types() if not names_object(t)]


@dataclass(frozen=True)
class Body:
    """The robot's body as every package sees it: AI2-THOR's agent as ALFRED uses it.

    Angles are degrees; a positive horizon looks down. Reach is measured as AI2-THOR measures its
    `visibilityDistance`: horizontally from the agent's vertical axis to the point under the target pixel."""

    fov_deg: float = 90.0            # the camera's field of view, across the frame's height
    resolution: int = 128            # the simulator's default square frame, pixels (docs/figures.md)
    camera_height: float = 1.5       # metres above the floor
    horizon_min: float = -30.0       # LookUp limit
    horizon_max: float = 60.0        # LookDown limit
    start_horizon: float = 30.0      # ALFRED starts every episode looking 30 degrees down
    grid_step: float = 0.25          # metres per MoveAhead
    turn_step: int = 90              # degrees per RotateLeft / RotateRight
    look_step: float = 15.0          # degrees per LookUp / LookDown
    reach: float = 1.5               # metres

    def pixel_rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) [height, width]: each pixel centre's offset on the image plane at unit depth along the view
        axis (right, up), for a `width` x `height` frame with `fov_deg` across its height."""
        t = math.tan(math.radians(self.fov_deg) / 2)
        u = ((np.arange(width) + 0.5) / width * 2 - 1) * t * (width / height)
        v = (1 - (np.arange(height) + 0.5) / height * 2) * t
        return np.broadcast_to(u[None, :], (height, width)), np.broadcast_to(v[:, None], (height, width))

    def ray_lengths(self, width: int, height: int) -> np.ndarray:
        """[height, width]: the length of each pixel's ray per metre of depth along the view axis."""
        u, v = self.pixel_rays(width, height)
        return np.sqrt(1 + u ** 2 + v ** 2)

    def reach_lengths(self, width: int, height: int, horizon: float) -> np.ndarray:
        """Per pixel of a `width` x `height` frame taken at camera pitch `horizon`, the horizontal distance from
        the agent's vertical axis of the point seen there, per metre of depth along the view axis (reach is
        measured so, whatever the point's height, not from the eye). Cached and read-only."""
        return _reach_lengths(self, width, height, horizon)


@functools.lru_cache(maxsize=32)
def _reach_lengths(body: Body, width: int, height: int, horizon: float) -> np.ndarray:
    u, v = body.pixel_rays(width, height)
    pitch = math.radians(horizon)
    along = math.cos(pitch) + v * math.sin(pitch)     # along the heading, per metre of depth
    lengths = np.sqrt(along ** 2 + u ** 2).astype(np.float32)
    lengths.flags.writeable = False     # shared by every caller (cached)
    return lengths


BODY = Body()

# How a split's tasks are played (dialfred_sim.chained): each from the expert's state at its first action
# (the paper's protocol, the default), or an episode's tasks in order on the agent's own state.
PROTOCOLS = ('expert', 'chained')
DEFAULT_PROTOCOL = 'expert'

MAX_QUESTIONS = 20     # in a row, without acting: an agent that asks more is stopped with an error
# The paper's episode limits: an episode ends after MAX_STEPS actions (truncated) or MAX_FAILURES failed ones.
MAX_STEPS, MAX_FAILURES = 1000, 10


def question_text(question_type: str, noun: str = '') -> str:
    """The question as a person asks it ('Where is the apple?'). ValueError for an unknown type."""
    return question_kind(question_type).template.format(noun=noun)


@dataclass(frozen=True)
class Question:
    """A question for the oracle: its type and the object it is about (direction questions name none)."""

    question_type: str
    object_noun: str = ''

    @property
    def text(self) -> str:
        """The question's wording; a type that is not registered (which the oracle refuses) is shown as it
        was asked, 'type: noun'."""
        if self.question_type in question_types():
            return question_text(self.question_type, self.object_noun)
        return f'{self.question_type}: {self.object_noun}'.rstrip(': ')


@dataclass(frozen=True)
class QA:
    """A question and what the oracle said: `answer` if `valid`, else `reason` why it could not answer."""

    question: Question
    valid: bool
    answer: str = ''
    reason: str = ''


@dataclass(frozen=True, eq=False)
class Observation:
    """What an agent sees and knows after a reset or a step (the fields of dialfred_msgs/Observation an
    agent may use), the same whichever path served it.

    rgb: HxWx3 uint8; depth: HxW float32 metres along the optical axis; segmentation: HxW int32 instance
    ids (either None when the simulator was asked not to send it); pose: (x, y, rotation_deg,
    horizon_deg) of the camera, as dialfred_msgs/AgentPose. The arrays must not be changed in place."""

    rgb: np.ndarray
    depth: Optional[np.ndarray] = None
    segmentation: Optional[np.ndarray] = None
    pose: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    held_object: str = ''
    last_action_success: bool = True
    last_action_error: str = ''
    step_count: int = 0
    failed_actions: int = 0

    def __post_init__(self):
        rgb = self.rgb
        if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f'Observation.rgb must be an HxWx3 uint8 array, got {_describe(rgb)}')


def env_observation(obs: dict, info: dict) -> Observation:
    """What an agent is given after a reset or a step of a DialfredEnv (`obs`, `info` as they return them):
    the local path's one conversion, as `messages.observation_from_msg` is the graph's."""
    return Observation(rgb=obs['rgb'], depth=obs['depth'], segmentation=obs['segmentation'],
                       pose=tuple(float(v) for v in obs['pose']), held_object=str(info['held_object']),
                       last_action_success=bool(info['last_action_success']),
                       last_action_error=str(info['last_action_error']), step_count=int(info['step_count']),
                       failed_actions=int(info['failed_actions']))


def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f'a {value.dtype} array of shape {value.shape}'
    return type(value).__name__


def as_observation(value) -> Observation:
    """`value` as an Observation: an Observation as it is, an HxWx3 uint8 frame as an Observation of that
    frame alone (for calling an agent by hand). ValueError for anything else."""
    if isinstance(value, Observation):
        return value
    if isinstance(value, np.ndarray):
        return Observation(rgb=value)
    raise ValueError(f'expected a protocol.Observation or an HxWx3 uint8 frame, got {_describe(value)}')


class Agent(Protocol):
    name: str

    def reset(self, task: Any, seed: int) -> None:
        """Start an episode of `task` (a dialfred_sim.tasks.PublicTask); `seed` seeds any randomness."""

    def act(self, observation: Observation) -> Decision:
        """The next action (name, x, y) given the latest observation."""


@runtime_checkable
class Listener(Protocol):
    """Hears the oracle's answers (every dialogue agent and questioner; a performer that reads QAs)."""

    def hear(self, qa: QA) -> None:
        """The oracle's reply to the question just asked."""


@runtime_checkable
class DialogueAgent(Agent, Protocol):
    """An agent that may ask the oracle before it acts."""

    def ask(self, observation: Observation) -> Optional[Question]:
        """A question to ask before the next action, or None to act now."""

    def hear(self, qa: QA) -> None:
        """The oracle's reply to the question just asked."""


class Questioner(Protocol):
    name: str

    def reset(self, task: Any, seed: int) -> None:
        """Start an episode of `task` (a dialfred_sim.tasks.PublicTask); `seed` seeds any randomness."""

    def ask(self, observation: Observation, step: int) -> Optional[Question]:
        """A question before the agent's action number `step` + 1, or None."""

    def hear(self, qa: QA) -> None:
        """The oracle's reply to the question just asked."""


@runtime_checkable
class ConfusionSource(Protocol):
    """An agent that says how sure it is: the model-confusion questioner reads the top-2 gap of these."""

    def action_probabilities(self, observation: Observation) -> np.ndarray:
        """Probabilities over ACTIONS of the action `act` would choose now (without choosing it)."""


@runtime_checkable
class MapPainter(Protocol):
    """An agent that keeps a picture of what it knows (the map performer): the live view and the GIFs
    show it beside the camera's frame."""

    def picture(self) -> Optional[np.ndarray]:
        """An HxWx3 uint8 picture of the agent's state now, or None before it has one."""


@runtime_checkable
class AnswerReader(Protocol):
    """An agent that reads answers into fields (the map performer's parser): `understood(qa)` says what it
    took from one, so that a person can see it ("heard: Fridge, to your left"), on the terminal and on
    `dialogue/qa` (QAPair.heard)."""

    def understood(self, qa: QA) -> str:
        """What the agent took from `qa`'s answer; '' when there is nothing to say."""


def heard_by(agent: Any, qa: QA) -> str:
    """What `agent` took from `qa` (AnswerReader.understood), '' for an agent that reads no fields or fails
    to say (what it heard is shown, never relied on)."""
    if not isinstance(agent, AnswerReader):
        return ''
    try:
        said = agent.understood(qa)
    except Exception:  # noqa: BLE001 - a user's agent: showing what it heard must never end its episode
        return ''
    return said if isinstance(said, str) else ''


@runtime_checkable
class Privileged(Protocol):
    """A reference agent that is told the whole task (the expert): only built-in ones may say True, and
    results mark them."""

    privileged: bool


def is_privileged(agent_or_class: Any) -> bool:
    """Whether an agent (or an agent class) is a privileged reference (`Privileged` with True)."""
    return bool(isinstance(agent_or_class, Privileged) and agent_or_class.privileged)


@runtime_checkable
class Continuing(Protocol):
    """An agent that carries what it knows from one task of a chained episode to the next (the map
    performer keeps its map, its pose on it and what it holds). Under the chained protocol every task
    after an episode's first starts with `carry_on` instead of `reset`; an agent without it is reset
    before every task (the Episodic Transformer starts each with a fresh memory, as it was trained)."""

    def carry_on(self, task: Any, seed: int) -> None:
        """Start the next task of the episode (a PublicTask) in the world as the last one left it."""


@runtime_checkable
class PerformerAware(Protocol):
    """A questioner that reads the performer it asks for (the model-confusion questioner): given it at
    the start of every episode."""

    def attach(self, performer: Any) -> None:
        """The performer this questioner asks for."""


@runtime_checkable
class GapQuestioner(Protocol):
    """A questioner that may decide from the performer's top-2 gap (`needs_gap`: the model-confusion
    questioner, a learned one with the confusion timing): in process it reads the gap of the performer
    it is attached to (`ask`); the questioner node gets the gap with each request instead."""

    needs_gap: bool

    def ask_given_gap(self, observation: Observation, step: int, gap: Optional[float]) -> Optional[Question]:
        """ask(), given the performer's top-2 gap before this action (None: not known; refused when
        `needs_gap`)."""


def episode_seed(run_seed: int, task_index: int) -> int:
    """A seed for one episode from the run's seed and the task's index in its split, so that an
    episode plays the same whichever worker runs it, in whatever order, and after a resume."""
    return int(np.random.SeedSequence([run_seed, task_index]).generate_state(1)[0])


def scale_pixel(x: int, y: int, from_resolution: int, to_resolution: int) -> tuple[int, int]:
    """The pixel (x, y) of a `from_resolution` frame in a `to_resolution` frame (same camera):
    the pixel whose centre is nearest the same point. Negative (no target) stays as it is."""
    if x < 0 or y < 0 or from_resolution == to_resolution:
        return x, y

    def one(v: int) -> int:
        return min(to_resolution - 1, int((v + 0.5) * to_resolution / from_resolution))

    return one(x), one(y)


def top2_gap(probabilities) -> float:
    """The gap between the two most likely actions' probabilities (0.0 with fewer than two): the
    performer's confusion signal, which the model-confusion questioner reads."""
    p = np.sort(np.asarray(probabilities, dtype=float))[::-1]
    return float(p[0] - p[1]) if len(p) >= 2 else 0.0


# ------------------------------------------------------------------------- images <-> arrays
# sensor_msgs/Image encodings of the simulator's three frames: colour, depth in metres, instance ids.
IMAGE_DTYPES = {'rgb8': np.uint8, '32FC1': np.float32, '32SC1': np.int32}


def image_array(msg, encoding: Optional[str] = None) -> np.ndarray:
    """The pixels of a sensor_msgs/Image (an rclpy message, a bag's message, anything with `encoding`,
    `height`, `width` and `data`) as an array: HxWx3 for rgb8, HxW for depth and segmentation.
    `encoding`: the one the caller expects (ValueError for another)."""
    if encoding is not None and msg.encoding != encoding:
        raise ValueError(f'expected an {encoding} image, got encoding {msg.encoding!r}')
    if msg.encoding not in IMAGE_DTYPES:
        raise ValueError(f'unknown image encoding {msg.encoding!r}; expected one of {", ".join(IMAGE_DTYPES)}')
    shape = (msg.height, msg.width, 3) if msg.encoding == 'rgb8' else (msg.height, msg.width)
    dtype = np.dtype(IMAGE_DTYPES[msg.encoding])
    data = bytes(msg.data)
    if len(data) != int(np.prod(shape)) * dtype.itemsize:
        raise ValueError(f'a {msg.width}x{msg.height} {msg.encoding} image has {int(np.prod(shape)) * dtype.itemsize} '
                         f'bytes of data, this one {len(data)}')
    return np.frombuffer(data, dtype=dtype).reshape(shape)


def image_buffer(array: np.ndarray) -> memoryview:
    """The bytes of `array` as a flat memoryview (no copy when it is C-contiguous)."""
    return memoryview(np.ascontiguousarray(array)).cast('B')


def image_bytes(array: np.ndarray) -> pyarray.array:
    """The bytes of `array` as array.array: about 7x faster for rclpy to take than bytes (which it
    converts per element); frombytes reads the numpy buffer directly, one copy."""
    data = pyarray.array('B')
    data.frombytes(image_buffer(array))
    return data


def fill_image(msg, array: np.ndarray, encoding: str, header) -> None:
    """Write `array` (HxW or HxWxC) into the sensor_msgs/Image `msg` without copying its pixels.

    `data` is given the array's own buffer (`image_buffer`). The caller must not change `array` in
    place while `msg` may still be sent; the simulator renders every frame into new arrays."""
    msg.header = header
    msg.height, msg.width = int(array.shape[0]), int(array.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = int(array.strides[0])
    # Past the property's setter, which would copy into an array.array: rclpy's C conversion reads
    # any object with the buffer protocol (one memcpy), as test_sim_node checks byte for byte.
    msg._data = image_buffer(array)
