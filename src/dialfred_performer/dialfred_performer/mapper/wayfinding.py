"""`Navigation`, a part of `MapAgent` (mapper/agent.py): moving about: towards where a type can be reached
on the map, turning and tilting to face it, exploring (the first look around, the answers'
directions, the nearest unexplored edge), and the last stand of a task with a go-to.

The last stand. A task with a go-to is judged by where the agent ends: within 4 actions of the pose
where the expert ended it (DialFRED's goal rule). The expert ends a go-to at ALFRED's designated pose
for the object it acts on there (the free grid point nearest the object's centre by L1 distance, with
the eye at least 0.5 m from that centre and the object within reach, facing it along the axis it lies
most along, the camera pitched at its base: `dialfred_sim.tasks.expert.Expert.find_pose`). Before
every Stop the agent walks to that pose as its own map places the object it acted on (or went to)
last. The expert passes over that pose where a put from it would land out of view or a closed
container's contents would be out of reach (dialfred_sim/tasks/expert.py); there the stand aims at the
plain pose and can end more than 4 actions from the expert's (`./dialfred bench expert_poses` counts
how often). The agent is not told whether its task has a go-to (an instruction may leave it unsaid:
"Open the box."); where it has none, the stand costs a few actions and changes no outcome."""

from __future__ import annotations

import math
from collections import deque
from typing import Optional

import numpy as np

from dialfred_sim.protocol import BODY
from dialfred_sim.tasks.expert import MARGIN as EXPERT_MARGIN_M

from .geometry import CAMERA_HEIGHT_M, HORIZON_MAX, HORIZON_MIN, LOOK_DEG, STEP_M, bearing_deg, off_bearing
from .language import Step
from .semantic_map import TIGHT_CELLS, UNREACHABLE, distance_field, next_move, reach_goals, unexamined_goals
from .rules import ANSWER_CONE_DEG, EXPLORING, REPLAN, SCAN_TURNS, STAND_MAX_ACTIONS, THERE, WALKING


