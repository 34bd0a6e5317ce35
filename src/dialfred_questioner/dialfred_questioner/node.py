"""`dialfred_questioner node`: a questioner as a ROS 2 node, serving `questioner/ask`.

Before each of the performer's actions, the performer sends the public task, the episode's seed,
the step (actions taken so far), the current frame, the dialogue so far and its top-2
action-probability gap (dialfred_msgs/srv/QuestionerAsk); the reply is a question for the oracle, or
none. The logic lives in `baselines.py` (random, all, confusion), in `policy.LearnedQuestioner` (a
learned questioner's checkpoint: a shipped name such as rl-anytime, or learned:PATH) or in a class of
yours (`package.module:ClassName`, with reset(task, seed), ask(observation, step), hear(qa)), made by
`questioners.make_questioner`; this node only converts messages and keeps one questioner's episode:

- the episode is the request's `episode` (the performer node sends its RunTask goal's id, so each goal
  is one episode and a task played again is a new one); a request of another episode starts it afresh
  (`reset(public task, seed)`), exactly as the in-process `QuestioningAgent` does. A request without an
  `episode` (a client of its own) is of the episode (task id, seed), and step 0 with an empty dialogue
  starts it afresh too;
- the QAs of the request's dialogue the questioner has not heard yet are handed to `hear` first;
- the confusion questioner, and a learned one with the confusion timing, decide from the request's
  `confusion_gap` (an error reply when it is < 0); a learned one reads the request's frame (rgb8);
- a request repeated unchanged (a resend after a lost reply) gets the same reply;
- every question it decides on is published on `questioner/question` (dialfred_msgs/QAPair with the
  question only: answer empty, valid false; the answered QA is the performer's `dialogue/qa`).

Parameters (read-only): `questioner` (random, all, confusion, a shipped learned name of
`policy.SHIPPED_LEARNED`, learned:PATH, learned with `checkpoint`, or package.module:ClassName);
for a learned questioner `timing` / `gap` / `epsilon` replace its checkpoint's where set ('' / 0 / < 0
keep it; `epsilon` also sets the confusion baseline's), and `torch_threads`. A bad request gets
ok=false and the reason; the node keeps serving.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from rclpy.node import Node

from dialfred_msgs.msg import QAPair
from dialfred_msgs.srv import QuestionerAsk
from dialfred_sim.protocol import QA, GapQuestioner, Observation, image_array
from dialfred_sim.messages import public_task_from_msg, qa_from_msg, qa_msg
from dialfred_sim.ros_util import SERVICE_QOS, Param, declare_parameters, error_reply, run_node

from .baselines import QUESTIONERS, ModelConfusionQuestioner
from .questioners import make_questioner


# The node's parameters (ros_util.Param): declared with their ranges; docs tables are made from them.
PARAMETERS = (
    Param('questioner', 'random', 'random, all, confusion (needs the confusion_gap of each request), a '
          'shipped learned questioner (pretrained, rl-begin, rl-anytime, rl-anytime-1, rl-anytime-10, rl-mc, '
          'rl-anytime-withhold-<type>, rl-anytime-no-dialogue, map-rl-anytime, rl-anytime-chained, '
          'map-rl-anytime-chained), learned (with `checkpoint`), learned:PATH, '
          'or package.module:ClassName'),
    Param('checkpoint', '', 'for questioner=learned: the questioner checkpoint file'),
    Param('timing', '', "a learned questioner's timing ('' = its checkpoint's)",
          choices=('', 'begin', 'anytime', 'confusion')),
    Param('gap', 0, "the anytime timing's gap in steps (0 = the checkpoint's)", span=(0, 1000)),
    Param('epsilon', -1.0, "the confusion threshold on the top-2 gap (< 0 = the checkpoint's, or 0.5 for "
          'confusion)', span=(-1.0, 1.0)),
    Param('torch_threads', 1, 'torch intra-op threads of a learned questioner', span=(1, 256)))


def is_learned(questioner) -> bool:
    """Whether `questioner` is a LearnedQuestioner."""
    # Imported here: policy imports torch, which the baselines' node does without (its start is faster).
    from .policy import LearnedQuestioner
    return isinstance(questioner, LearnedQuestioner)


def request_observation(request: QuestionerAsk.Request) -> Observation:
    """The request's frame as the questioner's observation; a request without a readable frame gives
    an empty (0x0) one: a learned questioner's request was refused for it first (`refusal`)."""
    try:
        return Observation(rgb=image_array(request.rgb, 'rgb8'))
    except ValueError:
        return Observation(rgb=np.zeros((0, 0, 3), np.uint8))


