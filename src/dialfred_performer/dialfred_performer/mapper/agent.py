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
import math
from collections import Counter, deque
from pathlib import Path
from typing import Any, Optional

import numpy as np
import torch

from dialfred_sim.protocol import ACTIONS, QA, Decision, Observation, as_observation
from dialfred_sim.tasks.demonstrations import label_classes
from dialfred_sim.world.catalog import load_catalog

from ..preprocess import frame_tensor
from .geometry import (HORIZON_MAX, HORIZON_MIN, LOOK_DEG, STEP_M, Pose, bearing_deg, estimate_horizon, off_bearing,
                       points_in_agent_frame, ray_distance, to_map_frame)
from .language import Fact, InstructionError, Step, parse_answer, parse_instruction
from .semantic_map import TIGHT_CELLS, UNREACHABLE, SemanticMap, distance_field, next_move, reach_goals, unexamined_goals

STRUCTURE = 4                    # label classes below this are nothing, Floor, Wall, Ceiling
FLOOR = 1
REACH_M = 1.3                    # stay inside the simulator's 1.5 m by more than the predicted depth's usual error
MIN_TARGET_CELLS = 1
PUT_CHANGE = 30.0                # _where_put: mean change of a cell's RGB (summed over channels) taken as a change
PLACED_M = 0.15                  # _inside_opened: how near the point of its own Put a cell must lie
INSIDE_P = 0.03                   # _inside_opened: the least probability of the target's type taken as it
MAX_STEP_ACTIONS = 120           # actions on one step of the plan before the agent gives up and stops
SCAN_TURNS = 3                   # turns of the first look around
SURE, WALKING, EXPLORING = 0.9, 0.7, 0.35
ANSWER_CONE_DEG = 67.5           # half a location answer's 45-degree direction bin, and one bin more either side
REPLAN = 'replan'                # _navigate changed the plan: decide again
# Attributes a decision reads but never changes (shared with the copy action_probabilities decides on).
_SHARED = frozenset({'net', 'catalog', 'classes', 'class_id', 'map', 'rgb', 'labels', 'conf', 'ray', 'points', 'class_prob',
                     '_pending', '_heard'})
INTERACTIONS = {'pickup': 'Pickup', 'put': 'Put', 'open': 'Open', 'close': 'Close', 'toggle_on': 'ToggleOn',
                'toggle_off': 'ToggleOff', 'slice': 'Slice'}