# A direction answer's turn (language.Fact.turn_deg, counter-clockwise): the first turn towards it.
TURN_FOR = {90: 'RotateLeft', -90: 'RotateRight', 180: 'RotateLeft'}
# Following directions: a pose the answers brought the agent back to more than FOLLOW_LOOP times is a circle; each
# circle makes its steps aside one grid point longer, up to ASIDE_MAX, from the other side.
FOLLOW_LOOP = 2
ASIDE_MAX = 4


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
        led = self._led_cone(step, *self.map.cell_centre(cx, cy)) if len(cx) and cone is None else None
        if led is not None and led.any():
            # A direction answer of an earlier step: the instances where it points first.
            move = self._approach(k, step, free, cx[led], cy[led], height[led])
            if move is not None:
                return move
        if len(cx):
            move = self._approach(k, step, free, cx, cy, height)
            if move is not None:
                return move
        return self._explore(k, step, free) if cone is None else None

    def _approach(self, k: int, step: Step, free: np.ndarray, cx, cy, height) -> Optional[str]:
        """The next move towards where the cells (cx, cy) of class k can be reached; None when there
        is no way."""
        off = self.map.node_offset()
        goals = reach_goals(self.map, cx, cy)
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
        want = math.degrees(math.atan2(CAMERA_HEIGHT_M - float(height[n]), max(float(d[n]), 0.05)))
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
                    keep = (off_bearing(at, f.bearing_deg, x, y) <= ANSWER_CONE_DEG if f.bearing_deg is not None
                            else np.ones(len(x), bool))          # a place named without a side: any of them
                    if keep.any():
                        goals = reach_goals(self.map, cx[keep], cy[keep])
                        if f.inside and f.receptacle in self.opened:
                            # opened to be searched: stand where it lies ahead, so its inside is in view
                            facing = reach_goals(self.map, cx[keep], cy[keep], facing_deg=25.0)
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
        goals = self._answered_goals(goals, fact, step)
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

    def _answered_goals(self, goals: np.ndarray, fact, step: Step) -> np.ndarray:
        """The goals in the direction the step's location answer (`fact`) gave, else where the last direction
        answer points (`reading._led`); all of them when none lies there or no answer says."""
        if not goals.any():
            return goals
        if fact is not None and fact[0].bearing_deg is not None:
            cone = self._cone(fact[1], fact[0].bearing_deg)
        else:
            lead = self._led(step)
            if lead is None:
                return goals
            cone = self._cone(*lead)
        toward = goals & cone
        return toward if toward.any() else goals

    # ------------------------------------------------------------------ the last stand

    def _follow(self) -> Optional[str]:
        """What a direction answer heard at this step says to do: THERE when the expert ended where the agent
        stands, else the turn or the move towards where it ended (a MoveAhead into a point a failed move found
        blocked becomes a step aside, and the next answer says the rest);
        None without such an answer. The turns an older answer queued give way to it."""
        if self.direction is None or self.direction[1] != self.step:
            return None
        fact = self.direction[0]
        self.turns.clear()
        self.confidence = WALKING
        if fact.stay:
            return THERE
        here = (self.pose.i, self.pose.j, self.pose.heading)
        arrived = here != self.followed_last        # answers heard where an action failed add no visit
        self.followed_last = here
        self.followed[here] += arrived
        if self.followed[here] > FOLLOW_LOOP:
            # Led round in a circle (an obstacle between the agent and the goal, the answers sending it back
            # and forth along one side): the next steps aside go one point further, from the other side.
            self.followed.clear()
            self.aside_points = min(self.aside_points + 1, ASIDE_MAX)
            self.turn_aside = 'RotateRight' if self.turn_aside == 'RotateLeft' else 'RotateLeft'
        if fact.turn_deg in TURN_FOR:
            return TURN_FOR[fact.turn_deg]
        if self.pose.forward() in self.map.blocked:     # a move failed into it (the map's clearance is not asked)
            # A step aside, then the next answer: around the obstacle on one side, the other side once a step
            # aside is blocked too (agent._decide's macro).
            self.macro = deque(['MoveAhead'] * self.aside_points)
            self.sidestep = True
            return self.turn_aside
        return 'MoveAhead'

    def _stand(self) -> Optional[str]:
        """Before the final Stop: the next move, turn or look towards the designated pose of the object
        acted on (or gone to) last (see the module); None when there, or when that pose is unknown, out of
        the way or not reached within STAND_MAX_ACTIONS."""
        if self.stand_anchor is None:
            return None
        if self.stand_goal is None:
            self.stand_goal = self._designated_pose(*self.stand_anchor) or ()
        if not self.stand_goal or self.stand_actions >= STAND_MAX_ACTIONS:
            return None
        i, j, heading, horizon = self.stand_goal
        move = None
        if (self.pose.i, self.pose.j) != (i, j):
            off = self.map.node_offset()
            goals = np.zeros((self.map.nodes, self.map.nodes), bool)
            goals[i + off, j + off] = True
            dist = distance_field(self.map.traversable(), goals, until=(self.pose.i + off, self.pose.j + off))
            move = next_move(dist, self.pose, off)
            if move is None or (move == 'MoveAhead' and self.pose.forward() in self.map.blocked):
                self.stand_goal = ()                 # no way there after all: stop where it is
                return None
        elif heading != self.pose.heading:
            move = 'RotateRight' if (heading - self.pose.heading) % 360 == 270 else 'RotateLeft'
        elif horizon > self.pose.horizon + 1e-6:
            move = 'LookDown'
        elif horizon < self.pose.horizon - 1e-6:
            move = 'LookUp'
        if move is None or not self._loop_guard(move):
            return None
        self.stand_actions += 1
        self.confidence = WALKING
        return move

    def _designated_pose(self, type_name: str, x: float, y: float) -> Optional[tuple[int, int, int, float]]:
        """(i, j, heading, horizon): ALFRED's designated pose for the instance of `type_name` the map has
        at map point (x, y) (its cells connected to the nearest one within 0.5 m), among the grid points
        the agent can walk to; None when the map has no such instance or no such point."""
        k = self.class_id.get(type_name)
        if k is None:
            return None
        cx, cy, height = self.map.object_cells(k)
        if len(cx) == 0:
            return None
        xs, ys = self.map.cell_centre(cx, cy)
        d2 = (xs - x) ** 2 + (ys - y) ** 2
        seed = int(np.argmin(d2))
        if d2[seed] > 0.5 ** 2:
            return None
        part = _connected(cx, cy, seed)
        xs, ys, hs = xs[part], ys[part], height[part]
        centre = np.array([(xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2, (hs.min() + hs.max()) / 2])
        base = float(hs.min())
        off = self.map.node_offset()
        free = self.map.traversable()
        at = np.zeros_like(free)
        at[self.pose.i + off, self.pose.j + off] = True
        walk = distance_field(free, at)
        ni, nj = np.nonzero(free & (walk < UNREACHABLE))
        gi, gj = (ni - off) * STEP_M, (nj - off) * STEP_M
        dx, dy = centre[0] - gi, centre[1] - gj
        eye_to_centre = np.sqrt(dx ** 2 + dy ** 2 + (CAMERA_HEIGHT_M - centre[2]) ** 2)
        reach = np.sqrt((xs[None, :] - gi[:, None]) ** 2 + (ys[None, :] - gj[:, None]) ** 2).min(1)   # from the axis
        ok = (eye_to_centre >= PULL_BACK_M) & (reach <= DESIGNATED_REACH_M)
        if not ok.any():
            return None
        steps = (np.abs(dx) + np.abs(dy)) / STEP_M
        order = np.lexsort((walk[ni, nj], np.where(ok, steps, np.inf)))
        n = int(order[0])
        ddx, ddy = float(dx[n]), float(dy[n])
        heading = (0 if ddx >= 0 else 180) if abs(ddx) > abs(ddy) else (90 if ddy >= 0 else 270)
        pitch = math.degrees(math.atan2(CAMERA_HEIGHT_M - base, max(abs(ddx), abs(ddy), 0.05)))
        horizon = min(max(round(pitch / LOOK_DEG) * LOOK_DEG, HORIZON_MIN), HORIZON_MAX)
        return int(ni[n] - off), int(nj[n] - off), heading, float(horizon)


# ALFRED's designated pose (dialfred_sim.tasks.expert): the eye this far from the target's centre at least,
# and the target's nearest point within the simulator's reach less the expert's margin.
PULL_BACK_M = 0.5
DESIGNATED_REACH_M = BODY.reach - EXPERT_MARGIN_M


def _connected(cx: np.ndarray, cy: np.ndarray, seed: int) -> np.ndarray:
    """bool [len(cx)]: the cells (cx, cy) 8-connected to cell `seed` through the others."""
    index = {(int(a), int(b)): n for n, (a, b) in enumerate(zip(cx.tolist(), cy.tolist()))}
    keep = np.zeros(len(cx), bool)
    keep[seed] = True
    todo = [seed]
    while todo:
        n = todo.pop()
        a, b = int(cx[n]), int(cy[n])
        for da in (-1, 0, 1):
            for db in (-1, 0, 1):
                m = index.get((a + da, b + db))
                if m is not None and not keep[m]:
                    keep[m] = True
                    todo.append(m)
    return keep
