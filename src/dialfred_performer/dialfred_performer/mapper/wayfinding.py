"""`Navigation`, a part of `MapAgent` (mapper/agent.py): moving about: towards where a type can be reached
on the map, turning and tilting to face it, and exploring (the first look around, the answers'
directions, the nearest unexplored edge)."""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .geometry import HORIZON_MAX, HORIZON_MIN, LOOK_DEG, bearing_deg, off_bearing
from .language import Step
from .semantic_map import TIGHT_CELLS, UNREACHABLE, distance_field, next_move, reach_goals, unexamined_goals
from .rules import ANSWER_CONE_DEG, EXPLORING, REPLAN, SCAN_TURNS, WALKING


class Navigation:
    """The navigation of the map performer (its state is `MapAgent`'s: see `MapAgent.reset_state`)."""

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
