"""`Targets`, a part of `MapAgent` (mapper/agent.py): where the object of a step is in view and which cell
to click: masks within reach, inside open receptacles, where the agent put things, the answers' colour
and direction."""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .geometry import off_bearing
from .language import Step
from .rules import ANSWER_CONE_DEG, INSIDE_P, MIN_TARGET_CELLS, PLACED_M, PUT_CHANGE, REACH_M, mask_components


class Targets:
    """The targets of the map performer (its state is `MapAgent`'s: see `MapAgent.reset_state`)."""

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
        comps = mask_components(mask)
        colour = self._colour_wanted(step)
        led_mapped = self._led_elsewhere(k, step)
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
            if led_mapped and not self._led_cone(step, p[:1], p[1:2])[0]:
                continue                      # not where the direction answer points, and the map has one there
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

    def _led_elsewhere(self, k: int, step: Step) -> bool:
        """Whether the map holds class k where the last direction answer points (`reading._led_cone`); the map
        is not searched where no such answer holds (most steps)."""
        if self._led(step) is None:
            return False
        cx, cy, _ = self.map.object_cells(k)
        return bool(len(cx)) and bool(self._led_cone(step, *self.map.cell_centre(cx, cy)).any())

    def _place_penalty(self, type_name: str, p: np.ndarray) -> float:
        """How far a mask of `type_name` centred on map point p lies from the instance acted on before
        (an opened fridge is the one to put into and close), else from where a location answer said it is."""
        anchor = self.anchors.get(type_name)
        if anchor is not None:
            return 100.0 * math.hypot(p[0] - anchor[0], p[1] - anchor[1])
        fact = self.facts.get(('location', type_name))
        if fact is not None and fact[0].bearing_deg is not None:
            f, at = fact
            diff = float(off_bearing(at, f.bearing_deg, p[:1], p[1:2])[0])
            return 2.0 * diff + (500.0 if diff > ANSWER_CONE_DEG else 0.0)
        return 0.0
