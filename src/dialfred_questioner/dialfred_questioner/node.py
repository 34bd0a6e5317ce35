"""`dialfred_questioner node`: a questioner as a ROS 2 node, serving `questioner/ask`.

Before each of the performer's actions, the performer sends the public task, the episode's seed,
the step (actions taken so far), the current frame, the dialogue so far and its top-2
action-probability gap (dialfred_msgs/srv/QuestionerAsk); the reply is a question for the oracle, or
none. The logic lives in `baselines.py` (random, all, confusion) or in a class of yours
(`package.module:ClassName`, with reset(task, seed), ask(observation, step), hear(qa)); this node
only converts messages and keeps one questioner's episode:

- the episode is (task id, seed); a request of another episode, or step 0 with an empty dialogue,
  starts it afresh (`reset(public task, seed)`), exactly as the in-process `QuestioningAgent` does;
- the QAs of the request's dialogue the questioner has not heard yet are handed to `hear` first;
- the confusion questioner decides from the request's `confusion_gap` (an error reply when it is < 0);
- a request repeated unchanged (a resend after a lost reply) gets the same reply.

Parameter `questioner` (read-only): random, all, confusion or package.module:ClassName. A bad
request gets ok=false and the reason; the node keeps serving.
"""

from __future__ import annotations

import sys

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from dialfred_msgs.msg import Observation
from dialfred_msgs.srv import QuestionerAsk
from dialfred_sim.messages import public_task_from_msg, qa_from_msg
from dialfred_sim.ros_util import SERVICE_QOS, error_reply, run_node

from .baselines import make_questioner


class QuestionerNode(Node):
    def __init__(self):
        super().__init__('dialfred_questioner')
        self.declare_parameter('questioner', 'random', ParameterDescriptor(
            description='random, all, confusion (needs the confusion_gap of each request) or '
                        'package.module:ClassName', read_only=True))
        name = self.get_parameter('questioner').value
        self.questioner = make_questioner(name)       # ValueError: said in one line by main()
        self.name = name
        self.episode = None        # (task_id, seed) being played
        self.heard = 0             # QAs of the episode's dialogue handed to the questioner
        self.last = None           # (request key, reply fields) of the last request
        self.create_service(QuestionerAsk, 'questioner/ask', self.on_ask, qos_profile=SERVICE_QOS)
        self.get_logger().info(f'serving questioner/ask with the {name!r} questioner')

    @error_reply()
    def on_ask(self, request: QuestionerAsk.Request, response: QuestionerAsk.Response) -> QuestionerAsk.Response:
        episode = (request.task.task_id, int(request.seed))
        key = (episode, int(request.step), len(request.dialogue), float(request.confusion_gap))
        if self.last is not None and self.last[0] == key:
            response.ok, response.ask, response.question_type, response.object_noun = self.last[1]
            return response
        if episode != self.episode or (request.step == 0 and not request.dialogue):
            self.questioner.reset(public_task_from_msg(request.task), int(request.seed))
            self.episode, self.heard = episode, 0
        if len(request.dialogue) < self.heard:
            response.ok, response.error = False, (f'the dialogue has {len(request.dialogue)} QAs, fewer than the '
                                                  f'{self.heard} heard in this episode: start it at step 0')
            return response
        for qa in request.dialogue[self.heard:]:
            self.questioner.hear(qa_from_msg(qa))
        self.heard = len(request.dialogue)
        ask_given_gap = getattr(self.questioner, 'ask_given_gap', None)
        if ask_given_gap is not None:
            if request.confusion_gap < 0:
                response.ok, response.error = False, (f'the {self.name!r} questioner needs the performer\'s '
                                                      'confusion_gap (>= 0) in the request')
                return response
            question = ask_given_gap(float(request.confusion_gap), int(request.step))
        else:
            question = self.questioner.ask(Observation(rgb=request.rgb), int(request.step))
        response.ok = True
        if question is not None:
            response.ask, response.question_type, response.object_noun = True, question.question_type, \
                question.object_noun
        self.last = (key, (response.ok, response.ask, response.question_type, response.object_noun))
        return response


def main(args=None):
    try:
        run_node(QuestionerNode, args)
    except ValueError as exc:      # an unknown questioner: one line, not a traceback
        print(f'dialfred_questioner node: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    main()
