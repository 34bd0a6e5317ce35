"""`AnswerReading`, a part of `MapAgent` (mapper/agent.py): the dialogue as the map performer reads it:
answers become facts (`words.read_answer`: the oracle's templates, or a person's words), taken in against the pose the frame of their step was
seen from."""

from __future__ import annotations

from collections import deque
from typing import Optional

import numpy as np

from dialfred_oracle.colours import colour_name
from dialfred_sim.protocol import QA

from .geometry import Pose, STEP_M, off_bearing
from .language import Step, describe_fact
from .words import read_answer
from .rules import ANSWER_CONE_DEG

# A direction answer points where the task's expert ended: its sector (straight on: the three front bins;
# left, right: one bin; turn around: the three rear ones) widened by half a bin, as a half-width in degrees
# about the answer's turn, seen from where it was heard (`_led`).
LEAD_HALF_WIDTH = {0: 90.0, 90: 45.0, -90: 45.0, 180: 90.0}


class AnswerReading:
    """The reading of the map performer (its state is `MapAgent`'s: see `MapAgent.reset_state`)."""

    def hear(self, qa: QA) -> None:
        """A QA of the dialogue: location, appearance and direction answers become facts (taken in
        when the step's frame has been perceived: `_observe`)."""
        self._heard.append(qa)

    def understood(self, qa: QA) -> str:
        """What the reader takes from `qa`'s answer (protocol.AnswerReader): '' for an invalid one."""
        return describe_fact(read_answer(qa.question.question_type, qa.answer, qa.question.object_noun)) \
            if qa.valid else ''

    def _take_in(self, qa: QA) -> None:
        self.answers += 1
        if not qa.valid:
            return
        fact = read_answer(qa.question.question_type, qa.answer, qa.question.object_noun)
        if fact is None:
            return
        if fact.kind == 'held' and fact.receptacle == '':
            self.held, self.held_known, self.held_confirmed = fact.object_type, True, True
        elif fact.kind == 'location':
            if fact.object_type == self.held and not self.held_confirmed:
                self.held = None                  # it is somewhere in the room, so not in hand
            self.cone_spent.discard(fact.object_type)    # a new answer, from here: its direction is searched anew
        elif fact.kind == 'direction':
            self.direction = (fact, self.step)      # followed at this step (wayfinding._follow)
            if fact.turn_deg == 90:
                self.turns = deque(['RotateLeft'])
            elif fact.turn_deg == -90:
                self.turns = deque(['RotateRight'])
            elif fact.turn_deg == 180:
                self.turns = deque(['RotateLeft', 'RotateLeft'])
        self.facts[(fact.kind, fact.object_type)] = (fact, Pose(self.pose.i, self.pose.j, self.pose.heading,
                                                                 self.pose.horizon))

    def _answered_cone(self, type_name: str, x: np.ndarray, y: np.ndarray) -> Optional[np.ndarray]:
        """Which map points (x, y) lie in the direction a location answer gave for `type_name` (within
        ANSWER_CONE_DEG of it, seen from where the answer was heard); None without such an answer, or
        once an instance of the type has been acted on (that one is the one)."""
        fact = self.facts.get(('location', type_name))
        if fact is None or type_name in self.anchors or type_name in self.cone_spent:
            return None
        f, at = fact
        if f.bearing_deg is None:            # the words named a place, not a side
            return None
        return off_bearing(at, f.bearing_deg, x, y) <= ANSWER_CONE_DEG

    def _led(self, step: Step) -> Optional[tuple[Pose, float, float]]:
        """(where it was heard, bearing, half-width) of the last direction answer, which lasts until the next:
        for the plan's last go-to only (the expert's end is where that go-to ends); None without either, or
        when the answer was "here"."""
        if step.kind != 'goto' or any(s.kind == 'goto' for s in list(self.plan)[1:]):
            return None
        fact = self.facts.get(('direction', ''))
        if fact is None or fact[0].stay or fact[0].turn_deg not in LEAD_HALF_WIDTH:
            return None
        f, at = fact
        return at, float(f.turn_deg), LEAD_HALF_WIDTH[f.turn_deg]

    def _led_cone(self, step: Step, x: np.ndarray, y: np.ndarray) -> Optional[np.ndarray]:
        """Which map points (x, y) lie where the last direction answer points (`_led`); None without one."""
        lead = self._led(step)
        if lead is None:
            return None
        at, bearing, half = lead
        return off_bearing(at, bearing, x, y) <= half

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
        h, w = self.rgb.shape[:2]
        s = comp.shape[0]
        rows = (np.arange(h) * s // h)
        cols = (np.arange(w) * s // w)
        full = comp[rows[:, None], cols[None, :]]
        return colour_name(self.rgb[full])

    def _cone(self, at: Pose, bearing: float, half_width: float = ANSWER_CONE_DEG) -> np.ndarray:
        """[nodes, nodes] bool: grid points within half_width degrees of `bearing` seen from `at`."""
        metres = (np.arange(self.map.nodes) - self.map.node_offset()) * STEP_M
        return off_bearing(at, bearing, metres[:, None], metres[None, :]) <= half_width
