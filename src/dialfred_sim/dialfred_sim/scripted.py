"""A scripted explorer: a simple agent that wanders and handles what it sees (for demos and tests).

It reads only what a real agent gets (frame, depth, instance segmentation with the instance table)
and the object catalog; no ground truth. It picks up the first small object it can reach, opens
closed containers it passes, puts the held object down on the next surface it reaches, and otherwise
walks ahead, turning when blocked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .catalog import load_catalog

# Stay a little inside the simulator's 1.5 m. The explorer measures from the eye (it does not track its
# pitch); the simulator measures from the agent's vertical axis, which is never farther: what it finds
# in reach is in reach, and low things near by it may miss.
REACH = 1.4


@dataclass(frozen=True)
class Decision:
    action: str
    pixel: tuple[int, int] = (-1, -1)


def type_of(object_id: str) -> str:
    """'Apple_3' -> 'Apple'; structure names ('Floor', 'Wall') come back as they are."""
    return object_id.rsplit('_', 1)[0]


class ExplorerPolicy:
    def __init__(self, seed: int = 0, hold_steps: int = 4):
        self.rng = np.random.default_rng(seed)
        self.opened: set[str] = set()
        self.handled: set[str] = set()
        self.held_for = 0
        self.hold_steps = hold_steps
        self.catalog = load_catalog()
        self.last = 'MoveAhead'

    def _reachable(self, depth, segmentation, instances):
        """(object id, type, pixel) for each instance with enough pixels within reach, largest first."""
        h, w = depth.shape
        # Distance along each pixel's ray from the eye (the camera has a 90 degree field of view: tan 45 = 1).
        u = (np.arange(w) + 0.5) / w * 2 - 1
        v = (np.arange(h) + 0.5) / h * 2 - 1
        within = depth * np.sqrt(1 + u[None, :] ** 2 + v[:, None] ** 2) < REACH
        ids, counts = np.unique(segmentation[within], return_counts=True)
        found = []
        for body, count in sorted(zip(ids.tolist(), counts.tolist()), key=lambda t: -t[1]):
            name = instances.get(body)
            if name is None or count < 12 or type_of(name) not in self.catalog:
                continue
            ys, xs = np.nonzero((segmentation == body) & within)
            k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))
            found.append((name, self.catalog[type_of(name)], (int(xs[k]), int(ys[k]))))
        return found

    def act(self, rgb, depth, segmentation, instances, held: str, last_success: bool) -> Decision:
        decision = self._choose(depth, segmentation, instances, held, last_success)
        self.last = decision.action
        return decision

    def _choose(self, depth, segmentation, instances, held, last_success) -> Decision:
        visible = self._reachable(depth, segmentation, instances)
        if held:
            self.held_for += 1
            if self.held_for >= self.hold_steps:
                for name, t, px in visible:
                    if t.receptacle and not t.openable and name != held and name not in self.handled:
                        self.handled.add(name)
                        return Decision('Put', px)
        else:
            self.held_for = 0
            for name, t, px in visible:
                if t.pickupable and not t.receptacle and name not in self.handled:
                    self.handled.add(name)
                    return Decision('Pickup', px)
        for name, t, px in visible:
            if t.openable and not t.pickupable and name not in self.opened:
                self.opened.add(name)
                return Decision('Open', px)
        if self.last == 'MoveAhead' and not last_success:
            return Decision('RotateLeft' if self.rng.random() < 0.5 else 'RotateRight')
        if self.rng.random() < 0.15:
            return Decision('RotateLeft' if self.rng.random() < 0.5 else 'RotateRight')
        return Decision('MoveAhead')
