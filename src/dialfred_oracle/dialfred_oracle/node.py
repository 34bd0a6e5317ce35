"""`dialfred_oracle node`: the benchmark's simulated human, serving `/oracle/answer`.

Each question is answered from the simulator's ground truth at the moment of asking, fetched from
the simulator node over ROS (`sim/ground_truth`; no memory is shared between the processes). The
rules live in `answers.py`; this node only converts messages. Parameters:

- `perturb_type`, `perturb_probability`, `seed`: withhold answers of one question type with this
  probability (the paper's ablation used 50%); a withheld answer is a valid "I don't know." Which
  ones are withheld depends only on the seed, the task, the question and the agent's pose
  (`answers.Perturbation`), so runs repeat exactly, and asking again in the same place does not help.
- `human`: ask a person in the terminal instead (the simulator's answer is shown as a suggestion;
  an empty line accepts it), as a robot running this stack would ask its human.
- `log_file`: append every question and answer as a JSON line.
- `sim_timeout`: seconds to wait for the simulator.

A malformed request gets valid=false with the reason; the node keeps serving.
"""

from __future__ import annotations

import json
import sys
import threading
import time

import numpy as np
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node

from dialfred_msgs.srv import GroundTruth, OracleAnswer
from dialfred_sim.ground_truth import Appearance, ObjectFact, Snapshot
from dialfred_sim.ros_util import SERVICE_QOS, run_node

from .answers import (MAX_NOUN_CHARS, QUESTION_ALIASES, QUESTION_TYPES, Answer, Perturbation, answer,
                      question_text, situation_key)


class SimulatorUnavailable(RuntimeError):
    pass


def snapshot_from_msg(msg: GroundTruth.Response) -> Snapshot:
    """The ROS-free Snapshot the answer rules read, from a `sim/ground_truth` reply."""
    a = msg.agent
    expert_end = None
    if msg.has_task:
        e = msg.answer_key.expert_end_pose
        expert_end = (e.x, e.y, e.rotation_deg, e.horizon_deg)
    objects = {f.object_id: ObjectFact(
        object_id=f.object_id, type_name=f.type_name, noun=f.noun, position=(f.x, f.y, f.z),
        parent_id=f.parent_id, parent_type=f.parent_type, parent_noun=f.parent_noun,
        preposition=f.preposition, colour=f.colour, material=f.material, pickupable=f.pickupable,
        is_open=f.is_open, is_on=f.is_on, is_dirty=f.is_dirty, is_sliced=f.is_sliced,
        temperature=f.temperature, held=f.held) for f in msg.objects}
    appearances = {p.object_id: Appearance(
        object_id=p.object_id, pixels=np.frombuffer(bytes(p.pixels), np.uint8).reshape(-1, 3),
        from_current_view=p.from_current_view) for p in msg.appearances}
    return Snapshot(agent=(a.x, a.y, a.rotation_deg, a.horizon_deg), expert_end=expert_end,
                    task_id=msg.task.task_id, task_type=msg.answer_key.task_type, instruction=msg.task.instruction,
                    task_objects=dict(zip(msg.task_nouns, msg.task_object_ids)), objects=objects,
                    appearances=appearances)


