"""`Sensing`, a part of `MapAgent` (mapper/agent.py): what the agent makes of a frame: the network's
reading of its cells, the pose dead-reckoned from its own actions, the points of the map and the object
in hand."""

from __future__ import annotations

from collections import Counter
from typing import Optional

import numpy as np
import torch

from dialfred_sim.protocol import Observation

from ..preprocess import frame_tensor
from .geometry import axis_distance, estimate_horizon, points_in_agent_frame, ray_distance, to_map_frame
from .rules import FLOOR, STRUCTURE, carried_volume, hand_cell


class Sensing:
    """The sensing of the map performer (its state is `MapAgent`'s: see `MapAgent.reset_state`)."""

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
        if self.carried is not None:
            self._carry_over(observation.last_action_success)
        elif self.step == 0:
            self.pose.horizon = estimate_horizon(depth, labels == FLOOR)
        else:
            self._dead_reckon(observation.last_action_success)
        self.labels, self.conf = labels, conf
        local = points_in_agent_frame(depth, self.pose.horizon)
        self.ray = axis_distance(local)               # how far from the agent's axis: its reach
        points = to_map_frame(local, self.pose)
        self.points = points
        if self._just_put is not None and before is not None and before.shape == self.rgb.shape:
            self._where_put(self._just_put, before)
        self._just_put = None
        mapped = ray_distance(depth)                  # the map takes points out to a range from the eye
        if self.held is not None:
            hand = self.hand_window()                 # the object in hand is not part of the room
            self.ray = self.ray.copy()
            self.ray[hand] = np.inf
            # Nor is it an obstacle: what is seen where the hand carries things is left off the map
            # (else it walls the agent in, a step ahead in every direction it turns to).
            mapped[hand] = np.inf
            mapped[carried_volume(local)] = np.inf
        self.map.update(points, labels, conf, mapped, FLOOR, STRUCTURE)
        self.map.visited.add((self.pose.i, self.pose.j))
        if not self.held_known and self.step == 0:
            # A put, heat, cool or clean instruction is given with the object in hand 91% of the time
            # in train; the hand's view or a failed Put says otherwise.
            wanted = [s.held for s in self.plan if s.kind == 'put' and s.held]
            self.held = wanted[0] if wanted else self._held_in_view()
            self.held_known = True

    def _world_effect(self, action: str, step, success: bool) -> bool:
        """What the agent's last action did to its pose, its hand and what it opened (`success`: as the
        observation after it said); True for a move, turn or look, which is all it did."""
        if action in ('MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown'):
            if success:
                self.pose = self.pose.after(action)
            elif action == 'MoveAhead':
                self.map.blocked.add(self.pose.forward())
            return True
        if not success:
            return False
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
        return False

    def _carry_over(self, success: Optional[bool]) -> None:
        """The first frame of a chained task (MapAgent.carry_on): the last task's final action, whose
        outcome this frame reports, moves the pose or changes the hand; nothing of the new plan."""
        action, step, _ = self.carried
        self.carried = None
        if action != 'Stop':
            self._world_effect(action, step, True if success is None else success)

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
        if self._world_effect(action, step, success):
            return
        if success:
            self.step_failures = 0
            if point is not None:
                self.anchors[step.target] = point
                self.stand_anchor = (step.target, *point)
            self._step_done(action)
        else:
            self.step_failures += 1
            self._after_failure(action, step, point)
