"""`MapAgent`: the performer that maps and plans (no ROS).

Each step: the perception network (trained on our frames; `dialfred_performer.perception`) reads
the RGB frame and predicts every cell's class and depth; the pose is dead-reckoned from the agent's
own last action and whether it succeeded (`last_action_success` of the observation, which the
graph's Observation message carries); the frame's points vote into the `SemanticMap`; then the
current step of the instruction's plan (`language.parse_instruction`) picks the action:

- the step's object is seen within reach in this frame: act on it, clicking the cell of its mask
  nearest the mask's centre among those within reach (an appearance answer's colour picks among
  several masks of a pickupable type; a mask out of the direction a location answer gave is passed over);
- it is on the map: walk to the nearest grid point from which it can be reached, turn to it and tilt
  the camera to its height; if it still is not in reach there, give that place up. With a location
  answer, the places in its direction come first, then a look that way, and only then the others;
- it has not been seen: look around once, then go where answers point (a location answer's
  direction and receptacle, a direction answer's turn), else to the nearest unexplored edge of the map.

What is seen where the hand carries an object is left off the map (it would block the grid point
ahead in every direction the agent turns to). Nothing privileged is read: not the simulator's depth,
segmentation, pose, held object or error text (a test removes them from every observation and gets
the same episode).

`action_probabilities(observation)` is the agent's confusion signal for the model-confusion
questioner: sure when it acts on what it sees, less so when walking to a mapped place, unsure when
exploring or lost. It decides on a copy of the plan's state and changes nothing, so that a questioner
may ask for it before the dialogue of the step: whatever the order of calls, a frame is perceived
first, then the answers of its step are heard (against the pose the frame was seen from), then the
action is decided (the performer node and worker processes play the same episode).
"""

from __future__ import annotations

import copy
from collections import Counter, deque
from pathlib import Path
from typing import Any, Optional

import numpy as np
import torch

from dialfred_sim.protocol import ACTIONS, QA, Decision, Observation, as_observation
from dialfred_sim.tasks.demonstrations import label_classes
from dialfred_sim.catalog import load_catalog

from ..model import load_checkpoint, read_state
from ..perception import PERCEPTION_FORMAT, load_perception
from .geometry import Pose
from .language import Fact, InstructionError, Step, parse_instruction
from .picture import belief_picture
from .reading import AnswerReading
from .rules import EXPLORING, INTERACTIONS, MAX_STEP_ACTIONS, REACH_M, REPLAN, SURE, THERE, WALKING
from .semantic_map import SemanticMap
from .sensing import Sensing
from .targets import Targets
from .wayfinding import Navigation

# Attributes a decision reads but never changes (shared with the copy action_probabilities decides on).
_SHARED = frozenset({'net', 'catalog', 'classes', 'class_id', 'map', 'rgb', 'labels', 'conf', 'ray', 'points', 'class_prob',
                     '_pending', '_heard'})