class QuestionerNode(Node):
    def __init__(self):
        super().__init__('dialfred_questioner')
        declare_parameters(self, PARAMETERS)
        p = self.get_parameter
        name, checkpoint = p('questioner').value, p('checkpoint').value
        if name == 'learned':
            if not checkpoint:
                raise ValueError('questioner learned needs the `checkpoint` parameter')
            name = f'learned:{checkpoint}'
        elif checkpoint:
            raise ValueError(f'the `checkpoint` parameter is for questioner learned, not {name!r}')
        self.name = name
        self.questioner = make_questioner(name)       # ValueError: said in one line by main()
        self.retime(p('timing').value, int(p('gap').value), float(p('epsilon').value))
        self.episode = None        # the episode being played: the requests' `episode`, or (task_id, seed)
        self.heard = 0             # QAs of the episode's dialogue handed to the questioner
        self.last = None           # (request key, reply fields) of the last request
        self.question_pub = self.create_publisher(QAPair, 'questioner/question', 100)
        self.create_service(QuestionerAsk, 'questioner/ask', self.on_ask, qos_profile=SERVICE_QOS)
        timing = self.questioner.timing if is_learned(self.questioner) else ''
        self.get_logger().info(f'serving questioner/ask with the {name!r} questioner {timing}'.rstrip())

    def retime(self, mode: str, gap: int, epsilon: float) -> None:
        """Apply the timing parameters (ValueError where they do not fit the questioner)."""
        if isinstance(self.questioner, ModelConfusionQuestioner) and not (mode or gap):
            if epsilon >= 0:
                self.questioner = ModelConfusionQuestioner(epsilon)
            return
        if type(self.questioner) in QUESTIONERS.values():
            if mode or gap or epsilon >= 0:
                raise ValueError(f'the timing, gap and epsilon parameters are not for the {self.name!r} questioner')
            return
        import torch     # a learned questioner only: the baselines' node starts without torch's import time

        from .policy import retimed  # lazy: pybullet, torch, which the rest of this module does without
        if is_learned(self.questioner):
            torch.set_num_threads(max(1, int(self.get_parameter('torch_threads').value)))
            self.questioner.timing = retimed(self.questioner.timing, mode, gap, epsilon)
        elif mode or gap or epsilon >= 0:
            raise ValueError('the timing, gap and epsilon parameters are for a learned questioner')

    @property
    def needs_gap(self) -> bool:
        return isinstance(self.questioner, GapQuestioner) and self.questioner.needs_gap

    def refusal(self, request: QuestionerAsk.Request) -> str:
        """Why the request cannot be served ('' if it can), found before any state changes."""
        if request.seed < 0:
            return f'seed must be a non-negative integer, got {request.seed}'
        if math.isnan(request.confusion_gap):
            return 'confusion_gap must be a number (< 0 = unknown), got nan'
        if self.needs_gap and request.confusion_gap < 0:
            return f'the {self.name!r} questioner needs the performer\'s confusion_gap (>= 0) in the request'
        if is_learned(self.questioner):
            try:
                rgb = image_array(request.rgb, 'rgb8')
            except ValueError as exc:
                return f'rgb: {exc}'
            if rgb.size == 0:
                return 'rgb: the learned questioner needs the current frame; this one is empty'
        return ''

    @error_reply()
    def on_ask(self, request: QuestionerAsk.Request, response: QuestionerAsk.Response) -> QuestionerAsk.Response:
        episode = request.episode or (request.task.task_id, int(request.seed))
        key = (episode, int(request.step), len(request.dialogue), float(request.confusion_gap))
        if self.last is not None and self.last[0] == key:
            response.ok, response.ask, response.question_type, response.object_noun = self.last[1]
            return response
        refusal = self.refusal(request)            # checked before anything changes
        if refusal:
            response.ok, response.error = False, refusal
            return response
        if episode != self.episode or (not request.episode and request.step == 0 and not request.dialogue):
            self.questioner.reset(public_task_from_msg(request.task), int(request.seed))
            self.episode, self.heard = episode, 0
        if len(request.dialogue) < self.heard:
            response.ok, response.error = False, (f'the dialogue has {len(request.dialogue)} QAs, fewer than the '
                                                  f'{self.heard} heard in this episode: start it at step 0')
            return response
        for qa in request.dialogue[self.heard:]:
            self.questioner.hear(qa_from_msg(qa))
        self.heard = len(request.dialogue)
        observation = request_observation(request)
        if self.needs_gap:
            question = self.questioner.ask_given_gap(observation, int(request.step), float(request.confusion_gap))
        else:
            question = self.questioner.ask(observation, int(request.step))
        response.ok = True
        if question is not None:
            response.ask, response.question_type, response.object_noun = True, question.question_type, \
                question.object_noun
            self.question_pub.publish(qa_msg(QA(question, False, '')))
        self.last = (key, (response.ok, response.ask, response.question_type, response.object_noun))
        return response


def main(args=None):
    try:
        run_node(QuestionerNode, args)
    except ValueError as exc:      # an unknown questioner, a missing checkpoint: one line, not a traceback
        print(f'dialfred_questioner node: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    main()