class MapAgent:
    """The map-and-plan performer over a perception network (see the module)."""

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
        from ..model import load_checkpoint, read_state
        from ..perception import PERCEPTION_FORMAT, load_perception
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
        self.last: Optional[tuple[str, Step, tuple]] = None     # (action, step, (x, y) map point)
        self.step = 0
        self.step_actions = 0
        self.step_failures = 0
        self.scans = 0
        self.approached = False
        self.macro: deque[str] = deque()
        self.anchors: dict[str, tuple[float, float]] = {}     # type -> map point of the instance acted on
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

    def reset(self, task: Any, seed: int = 0) -> None:
        """Start an episode of `task` (a PublicTask: only its instruction is read)."""
        self.reset_state()
        self.task = task
        try:
            self.reading = parse_instruction(task.instruction)
            self.plan = deque(self.reading.steps)
        except InstructionError as exc:
            self.log.append(f'cannot read the instruction: {exc}')
            self.plan = deque([Step('stop')])

    def hear(self, qa: QA) -> None:
        """A QA of the dialogue: location, appearance and direction answers become facts (taken in
        when the step's frame has been perceived: `_observe`)."""
        self._heard.append(qa)

    def _take_in(self, qa: QA) -> None:
        self.answers += 1
        if not qa.valid:
            return
        fact = parse_answer(qa.question.question_type, qa.answer)
        if fact is None:
            return
        if fact.kind == 'held' and fact.receptacle == '':
            self.held, self.held_known, self.held_confirmed = fact.object_type, True, True
        elif fact.kind == 'location' and fact.object_type == self.held and not self.held_confirmed:
            self.held = None                      # it is somewhere in the room, so not in hand
        elif fact.kind == 'direction':
            if fact.turn_deg == 90:
                self.turns = deque(['RotateLeft'])
            elif fact.turn_deg == -90:
                self.turns = deque(['RotateRight'])
            elif fact.turn_deg == 180:
                self.turns = deque(['RotateLeft', 'RotateLeft'])
        self.facts[(fact.kind, fact.object_type)] = (fact, Pose(self.pose.i, self.pose.j, self.pose.heading,
                                                                 self.pose.horizon))

    # ------------------------------------------------------------------ perception

    @torch.inference_mode()
    def perceive(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(class [S, S], its probability [S, S], depth m [S, S]) at the network's cells."""
        out = self.net(frame_tensor(rgb, self.resolution)[None])
        logits, metres, _ = self.net.heads(out.fine)
        prob = torch.softmax(logits[0], 0)
        self.class_prob = prob
        conf, labels = prob.max(0)
        return labels.numpy(), conf.numpy(), metres[0].numpy()

    def sense(self, observation: Observation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the agent makes of an observation: `perceive` of its RGB frame (a diagnostic subclass may
        read something else: benchmarks/map_perception_ceiling.py)."""
        return self.perceive(self.rgb)

    def _update(self, observation: Observation) -> None:
        before, self.rgb = self.rgb, observation.rgb
        labels, conf, depth = self.sense(observation)
        if self.step == 0:
            self.pose.horizon = estimate_horizon(depth, labels == FLOOR)
        else:
            self._dead_reckon(observation.last_action_success)
        self.labels, self.conf = labels, conf
        self.ray = ray_distance(depth)
        local = points_in_agent_frame(depth, self.pose.horizon)
        points = to_map_frame(local, self.pose)
        self.points = points
        if self._just_put is not None and before is not None and before.shape == self.rgb.shape:
            self._where_put(self._just_put, before)
        self._just_put = None
        mapped = self.ray
        if self.held is not None:
            ray = self.ray.copy()
            ray[self.hand_window()] = np.inf          # the object in hand is not part of the room
            self.ray = ray
            # Nor is it an obstacle: what is seen where the hand carries things is left off the map
            # (else it walls the agent in, a step ahead in every direction it turns to).
            mapped = ray.copy()
            mapped[carried_volume(local)] = np.inf
        self.map.update(points, labels, conf, mapped, FLOOR, STRUCTURE)
        self.map.visited.add((self.pose.i, self.pose.j))
        if not self.held_known and self.step == 0:
            # A put, heat, cool or clean instruction is given with the object in hand 91% of the time
            # in train; the hand's view or a failed Put says otherwise.
            wanted = [s.held for s in self.plan if s.kind == 'put' and s.held]
            self.held = wanted[0] if wanted else self._held_in_view()
            self.held_known = True

    def _held_in_view(self) -> Optional[str]:
        """The pickupable type seen most (at least 3 cells) where the hand carries an object, if any."""
        seen = Counter(self.labels[self.hand_window() & (self.labels >= STRUCTURE)].tolist())
        for k, count in seen.most_common():
            t = self.catalog.get(self.classes[k])
            if t is not None and t.pickupable and count >= 3:
                return self.classes[k]
        return None

    def hand_window(self, radius: int = 3) -> np.ndarray:
        """[S, S] bool: the cells around where the hand's object appears at the current horizon."""
        s = self.labels.shape[0]
        r, c = hand_cell(self.pose.horizon, s)
        window = np.zeros((s, s), bool)
        window[max(r - radius, 0):r + radius + 1, max(c - radius, 0):c + radius + 1] = True
        return window

    def _dead_reckon(self, success: Optional[bool]) -> None:
        if self.last is None:
            return
        action, step, point = self.last
        if success is None:
            success = True
        if action in ('MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown'):
            if success:
                self.pose = self.pose.after(action)
            elif action == 'MoveAhead':
                self.map.blocked.add(self.pose.forward())
            return
        if success:
            self.step_failures = 0
            if point is not None:
                self.anchors[step.target] = point
            if action == 'Pickup':
                self.held, self.held_confirmed = step.target, True
                self.placed.pop(step.target, None)
            elif action == 'Put':
                if self.held or step.held:
                    self.placed[self.held or step.held] = (step.target, None)
                    self._just_put = self.held or step.held
                self.held = None
            elif action == 'Open':
                self.opened.add(step.target)
            elif action == 'Close':
                self.opened.discard(step.target)
            self._step_done(action)
        else:
            self.step_failures += 1
            self._after_failure(action, step, point)

    # ------------------------------------------------------------------ the plan

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
        if self.macro:
            action = self.macro.popleft()
            if action == 'MoveAhead' and (self.map.blocked and self.pose.forward() in self.map.blocked):
                self.macro.clear()
            else:
                self.confidence = WALKING
                return action, -1, -1, None
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

    def _seen_within(self, k: int, metres: float) -> bool:
        return bool(((self.labels == k) & (self.ray < metres)).sum() >= MIN_TARGET_CELLS)

    def _target_pixel(self, k: int, step: Step):
        """((row, col), map point) of the cell to click on class k, or None when none is in reach."""
        mask = (self.labels == k) & (self.conf > 0.3)
        if not mask.any():
            mask = self._inside_opened(k, step)
        if self.held is not None:
            mask &= ~self.hand_window()
        given_up = self.map.excluded.get(k)
        if given_up is not None and mask.any():
            # Places given up on (two failed interactions there) are given up on in view too.
            cx, cy = self.map.cell_of(self.points[..., 0], self.points[..., 1])
            inside = (cx >= 0) & (cx < self.map.n) & (cy >= 0) & (cy < self.map.n)
            mask &= ~(inside & given_up[np.clip(cx, 0, self.map.n - 1), np.clip(cy, 0, self.map.n - 1)])
        reach = mask & (self.ray < (REACH_M - 0.15 if step.kind == 'goto' else REACH_M))
        if reach.sum() < (2 if step.kind == 'goto' else MIN_TARGET_CELLS):
            return None
        comps = _components(mask)
        colour = self._colour_wanted(step)
        best, best_score = None, None
        for comp in comps:
            inside = comp & reach
            if not inside.any():
                continue
            rows, cols = np.nonzero(comp)
            p = self.points[rows, cols].mean(0)
            cone = self._answered_cone(step.target, p[:1], p[1:2])
            if cone is not None and not cone[0]:
                continue                      # not where the location answer said
            score = -float(inside.sum())
            if colour is not None:
                named = self._colour_of(comp)
                score += 0.0 if named == colour else 1000.0
            score += self._place_penalty(step.target, p)
            if best_score is None or score < best_score:
                best, best_score = (comp, inside), score
        if best is None:
            return None
        comp, inside = best
        rows, cols = np.nonzero(comp)
        cr, cc = rows.mean(), cols.mean()
        interior = inside.copy()
        interior[1:, :] &= comp[:-1, :]
        interior[:-1, :] &= comp[1:, :]
        interior[:, 1:] &= comp[:, :-1]
        interior[:, :-1] &= comp[:, 1:]
        safe = interior & (self.ray < REACH_M - 0.1)
        if safe.any():
            inside = safe
        elif interior.any():
            inside = interior
        ir, ic = np.nonzero(inside)
        j = int(np.argmin((ir - cr) ** 2 + (ic - cc) ** 2 + 4.0 * (self.step_failures > 0) * self.ray[ir, ic]))
        r, c = int(ir[j]), int(ic[j])
        p = self.points[r, c]
        return (r, c), (float(p[0]), float(p[1]))

    def _where_put(self, obj: str, before: np.ndarray) -> None:
        """Where `obj`, just put down, lies: the middle (map point) of the receptacle's cells whose colour
        changed between the frame before the Put and this one (the agent did not move; the network mostly
        labels a small thing inside a receptacle as the receptacle, and where the hand carried it, as what
        lies behind)."""
        recep = self.placed[obj][0]
        rk = self.class_id.get(recep)
        s = self.labels.shape[0]
        f = self.rgb.shape[0] // s
        if rk is None or f < 1 or self.rgb.shape[0] != f * s:
            return
        change = np.abs(self.rgb.astype(np.int16) - before.astype(np.int16)).sum(-1)
        change = change.reshape(s, f, s, f).mean((1, 3))
        moved = (change > PUT_CHANGE) & (self.labels == rk) & (self.ray < REACH_M)
        if moved.any():
            p = self.points[moved].mean(0)
            self.placed[obj] = (recep, (float(p[0]), float(p[1])))

    def _inside(self, target: str) -> Optional[str]:
        """The receptacle `target` lies in, open, as far as the agent knows: the one it put it into itself,
        else the one a location answer said it is in; None if unknown or shut (an openable one the agent
        has not opened)."""
        where = self.placed[target][0] if target in self.placed else None
        if where is None:
            fact = self.facts.get(('location', target))
            if fact is None or not fact[0].inside:
                return None
            where = fact[0].receptacle
        kind = self.catalog.get(where)
        return where if where in self.opened or (kind is not None and not kind.openable) else None

    def _inside_opened(self, k: int, step: Step) -> np.ndarray:
        """[S, S] bool: where a pickup's target may lie unlabelled in view: inside the open receptacle it is
        known to be in (`_inside`), at the cell the network gives the target's type the most probability (at
        least INSIDE_P) within the receptacle's box in the frame; failing that, where the agent put it
        itself, the cell of that box nearest the point it put it down at (within PLACED_M)."""
        none = np.zeros_like(self.labels, bool)
        prob = self.class_prob
        where = self._inside(step.target) if step.kind == 'pickup' else None
        if where is None or prob is None:
            return none
        rk = self.class_id.get(where)
        if rk is None:
            return none
        rows, cols = np.nonzero(self.labels == rk)
        if len(rows) < 2:
            return none
        box = none.copy()
        box[max(rows.min() - 1, 0):rows.max() + 2, max(cols.min() - 1, 0):cols.max() + 2] = True
        near = box & (self.ray < REACH_M)
        p = np.where(near, prob[k].numpy(), 0.0)
        if p.max() >= INSIDE_P:
            return p == p.max()
        put = self.placed.get(step.target, (None, None))[1]
        if put is None:
            return none
        d = np.where(near, np.hypot(self.points[..., 0] - put[0], self.points[..., 1] - put[1]), np.inf)
        return d == d.min() if d.min() <= PLACED_M else none

    def _place_penalty(self, type_name: str, p: np.ndarray) -> float:
        """How far a mask of `type_name` centred on map point p lies from the instance acted on before
        (an opened fridge is the one to put into and close), else from where a location answer said it is."""
        anchor = self.anchors.get(type_name)
        if anchor is not None:
            return 100.0 * math.hypot(p[0] - anchor[0], p[1] - anchor[1])
        fact = self.facts.get(('location', type_name))
        if fact is not None:
            f, at = fact
            diff = float(off_bearing(at, f.bearing_deg, p[:1], p[1:2])[0])
            return 2.0 * diff + (500.0 if diff > ANSWER_CONE_DEG else 0.0)
        return 0.0

    def _answered_cone(self, type_name: str, x: np.ndarray, y: np.ndarray) -> Optional[np.ndarray]:
        """Which map points (x, y) lie in the direction a location answer gave for `type_name` (within
        ANSWER_CONE_DEG of it, seen from where the answer was heard); None without such an answer, or
        once an instance of the type has been acted on (that one is the one)."""
        fact = self.facts.get(('location', type_name))
        if fact is None or type_name in self.anchors or type_name in self.cone_spent:
            return None
        f, at = fact
        return off_bearing(at, f.bearing_deg, x, y) <= ANSWER_CONE_DEG

    def _colour_wanted(self, step: Step) -> Optional[str]:
        """The colour an appearance answer gave for the step's target, if the target is pickupable.

        Fixed things (a faucet, a lamp, a fridge) are left out: their predicted masks are few cells that
        spill onto the wall or counter behind them, so the colour read off a mask names the background
        (All QAs, valid_unseen: Turn off 52.4 -> 90.5 when they were left out), and a room rarely has two
        of them side by side to choose between."""
        kind = self.catalog.get(step.target)
        if kind is None or not kind.pickupable:
            return None
        fact = self.facts.get(('appearance', step.target))
        return fact[0].colour if fact is not None else None

    def _colour_of(self, comp: np.ndarray) -> Optional[str]:
        from dialfred_oracle.colours import colour_name
        h, w = self.rgb.shape[:2]
        s = comp.shape[0]
        rows = (np.arange(h) * s // h)
        cols = (np.arange(w) * s // w)
        full = comp[rows[:, None], cols[None, :]]
        return colour_name(self.rgb[full])

    def _navigate(self, k: int, step: Step) -> Optional[str]:
        """The next move towards where class k can be reached, or towards where it may be found."""
        if self.turns:
            self.confidence = WALKING
            return self.turns.popleft()
        free = self.map.traversable()
        cx, cy, height = self.map.object_cells(k)
        cone = self._answered_cone(step.target, *self.map.cell_centre(cx, cy)) if len(cx) else None
        if cone is not None:
            # A location answer: the instances in its direction first, then a look there, and only
            # then the others (the answer's direction is spent).
            if cone.any():
                move = self._approach(k, step, free, cx[cone], cy[cone], height[cone])
                if move is not None:
                    return move
            move = self._explore(k, step, free)
            if move is not None:
                return move
            self.cone_spent.add(step.target)
        if len(cx):
            move = self._approach(k, step, free, cx, cy, height)
            if move is not None:
                return move
        return self._explore(k, step, free) if cone is None else None

    def _approach(self, k: int, step: Step, free: np.ndarray, cx, cy, height) -> Optional[str]:
        """The next move towards where the cells (cx, cy) of class k can be reached; None when there
        is no way."""
        off = self.map.node_offset()
        goals = reach_goals(self.map, cx, cy, height)
        at = (self.pose.i + off, self.pose.j + off)
        dist = distance_field(free, goals, until=at)
        here = dist[at]
        if here >= UNREACHABLE and goals.any():
            # No way with the safe clearance (an obstacle a cell too near on the far side walls it
            # in): plan with the tight one, and let failed moves tell.
            dist = distance_field(self.map.traversable(TIGHT_CELLS), goals, until=at)
            here = dist[at]
        if here == 0:
            move = self._face(cx, cy, height)
            if move is not None:
                self.confidence = WALKING
                return move
            # At a place from which it should be in reach and facing it, yet not in reach: give it up.
            x, y = self.map.cell_centre(cx, cy)
            d = (x - self.pose.xy[0]) ** 2 + (y - self.pose.xy[1]) ** 2
            n = int(np.argmin(d))
            self.map.exclude(k, float(x[n]), float(y[n]))
            return self._navigate(k, step)
        if here < UNREACHABLE:
            move = next_move(dist, self.pose, off)
            if move is not None and self._loop_guard(move):
                self.confidence = WALKING
                return move
        return None

    def _loop_guard(self, move: str) -> bool:
        key = (self.pose.i, self.pose.j, self.pose.heading, self.pose.horizon, move)
        self.visits[key] += 1
        return self.visits[key] <= 3

    def _face(self, cx, cy, height) -> Optional[str]:
        """A turn or tilt that brings the nearest of the cells into view; None when it is in view."""
        x, y = self.map.cell_centre(cx, cy)
        x0, y0 = self.pose.xy
        d = np.sqrt((x - x0) ** 2 + (y - y0) ** 2)
        n = int(np.argmin(d))
        b = bearing_deg(self.pose, float(x[n]), float(y[n]))
        if b > 45:
            return 'RotateLeft' if self._loop_guard('RotateLeft') else None
        if b < -45:
            return 'RotateRight' if self._loop_guard('RotateRight') else None
        want = math.degrees(math.atan2(1.5 - float(height[n]), max(float(d[n]), 0.05)))
        want = min(max(round(want / LOOK_DEG) * LOOK_DEG, HORIZON_MIN), HORIZON_MAX)
        if want > self.pose.horizon + 1e-6:
            return 'LookDown' if self._loop_guard('LookDown') else None
        if want < self.pose.horizon - 1e-6:
            return 'LookUp' if self._loop_guard('LookUp') else None
        return None

    def _explore(self, k: int, step: Step, free: np.ndarray) -> Optional[str]:
        self.confidence = EXPLORING
        off = self.map.node_offset()
        # A location answer: walk to its receptacle in its direction, if mapped.
        name = step.held if step.kind == 'put' and self.held != step.held else step.target
        fact = self.facts.get(('location', name))
        if fact is not None and fact[0].receptacle:
            f, at = fact
            rk = self.class_id.get(f.receptacle)
            if rk is not None and rk != k:
                cx, cy, height = self.map.object_cells(rk)
                if len(cx):
                    x, y = self.map.cell_centre(cx, cy)
                    keep = off_bearing(at, f.bearing_deg, x, y) <= ANSWER_CONE_DEG
                    if keep.any():
                        goals = reach_goals(self.map, cx[keep], cy[keep], height[keep])
                        if f.inside and f.receptacle in self.opened:
                            # opened to be searched: stand where it lies ahead, so its inside is in view
                            facing = reach_goals(self.map, cx[keep], cy[keep], height[keep], facing_deg=25.0)
                            if (facing & free).any():
                                goals = facing
                        dist = distance_field(free, goals, until=(self.pose.i + off, self.pose.j + off))
                        if dist[self.pose.i + off, self.pose.j + off] == 0:
                            move = self._face(cx[keep], cy[keep], height[keep])
                            if move is not None:
                                return move
                            t = self.catalog.get(f.receptacle)
                            if t is not None and t.openable and f.inside and f.receptacle not in self.opened \
                                    and step.kind == 'pickup':
                                self.plan.appendleft(Step('open', f.receptacle, search=True))
                                self.plan.insert(2, Step('close', f.receptacle, search=True))
                                return REPLAN
                            # Looked at this part of the receptacle and the object is not there: the next part.
                            d = (x[keep] - self.pose.xy[0]) ** 2 + (y[keep] - self.pose.xy[1]) ** 2
                            n = int(np.argmin(d))
                            self.map.exclude(rk, float(x[keep][n]), float(y[keep][n]), radius_m=1.0)
                            return REPLAN
                        else:
                            move = next_move(dist, self.pose, off)
                            if move is not None and self._loop_guard(move):
                                return move
        if self.scans < SCAN_TURNS:
            self.scans += 1
            return 'RotateLeft'
        # The nearest furniture not yet looked at from close by (objects lie on it), in the answered
        # direction if there is one ...
        goals = unexamined_goals(self.map, free)
        for (i, j) in self.map.visited:
            goals[i + off, j + off] = False
        if fact is not None and goals.any():
            toward = goals & self._cone(fact[1], fact[0].bearing_deg)
            goals = toward if toward.any() else goals
        if goals.any():
            dist = distance_field(free, goals, until=(self.pose.i + off, self.pose.j + off))
            if dist[self.pose.i + off, self.pose.j + off] < UNREACHABLE:
                move = next_move(dist, self.pose, off)
                if move is not None and self._loop_guard(move):
                    return move
        # ... else the nearest edge of what has been seen.
        known = self.map.known()
        unknown = ~known
        edge = np.zeros_like(known)
        edge[1:, :] |= unknown[:-1, :]
        edge[:-1, :] |= unknown[1:, :]
        edge[:, 1:] |= unknown[:, :-1]
        edge[:, :-1] |= unknown[:, 1:]
        goals = edge & known & free
        for (i, j) in self.map.visited:
            goals[i + off, j + off] = False
        if not goals.any():
            return None
        dist = distance_field(free, goals, until=(self.pose.i + off, self.pose.j + off))
        if dist[self.pose.i + off, self.pose.j + off] >= UNREACHABLE:
            return None
        move = next_move(dist, self.pose, off)
        if move is None:
            return 'RotateLeft' if self._loop_guard('RotateLeft') else None
        return move if self._loop_guard(move) else None

    def _cone(self, at: Pose, bearing: float, half_width: float = ANSWER_CONE_DEG) -> np.ndarray:
        """[nodes, nodes] bool: grid points within half_width degrees of `bearing` seen from `at`."""
        metres = (np.arange(self.map.nodes) - self.map.node_offset()) * STEP_M
        return off_bearing(at, bearing, metres[:, None], metres[None, :]) <= half_width

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

    def _fork(self) -> 'MapAgent':
        """A copy whose decision changes nothing of this agent's state (the network, the frame's
        perception and the map's arrays are shared; the map's give-ups are copied)."""
        twin = copy.copy(self)
        for name, value in self.__dict__.items():
            if name not in _SHARED:
                setattr(twin, name, copy.deepcopy(value))
        twin.map = copy.copy(self.map)
        twin.map.excluded = {k: v.copy() for k, v in self.map.excluded.items()}
        twin.map.blocked, twin.map.visited = set(self.map.blocked), set(self.map.visited)
        return twin

    def _outputs(self) -> tuple:
        action, r, c, point = self._decide()
        return action, r, c, point, self.confidence

    def action_probabilities(self, observation: Observation) -> np.ndarray:
        """Probabilities over ACTIONS of the next action: the chosen one gets the agent's confidence,
        the rest is spread over the others (the model-confusion questioner's signal)."""
        key = self._observe(observation)
        twin = self._fork()
        outputs = twin._outputs()
        self._pending = (key, self.answers, twin, outputs)
        confidence, action = outputs[4], outputs[0]
        p = np.full(len(ACTIONS), (1.0 - confidence) / (len(ACTIONS) - 1), np.float32)
        p[ACTIONS.index(action)] = confidence
        return p

    def picture(self) -> np.ndarray:
        """[H, W, 3] uint8: the belief map as a picture (`picture.belief_picture`), for bags and the live view."""
        from .picture import belief_picture
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


HAND_M = (0.42, -0.16, 0.95)      # where the simulator's hand carries an object (ahead, left, height)


CARRIED_M = (0.8, 0.45, 0.45)       # a held object's points: nearer ahead, to either side, higher than these


def carried_volume(local: np.ndarray) -> np.ndarray:
    """[S, S] bool: the points (in the agent's frame: forward, left, height) where an object carried
    in the hand may be seen (HAND_M, give or take the largest pickupable object's half size)."""
    ahead, side, low = CARRIED_M
    return (local[..., 0] < ahead) & (np.abs(local[..., 1]) < side) & (local[..., 2] > low)


def hand_cell(horizon: float, size: int) -> tuple[int, int]:
    """(row, col) of the cell where the hand's object appears in a size x size grid at `horizon`."""
    pitch = math.radians(-horizon)
    cp, sp = math.cos(pitch), math.sin(pitch)
    f, l, up = HAND_M[0], HAND_M[1], HAND_M[2] - 1.5
    z = f * cp + up * sp
    u = -l / z
    v = (-f * sp + up * cp) / z
    col = int(round((u + 1) / 2 * size - 0.5))
    row = int(round((1 - v) / 2 * size - 0.5))
    return min(max(row, 0), size - 1), min(max(col, 0), size - 1)


def _components(mask: np.ndarray) -> list[np.ndarray]:
    """The 4-connected components of a small bool mask, largest first."""
    seen = np.zeros_like(mask)
    out = []
    h, w = mask.shape
    for r0, c0 in zip(*np.nonzero(mask)):
        if seen[r0, c0]:
            continue
        comp = np.zeros_like(mask)
        stack = [(r0, c0)]
        seen[r0, c0] = True
        while stack:
            r, c = stack.pop()
            comp[r, c] = True
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                a, b = r + dr, c + dc
                if 0 <= a < h and 0 <= b < w and mask[a, b] and not seen[a, b]:
                    seen[a, b] = True
                    stack.append((a, b))
        out.append(comp)
    out.sort(key=lambda m: -int(m.sum()))
    return out
