"""The oracle in the same process as a `DialfredEnv` (no ROS): what `/oracle/answer` would say now.

For loops that play many episodes in one process (the questioner's RL rollouts): the same rules
as the node (`node.OracleNode.answer`): the world's ground truth now, an appearance answer
recomputed with the looks of the object it is about, and the paper's perturbation (withholding one
type's answers) keyed on the same situation, so an answer here is the node's answer in the same
state.
"""

from __future__ import annotations

from typing import Optional

from dialfred_sim.ground_truth import snapshot

from .answers import MAX_NOUN_CHARS, Answer, Perturbation, answer, parse_question_type, situation_key


def answer_now(env, question_type: str, object_noun: str = '', perturbation: Optional[Perturbation] = None) -> Answer:
    """The oracle's answer to a question about `env` (a DialfredEnv after reset) in its state now."""
    qtype = parse_question_type(question_type)
    if qtype is None:
        return answer(None, question_type, object_noun)
    if qtype != 'direction' and len(object_noun) > MAX_NOUN_CHARS:
        return Answer(False, reason=f'the object noun is longer than {MAX_NOUN_CHARS} characters', question_type=qtype)
    snap = snapshot(env)
    result = answer(snap, qtype, object_noun)
    if result.valid and qtype == 'appearance' and result.object_id:
        result = answer(snapshot(env, [result.object_id]), qtype, object_noun)
    if perturbation is not None:
        result = perturbation.apply(result, situation_key(snap, qtype, object_noun))
    return result
