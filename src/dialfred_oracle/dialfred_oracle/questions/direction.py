"""The direction question, "Which direction should I turn to?", whole: the oracle's rule and wording
("You should turn left.", "You don't need to move."), the words read back, the check against the
ground truth, and the synthetic annotator's rule (asked when the target is behind the agent).

The answer points from the agent's pose now to where the expert ends the task (Snapshot.expert_end):
the way to go when it is elsewhere, the way to turn when it is here.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from dialfred_sim.ground_truth import ObjectFact, Snapshot
from dialfred_sim.protocol import PAPER_QUESTION_KINDS

from .base import Answer, AnswerContent, OracleQuestion, direction_bin, one_of, register, wrap_deg

SAME_PLACE_M = 0.125         # the expert's end is "here" on the same grid point (steps are 0.25 m) ...
SAME_HEADING_DEG = 45.0      # ... and this heading difference
GO_STRAIGHT = 'You should go straight ahead.'
TURN_LEFT = 'You should turn left.'
TURN_RIGHT = 'You should turn right.'
TURN_AROUND = 'You should turn around.'
STAY = "You don't need to move."
_MOVE_FOR_BIN = {'in front of you': GO_STRAIGHT, 'to your front left': GO_STRAIGHT, 'to your front right': GO_STRAIGHT,
                 'to your left': TURN_LEFT, 'to your right': TURN_RIGHT, 'to your rear left': TURN_AROUND,
                 'behind you': TURN_AROUND, 'to your rear right': TURN_AROUND}
# Each sentence read back: the way it says to go (AnswerContent.where), '' for staying.
MOVES = {GO_STRAIGHT: 'in front of you', TURN_LEFT: 'to your left', TURN_RIGHT: 'to your right',
         TURN_AROUND: 'behind you', STAY: ''}
_MOVES_READ = {text.lower(): where for text, where in MOVES.items()}


def advice(agent, expert_end) -> str:
    """What to do to get from pose `agent` to pose `expert_end` (x, y, rotation, horizon)."""
    if math.hypot(expert_end[0] - agent[0], expert_end[1] - agent[1]) < SAME_PLACE_M:
        turn = wrap_deg(expert_end[2] - agent[2])
        if abs(turn) <= SAME_HEADING_DEG:
            return STAY
        if abs(turn) >= 180.0 - SAME_HEADING_DEG:
            return TURN_AROUND
        return TURN_LEFT if turn > 0 else TURN_RIGHT
    return _MOVE_FOR_BIN[direction_bin(agent[:2], agent[2], expert_end[:2])]


class Direction(OracleQuestion):
    kind = PAPER_QUESTION_KINDS[2]
    human_share = 0.06
    choice_bias = -2.7161
    necessary_p = (0.3, 0.8)

    def answer(self, snapshot: Snapshot, object_id: str = '') -> Answer:
        if snapshot.expert_end is None:
            return Answer(False, reason='there is no task, so there is no way to go', question_type=self.name)
        return Answer(True, advice(snapshot.agent, snapshot.expert_end), question_type=self.name)

    def parts(self, text: str) -> Optional[dict]:
        where = _MOVES_READ.get(text.strip().lower())
        return None if where is None else {'where': where}

    def vocabulary(self) -> list[str]:
        return list(MOVES)

    def check(self, snapshot: Snapshot, ans: Answer, fact: Optional[ObjectFact]) -> dict[str, Optional[bool]]:
        """direction_ok: the advice recomputed from the geometry."""
        return {'direction_ok': snapshot.expert_end is not None
                and ans.text == advice(snapshot.agent, snapshot.expert_end)}

    def evidence(self, s) -> float:
        return 2.0 * float(s.target_behind)     # rare overall, so it must stand out where it fits

    def called_for(self, noun: str, s) -> bool:
        return s.target_behind

    def covered(self, c: AnswerContent) -> bool:
        return c.oracle_text in MOVES

    def candidate(self, c: AnswerContent, rng: np.random.Generator, distractor: bool) -> str:
        w = c.where.replace('_', ' ').lower()
        side = 'left' if 'left' in w else 'right' if 'right' in w else ''
        if any(k in w for k in ('behind', 'back', 'around')):
            forms = ['turn around', 'turn back', 'turn all the way around', "it's behind you, turn around",
                     'you need to turn around', 'turn around and walk forward']
            if side:
                forms += [f'turn around to your {side}', f'turn {side} twice']
        elif side:
            forms = [f'turn {side}', f'go {side}', f'you should turn {side}', f'turn to your {side}',
                     f'turn {side} and walk forward', f'turn {side}, then go straight', f'head {side}',
                     f'make a {side} turn', f'turn {side} and keep walking']
        elif any(k in w for k in ('front', 'ahead', 'forward', 'straight')):
            forms = ['go straight', 'walk straight ahead', 'keep going straight', "don't turn, just go forward",
                     'straight ahead of you', 'no need to turn, walk forward']
        else:
            forms = ["you don't need to move", 'stay where you are', 'no need to move', 'you are already there',
                     "don't move, it's right here", 'just stay here']
        return one_of(rng, forms)


DIRECTION = register(Direction())
