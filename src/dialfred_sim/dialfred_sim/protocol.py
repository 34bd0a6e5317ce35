"""The dialogue protocol between the simulator, the oracle, a questioner and a performer (no ROS).

Everything two packages must agree on is defined here once, and every package imports it from here:

- `ACTIONS`: ALFRED's 13 low-level actions (as dialfred_msgs/msg/Action.msg lists them); a decision is
  `(action, x, y)`, the target pixel in the simulator's frame or -1, -1 for actions without one.
- `QUESTION_TYPES` and `QUESTION_TEMPLATES`: the oracle's three question types in the paper's order and
  their wording (the paper's templates, section III-B); `question_text` fills one in.
- `Question` and `QA`: a question for the oracle and what it said.
- `MAX_QUESTIONS`: how many questions an agent may ask in a row without acting before its episode ends
  with an error.
- `Agent`, `DialogueAgent` and `Questioner`: what the episode loop calls. An agent is told the task at
  the start (`reset(task, seed)`: a `tasks.PublicTask`, never the expert's plan) and names its next
  action (`act(observation)`); a dialogue agent may first `ask(observation)` and `hear(qa)` the answer,
  until `ask` returns None. A questioner decides for an agent what to ask (`ask(observation, step)`).
- `episode_seed`, `scale_pixel`, `top2_gap`: small rules every driver of an episode applies the same way.
- `image_array` / `fill_image`: the one conversion between sensor_msgs/Image and arrays (duck-typed: no rclpy).
"""

from __future__ import annotations

import array as pyarray
from dataclasses import dataclass
from typing import Any, Optional, Protocol, runtime_checkable

import numpy as np

# ALFRED's 13 low-level actions, as in dialfred_msgs/msg/Action.msg.
ACTIONS = ('MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown', 'Pickup', 'Put', 'Open', 'Close',
           'ToggleOn', 'ToggleOff', 'Slice', 'Stop')

Decision = tuple[str, int, int]

# The oracle's question types (dialfred_msgs/srv/OracleAnswer), in the paper's order.
QUESTION_TYPES = ('location', 'appearance', 'direction')

# The paper's question templates (DialFRED, section III-B); direction questions name no object.
QUESTION_TEMPLATES = {'location': 'Where is the {noun}?', 'appearance': 'What does the {noun} look like?',
                      'direction': 'Which direction should I turn to?'}

MAX_QUESTIONS = 20     # in a row, without acting: an agent that asks more is stopped with an error
# The paper's episode limits: an episode ends after MAX_STEPS actions (truncated) or MAX_FAILURES failed ones.
MAX_STEPS, MAX_FAILURES = 1000, 10


def question_text(question_type: str, noun: str = '') -> str:
    """The question as a person asks it ('Where is the apple?'). ValueError for an unknown type."""
    if question_type not in QUESTION_TEMPLATES:
        raise ValueError(f'unknown question type {question_type!r}; expected one of {QUESTION_TYPES}')
    return QUESTION_TEMPLATES[question_type].format(noun=noun)


@dataclass(frozen=True)
class Question:
    """A question for the oracle: its type and the object it is about (direction questions name none)."""

    question_type: str
    object_noun: str = ''

    @property
    def text(self) -> str:
        """The question's wording; a type that is not one of QUESTION_TYPES (which the oracle refuses) is
        shown as it was asked, 'type: noun'."""
        if self.question_type in QUESTION_TEMPLATES:
            return question_text(self.question_type, self.object_noun)
        return f'{self.question_type}: {self.object_noun}'.rstrip(': ')


@dataclass(frozen=True)
class QA:
    """A question and what the oracle said: `answer` if `valid`, else `reason` why it could not answer."""

    question: Question
    valid: bool
    answer: str = ''
    reason: str = ''


class Agent(Protocol):
    name: str

    def reset(self, task: Any, seed: int) -> None:
        """Start an episode of `task` (a dialfred_sim.tasks.PublicTask); `seed` seeds any randomness."""

    def act(self, observation: Any) -> Decision:
        """The next action (name, x, y) given the latest observation."""


@runtime_checkable
class DialogueAgent(Agent, Protocol):
    """An agent that may ask the oracle before it acts."""

    def ask(self, observation: Any) -> Optional[Question]:
        """A question to ask before the next action, or None to act now."""

    def hear(self, qa: QA) -> None:
        """The oracle's reply to the question just asked."""


class Questioner(Protocol):
    name: str

    def reset(self, task: Any, seed: int) -> None:
        """Start an episode of `task` (a dialfred_sim.tasks.PublicTask); `seed` seeds any randomness."""

    def ask(self, observation: Any, step: int) -> Optional[Question]:
        """A question before the agent's action number `step` + 1, or None."""

    def hear(self, qa: QA) -> None:
        """The oracle's reply to the question just asked."""


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


def observation_field(observation, name: str, default=None):
    """A field of an agent's observation, whichever path gave it: the graph's Observation message
    (an attribute) or the local path's dict (a key)."""
    if isinstance(observation, dict):
        return observation.get(name, default)
    return getattr(observation, name, default)


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
