"""The oracle in the same process as a `DialfredEnv` (no ROS): what `/oracle/answer` would say now, and
`EnvServer`, which serves an episode's requests (dialfred_sim.episode) from both.

For loops that play many episodes in one process (the questioner's RL rollouts): the node's rule
(`answers.answer_now`, which `node.OracleNode.answer` calls too): the world's ground truth now, an
answer that reads an object's looks given again with that object's rendered pixels, and the paper's
perturbation (withholding one type's answers) keyed on the same situation, so an answer here is the
node's answer in the same state.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional

from dialfred_sim.episode import Ask, Reply, Request, Reset, SimReply
from dialfred_sim.ground_truth import snapshot
from dialfred_sim.protocol import DEFAULT_PROTOCOL, QA, env_observation

from . import answers
from .answers import Answer, Perturbation, refusal_on_its_face, situation_key


def answer_now(env, question_type: str, object_noun: str = '', perturbation: Optional[Perturbation] = None) -> Answer:
    """The oracle's answer to a question about `env` (a DialfredEnv after reset) in its state now."""
    qtype, refusal = refusal_on_its_face(question_type, object_noun)
    if refusal is not None:
        return refusal
    snap = snapshot(env)
    result = answers.answer_now(snap, qtype, object_noun, lambda object_id: snapshot(env, [object_id]))
    if perturbation is not None:
        result = perturbation.apply(result, situation_key(snap, qtype, object_noun))
    return result


class EnvServer:
    """Serves an episode's requests in this process: the simulator from `env` (a DialfredEnv, reset to
    `task`), questions from the oracle's rules (`dialfred_oracle.in_process.answer_now`, with `perturbation`;
    with `swap`, a `swap.AnswerSwap`, another task's answers), exactly as the simulator and oracle nodes
    answer them. `with_depth` / `with_segmentation` False: the observations carry None for those images,
    as the simulator node's replies do when a request does not ask for them (evaluations ask for RGB only).
    `protocol` 'chained' (dialfred_sim.chained): the reset starts `task` as an episode's first chained
    task, or with `continues`, goes on to it in the world as the last task left it."""

    def __init__(self, env, task, perturbation=None, swap=None, with_depth: bool = True,
                 with_segmentation: bool = True, protocol: str = DEFAULT_PROTOCOL, continues: bool = False):
        self.env, self.task, self.perturbation, self.swap = env, task, perturbation, swap
        self.with_depth, self.with_segmentation = with_depth, with_segmentation
        if continues and protocol == DEFAULT_PROTOCOL:
            raise ValueError('only a chained task continues from the last one')
        self.protocol, self.continues = protocol, continues
        self.info: dict = {}

    def __call__(self, request: Request) -> Reply:
        if isinstance(request, Ask):
            q = request.question
            ans = answer_now(self.env, q.question_type, q.object_noun, self.perturbation)
            if self.swap is not None:
                ans = self.swap.apply(ans, self.task.task_id, q.object_noun)
            return QA(q, bool(ans.valid), ans.text, ans.reason)
        if isinstance(request, Reset):
            try:
                if self.continues:
                    obs, self.info = self.env.continue_task(self.task)
                elif self.protocol == DEFAULT_PROTOCOL:
                    obs, self.info = self.env.reset(options={'task': self.task})
                else:
                    obs, self.info = self.env.reset(options={'task': self.task, 'protocol': self.protocol})
            except (ValueError, FileNotFoundError) as exc:
                return SimReply(ok=False, error=str(exc))
            return self._reply(obs, self.info, task=self.task.public())
        try:
            obs, _, terminated, truncated, info = self.env.step({'action': request.action,
                                                                 'pixel': (request.x, request.y)})
        except (ValueError, RuntimeError) as exc:     # refused: nothing changed
            return SimReply(step_count=int(self.info.get('step_count', 0)),
                            failed_actions=int(self.info.get('failed_actions', 0)), ok=False, error=str(exc))
        self.info = info
        return self._reply(obs, info, terminated=terminated, truncated=truncated)

    def _reply(self, obs, info: dict, terminated: bool = False, truncated: bool = False, task=None) -> SimReply:
        observation = env_observation(obs, info)
        if not (self.with_depth and self.with_segmentation):
            observation = replace(observation, depth=observation.depth if self.with_depth else None,
                                  segmentation=observation.segmentation if self.with_segmentation else None)
        return SimReply(observation=observation, step_count=observation.step_count,
                        failed_actions=observation.failed_actions, last_action_success=observation.last_action_success,
                        last_action_error=observation.last_action_error,
                        goal_conditions_met=int(info['goal_conditions_met']),
                        goal_conditions_total=int(info['goal_conditions_total']), success=bool(info['success']),
                        terminated=bool(terminated), truncated=bool(truncated), task=task)