class OracleNode(Node):
    """Thin ROS adapter over answers.answer()."""

    def __init__(self):
        super().__init__('dialfred_oracle')
        self.declare_parameter('perturb_type', '')
        self.declare_parameter('perturb_probability', 0.0)
        self.declare_parameter('seed', 0)
        self.declare_parameter('human', False)
        self.declare_parameter('log_file', '')
        self.declare_parameter('sim_timeout', 5.0)
        p = self.get_parameter
        self.perturbation = Perturbation(p('perturb_type').value, float(p('perturb_probability').value),
                                         int(p('seed').value))
        self.human = bool(p('human').value)
        self.log_file = p('log_file').value
        self.sim_timeout = float(p('sim_timeout').value)
        self._sim_settled = False
        # The answer callback waits on the simulator's reply, which another thread must take.
        self.sim_cli = self.create_client(GroundTruth, 'sim/ground_truth', qos_profile=SERVICE_QOS,
                                          callback_group=ReentrantCallbackGroup())
        self.create_service(OracleAnswer, 'oracle/answer', self.on_answer, qos_profile=SERVICE_QOS,
                            callback_group=MutuallyExclusiveCallbackGroup())
        mode = 'asking a person in this terminal' if self.human else 'from the simulator\'s ground truth'
        self.get_logger().info(f'serving oracle/answer, {mode}')

    def on_answer(self, request: OracleAnswer.Request, response: OracleAnswer.Response) -> OracleAnswer.Response:
        qtype, noun = request.question_type, request.object_noun
        try:
            result = self.answer(qtype, noun)
        except SimulatorUnavailable as exc:
            result = Answer(False, reason=str(exc), question_type=qtype, object_noun=noun)
        except Exception as exc:   # a bad question must never take the node down
            self.get_logger().error(f'answering {qtype!r} {noun[:80]!r} failed: {exc!r}')
            result = Answer(False, reason=f'internal error: {type(exc).__name__}', question_type=qtype,
                            object_noun=noun)
        response.valid, response.answer, response.reason = bool(result.valid), result.text, result.reason
        self._log(qtype, noun, result)
        return response

    def answer(self, qtype: str, noun: str) -> Answer:
        # Questions that are malformed on their face never reach the simulator.
        if qtype not in QUESTION_TYPES and qtype not in QUESTION_ALIASES:
            return answer(None, qtype, noun)
        qtype = QUESTION_ALIASES.get(qtype, qtype)
        if qtype != 'direction' and len(noun) > MAX_NOUN_CHARS:
            return Answer(False, reason=f'the object noun is longer than {MAX_NOUN_CHARS} characters',
                          question_type=qtype)
        snap = self.ground_truth([])
        result = answer(snap, qtype, noun)
        if result.valid and qtype == 'appearance' and result.object_id:
            result = answer(self.ground_truth([result.object_id]), qtype, noun)
        # The paper's ablation: the human does not know (the question itself was fine).
        withheld = self.perturbation.apply(result, situation_key(snap, qtype, noun))
        if withheld is not result:
            return withheld
        if self.human and result.valid:
            result = self.ask_person(qtype, noun, result)
        return result

    def ground_truth(self, appearance_of: list[str]) -> Snapshot:
        # Right after start-up, discovery may not have found the simulator yet: give it time.
        if not self.sim_cli.service_is_ready() and not self.sim_cli.wait_for_service(timeout_sec=self.sim_timeout):
            raise SimulatorUnavailable('the simulator is not reachable (no sim/ground_truth service)')
        if not self._sim_settled:
            # The reply path can match a moment after the request path (DDS service discovery
            # race): a reply sent before that would be lost, so wait a moment once.
            time.sleep(0.2)
            self._sim_settled = True
        done = threading.Event()
        future = self.sim_cli.call_async(GroundTruth.Request(appearance_of=appearance_of))
        future.add_done_callback(lambda _: done.set())
        if not done.wait(self.sim_timeout):
            self.sim_cli.remove_pending_request(future)
            raise SimulatorUnavailable(f'the simulator did not answer within {self.sim_timeout:g} s')
        reply = future.result()
        if not reply.ok:
            raise SimulatorUnavailable(f'the simulator refused: {reply.error}')
        return snapshot_from_msg(reply)

    def ask_person(self, qtype: str, noun: str, suggestion: Answer) -> Answer:
        """Print the question and read a person's answer from standard input."""
        print(f'\n[oracle] the agent asks ({qtype}): {question_text(qtype, noun)}', flush=True)
        print(f'[oracle] the simulator would say: {suggestion.text}', flush=True)
        print('[oracle] your answer (empty line = use that): ', end='', flush=True)
        line = sys.stdin.readline()
        if not line:
            return Answer(False, reason='no person answered (standard input is closed)', question_type=qtype,
                          object_noun=noun)
        text = line.strip() or suggestion.text
        return Answer(True, text, question_type=qtype, object_noun=noun, object_id=suggestion.object_id)

    def _log(self, qtype: str, noun: str, result: Answer) -> None:
        if not self.log_file:
            return
        row = {'time': time.time(), 'question_type': qtype, 'object_noun': noun[:200], 'valid': result.valid,
               'answer': result.text, 'reason': result.reason, 'human': self.human}
        with open(self.log_file, 'a') as f:
            f.write(json.dumps(row) + '\n')


def main(args=None):
    run_node(OracleNode, args, executor_factory=lambda: MultiThreadedExecutor(num_threads=4))


if __name__ == '__main__':
    main()