class MapAgent(Sensing, AnswerReading, Targets, Navigation):
    """The map-and-plan performer over a perception network (see the module). Its parts, each in a module
    of its own over the state `reset_state` makes: `Sensing` (the frame, the pose, the hand), `AnswerReading`
    (answers as facts), `Targets` (what to click), `Navigation` (moving, facing, exploring); here, the plan's
    steps, what follows a failure, and the decision."""

    name = 'map'

    def __init__(self, net: torch.nn.Module, resolution: int = 64):
        self.net = net.eval()
        self.resolution = int(resolution)
        self.classes = label_classes()
        self.class_id = {name: k for k, name in enumerate(self.classes)}
        self.catalog = load_catalog()
        self.reset_state()

    @classmethod
    def from_checkpoint(cls, path: Path) -> 'MapAgent':
        """From a perception performer's checkpoint (its frozen network) or a perception.pt file."""
        state = read_state(path)                      # once: either file is read from this dict
        if state.get('format') == PERCEPTION_FORMAT:
            net, _ = load_perception(path, state)
            return cls(net, net.config.resolution)
        model, _, info = load_checkpoint(path, state)
        if info['config'].visual != 'perception':
            raise ValueError(f'{path}: the map performer needs a perception network; this performer '
                             f'sees through a {info["config"].visual!r} encoder')
        return cls(model.visual.net, model.config.resolution)

    # ------------------------------------------------------------------ episode

    def reset_state(self) -> None:
        self.task = None
        self.pose = Pose()
        self.map = SemanticMap(len(self.classes))
        self.plan: deque[Step] = deque()
        self.reading = None
        self.held: Optional[str] = None
        self.held_known = False
        self.held_confirmed = False
        self.opened: set[str] = set()
        self.placed: dict[str, tuple] = {}     # type -> (receptacle type, map point) of the agent's Put of it
        self._just_put: Optional[str] = None     # the type put down by the last action, if it was a Put
        self.facts: dict[tuple[str, str], tuple[Fact, Pose]] = {}
        self.turns: deque[str] = deque()
        self.direction: Optional[tuple[Fact, int]] = None     # the last direction answer and the step it came at
        self.turn_aside = 'RotateLeft'         # following directions: the side to step to when a move is blocked
        self.sidestep = False                  # the macro is that step aside (wayfinding._follow)
        self.aside_points = 1                  # ... its length in grid points (longer after each circle)
        self.followed: Counter = Counter()     # (i, j, heading) -> arrivals there while following (circles)
        self.followed_last: Optional[tuple] = None     # the pose of the last answer followed
        self.last: Optional[tuple[str, Step, tuple]] = None     # (action, step, (x, y) map point)
        self.step = 0
        self.step_actions = 0
        self.step_failures = 0
        self.scans = 0
        self.approached = False
        self.macro: deque[str] = deque()
        self.anchors: dict[str, tuple[float, float]] = {}     # type -> map point of the instance acted on
        self.stand_anchor: Optional[tuple[str, float, float]] = None   # (type, map point) acted on or gone to last
        self.stand_goal: Optional[tuple] = None    # the last stand's pose (i, j, heading, horizon); () none
        self.stand_actions = 0
        self.cone_spent: set[str] = set()      # types whose location answer's direction was searched in vain
        self.last_ray: Optional[float] = None
        self.visits: Counter = Counter()
        self.confidence = EXPLORING
        self.decided = Step('stop')
        self._observed = None            # (step, id(observation)) of the frame perceived last
        self._heard: deque[QA] = deque()  # answers not yet taken in (see _observe)
        self.answers = 0
        self._pending = None             # (key, answers, twin, outputs) of action_probabilities
        self.log: list[str] = []
        self.rgb: Optional[np.ndarray] = None           # the frame perceived last
        self.class_prob: Optional[torch.Tensor] = None  # the network's class probabilities of that frame
        self.carried: Optional[tuple] = None   # a chained task's start: the last task's final decision (carry_on)

    def reset(self, task: Any, seed: int = 0) -> None:
        """Start an episode of `task` (a PublicTask: only its instruction is read)."""
        self.reset_state()
        self._start(task)

    # What a chained episode's next task starts with (carry_on): the map, the pose on it and the frame
    # last seen, the hand, what the agent opened and where it put things.
    CARRIED = ('pose', 'map', 'held', 'held_known', 'held_confirmed', 'opened', 'placed', 'rgb', 'class_prob')

    def carry_on(self, task: Any, seed: int = 0) -> None:
        """The next task of a chained episode (protocol.Continuing): what the agent knows of the room and
        its hand (`CARRIED`) stays, the plan, the answers and the step's state start anew. The last
        task's final action is reckoned when the first frame of this one, which reports its outcome,
        arrives. Without a task before, the same as `reset`."""
        if self.task is None:
            self.reset(task, seed)
            return
        kept = {name: getattr(self, name) for name in self.CARRIED}
        last = self.last
        self.reset_state()
        self.__dict__.update(kept)
        self.carried = last
        self._start(task)

    def _start(self, task: Any) -> None:
        self.task = task
        try:
            self.reading = parse_instruction(task.instruction)
            self.plan = deque(self.reading.steps)
        except InstructionError as exc:
            self.log.append(f'cannot read the instruction: {exc}')
            self.plan = deque([Step('stop')])


    # ------------------------------------------------------------------ the plan (perception: sensing.py)

    def _step_done(self, action: str) -> None:
        step = self.plan.popleft() if self.plan else None
        self.step_actions, self.step_failures = 0, 0
        self.approached = False
        if step is not None and step.kind == 'put' and (step.close or step.target in self.opened) and \
                self.catalog.get(step.target) is not None and self.catalog[step.target].openable:
            self.plan.appendleft(Step('close', step.target))

    def _after_failure(self, action: str, step: Step, point) -> None:
        t = self.catalog.get(step.target)
        if action == 'Put' and t is not None and t.openable and step.target not in self.opened and \
                self.step_failures == 1:
            self.plan.appendleft(Step('open', step.target))        # closed: open it first
            return
        if action == 'Put' and not self.held_confirmed and (t is None or not t.openable or step.target in self.opened):
            self.held = None                      # nothing to put down: fetch it first (see _current)
            self.step_failures = 0
            return
        if action == 'Pickup' and self.held is None and ('location', step.target) not in self.facts and \
                any(s.kind == 'put' and s.held == step.target for s in self.plan):
            # A hand that cannot take the object the task puts down most likely holds it already (unless a
            # location answer said where in the room it lies: then the click missed it); that counts as
            # confirmed, so a Put that fails again is a bad place, not an empty hand (else the two rules
            # would trade the step back and forth, each resetting the failures).
            self.held, self.held_confirmed = step.target, True
            if self.plan and self.plan[0] == step:
                self.plan.popleft()
            self.step_failures = 0
            return
        if action == 'Open' and self.step_failures == 1 and self.last_ray is not None and self.last_ray < 1.0:
            # Too near for the door to swing open: one step back, then again.
            self.macro = deque(['RotateLeft', 'RotateLeft', 'MoveAhead', 'RotateLeft', 'RotateLeft'])
            return
        if action == 'Open' and step.search and self.last_ray is not None and self.last_ray < REACH_M - 0.1:
            # Opened to look inside, clicked well within reach, and refused: most likely open already (the
            # location answer does not say). Look inside as it is; nothing to close afterwards.
            self.opened.add(step.target)
            if self.plan and self.plan[0] == step:
                self.plan.popleft()
            shut = Step('close', step.target, search=True)
            if shut in self.plan:
                self.plan.remove(shut)
            self.step_failures = 0
            return
        if self.step_failures >= 2 and point is not None:
            self.map.exclude(self.class_id[step.target], point[0], point[1])
            self.step_failures = 0

    def _current(self) -> Step:
        while self.plan:
            step = self.plan[0]
            if step.kind == 'put' and self.held_known and self.held != step.held and step.held:
                self.plan.appendleft(Step('pickup', step.held))
                continue
            return step
        return Step('stop')

    # ------------------------------------------------------------------ acting

    def _decide(self, depth: int = 0) -> tuple[str, int, int, Optional[tuple]]:
        step = self._current()
        self.decided = step
        self.step_actions += 1
        if depth > 4:
            return 'Stop', -1, -1, None
        if not self.macro:
            self.sidestep = False
        if self.macro:
            action = self.macro.popleft()
            if action == 'MoveAhead' and (self.map.blocked and self.pose.forward() in self.map.blocked):
                self.macro.clear()
                if self.sidestep:        # the step aside is blocked too: the other side next time
                    self.turn_aside = 'RotateRight' if self.turn_aside == 'RotateLeft' else 'RotateLeft'
            else:
                self.confidence = WALKING
                return action, -1, -1, None
        follow = self._follow()        # a direction answer of this step: the way to where the expert ended
        if follow == THERE and step.kind == 'goto':      # the agent stands there: the go-to is done
            self.plan.popleft()
            self.step_actions = 0
            return self._decide(depth + 1)
        if follow == THERE and step.kind == 'stop':
            self.confidence = SURE
            return 'Stop', -1, -1, None
        if step.kind == 'stop' and follow is not None:
            return follow, -1, -1, None
        if step.kind == 'stop':
            move = self._stand()
            if move is not None:
                return move, -1, -1, None
        if step.kind == 'stop' or self.step_actions > MAX_STEP_ACTIONS:
            self.confidence = SURE if step.kind == 'stop' else EXPLORING
            if step.kind != 'stop':
                self.log.append(f'gave up on {step.kind} {step.target} after {MAX_STEP_ACTIONS} actions')
            return 'Stop', -1, -1, None
        k = self.class_id.get(step.target)
        if k is None:
            self.log.append(f'no class for {step.target}')
            return 'Stop', -1, -1, None
        target = self._target_pixel(k, step)
        if step.kind == 'goto':
            if target is not None:
                self.stand_anchor = (step.target, *target[1])
                self.plan.popleft()
                self.step_actions = 0
                return self._decide(depth + 1)
        elif target is not None:
            if self.step_failures >= 2 and not self.approached:
                self.approached = True              # twice failed from here: one step nearer, then again
                free = self.map.traversable()
                off = self.map.node_offset()
                a, b = self.pose.forward()
                if free[a + off, b + off]:
                    self.confidence = WALKING
                    return 'MoveAhead', -1, -1, None
            self.confidence = SURE
            (r, c), point = target
            self.last_ray = float(self.ray[r, c])
            return INTERACTIONS[step.kind], r, c, point
        if follow not in (None, THERE):      # nothing to act on in reach: walk where the answer says
            return follow, -1, -1, None
        move = self._navigate(k, step)
        if move == REPLAN:
            return self._decide(depth + 1)
        if move is None:
            self.log.append(f'lost: no way to {step.kind} {step.target} (seen: {len(self.map.object_cells(k)[0])} cells)')
            self.confidence = EXPLORING
            if step.kind == 'goto' and self._seen_within(k, REACH_M + 0.3):
                self.plan.popleft()
                return self._decide(depth + 1)
            return 'Stop', -1, -1, None
        return move, -1, -1, None


    def _observe(self, observation: Observation) -> tuple:
        """Perceive the frame (once per step), then take in the answers heard since; its key."""
        if self.task is None:
            raise RuntimeError('reset() the agent before it acts')
        key = (self.step, id(observation))
        if self._observed != key:
            self._update(as_observation(observation))
            self._observed = key
        while self._heard:
            self._take_in(self._heard.popleft())
        return key

    def _outputs(self) -> tuple:
        action, r, c, point = self._decide()
        return action, r, c, point, self.confidence

    def action_probabilities(self, observation: Observation) -> np.ndarray:
        """Probabilities over ACTIONS of the next action: the chosen one gets the agent's confidence,
        the rest is spread over the others (the model-confusion questioner's signal)."""
        key = self._observe(observation)
        twin = forked(self)
        outputs = twin._outputs()
        self._pending = (key, self.answers, twin, outputs)
        confidence, action = outputs[4], outputs[0]
        p = np.full(len(ACTIONS), (1.0 - confidence) / (len(ACTIONS) - 1), np.float32)
        p[ACTIONS.index(action)] = confidence
        return p

    def picture(self) -> np.ndarray:
        """[H, W, 3] uint8: the belief map as a picture (`picture.belief_picture`), for bags and the live view."""
        return belief_picture(self)

    def act(self, observation: Observation) -> Decision:
        """The next (action, x, y) with the pixel in the observation's frame (-1, -1 for moves)."""
        key = self._observe(observation)
        pending = self._pending
        if pending is not None and pending[:2] == (key, self.answers):
            self.__dict__.update(vars(pending[2]))          # nothing heard since: that decision stands
            action, r, c, point, _ = pending[3]
        else:
            action, r, c, point, _ = self._outputs()
        self._pending = None
        x = y = -1
        step = self.decided
        if r >= 0:
            h, w = self.rgb.shape[:2]
            s = self.labels.shape[0]
            x, y = int((c + 0.5) * w / s), int((r + 0.5) * h / s)
        self.last = (action, step, point)
        self.step += 1
        return action, x, y


def forked(agent: MapAgent) -> MapAgent:
    """A copy of `agent` whose decision changes nothing of the agent's state (the network, the frame's
    perception and the map's arrays are shared; the map's give-ups are copied)."""
    twin = copy.copy(agent)
    for name, value in agent.__dict__.items():
        if name not in _SHARED:
            setattr(twin, name, copy.deepcopy(value))
    twin.map = copy.copy(agent.map)
    twin.map.excluded = {k: v.copy() for k, v in agent.map.excluded.items()}
    twin.map.blocked, twin.map.visited = set(agent.map.blocked), set(agent.map.visited)
    return twin
