"""`dialfred_oracle node`: the benchmark's simulated human, serving `/oracle/answer`.

Each question is answered from the simulator's ground truth at the moment of asking, fetched from
the simulator node over ROS (`sim/ground_truth`; no memory is shared between the processes). The
rules live in `answers.py`; this node only converts messages. The node keeps the last state it
fetched with the simulator's state version: every question still asks the simulator, but with that
version, and while nothing has changed the reply is a few bytes instead of the whole world (rendered
looks are kept per state too). Parameters:

- `perturb_type`, `perturb_probability`, `seed`: withhold answers of one question type with this
  probability (the paper's ablation used 50%); a withheld answer is a valid "I don't know." Which
  ones are withheld depends only on the seed, the task, the question and the agent's pose
  (`answers.Perturbation`), so runs repeat exactly, and asking again in the same place does not help.
- `answers` (`oracle`), `swap_resolution`, `tasks_file`: `swapped` answers every question with the answer
  to the same question in another task of the split (`swap.AnswerSwap`, a control: does the performer
  read its answers?), seen at the simulator's resolution. A FILE of a person's words, or
  `package.module:ClassName`: an answerer (answerers.py) puts each answer the oracle gives into its words.
- `human`: ask a person in the terminal instead (the simulator's answer is shown as a suggestion;
  an empty line accepts it), as a robot running this stack would ask its human. A question is put to
  the person once: a copy of it that the asker sends again while the person thinks (callers resend an
  unanswered question after a few seconds, in case it was lost) is matched to the question asked, in
  the same world state, and gets the person's answer without a second prompt. `human_timeout`: seconds
  the person may take (0: as long as they need); after it the robot hears "I don't know." and goes on.
- `log_file`: append every question and answer as a JSON line.
- `sim_timeout`: seconds to wait for the simulator.
- `cache_ground_truth` (true): keep the state as above; false fetches the whole world for every
  question (and again for an appearance's pixels), as the oracle did before; the answers are the same.

A malformed request gets valid=false with the reason; the node keeps serving.
"""

from __future__ import annotations

import json
import queue
import sys
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
import rclpy
from rclpy.node import Node

from dialfred_msgs.srv import GroundTruth, OracleAnswer
from dialfred_sim.ground_truth import Appearance, ObjectFact, Snapshot
from dialfred_sim.protocol import question_types
from dialfred_sim.ros_util import MAX_SEED, SERVICE_QOS, Param, declare_parameters, make_executor, run_node

from dialfred_sim.tasks.split_files import load_split, read_tasks_file

from .answers import (WITHHELD, Answer, Perturbation, answer_now, question_text, refusal_on_its_face,
                      situation_key)
from .answerers import AnswersError, speaking
from .swap import AnswerSwap


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
        temperature=f.temperature, held=f.held,
        seen_position=(f.seen_x, f.seen_y, f.seen_z) if f.in_view else None) for f in msg.objects}
    return Snapshot(agent=(a.x, a.y, a.rotation_deg, a.horizon_deg), expert_end=expert_end,
                    task_id=msg.task.task_id, task_type=msg.answer_key.task_type, instruction=msg.task.instruction,
                    task_objects=dict(zip(msg.task_nouns, msg.task_object_ids)), objects=objects,
                    appearances=appearances_from_msg(msg))


def appearances_from_msg(msg: GroundTruth.Response) -> dict[str, Appearance]:
    return {p.object_id: Appearance(object_id=p.object_id,
                                    pixels=np.frombuffer(bytes(p.pixels), np.uint8).reshape(-1, 3),
                                    from_current_view=p.from_current_view) for p in msg.appearances}


@dataclass
class WorldState:
    """One state of the simulator as the oracle holds it: its version, the snapshot (without looks)
    and the looks fetched so far for it."""

    version: int
    snapshot: Snapshot
    appearances: dict[str, Appearance] = field(default_factory=dict)

    def with_appearance(self, object_id: str) -> Snapshot:
        """The snapshot with the look of `object_id` (if fetched), as `snapshot(env, [object_id])`."""
        look = self.appearances.get(object_id)
        return replace(self.snapshot, appearances={object_id: look} if look is not None else {})


# The node's parameters (ros_util.Param): declared with their ranges; docs tables are made from them.
PARAMETERS = (
    Param('perturb_type', '', "the paper's ablation: withhold answers of this type ('' = none)",
          choices=lambda: ('', *question_types())),
    Param('perturb_probability', 0.0, '... with this probability (the paper: 0.5)', span=(0.0, 1.0)),
    Param('seed', 0, 'seeds which answers are withheld', span=(0, MAX_SEED)),
    Param('answers', 'oracle', "oracle: its own answers; swapped: a control, each answer replaced by the answer to "
          'the same question in another task of the split (swap.AnswerSwap; tasks of the shipped split named in the '
          "task id, or of tasks_file); a FILE of a person's words or package.module:ClassName: an answerer that words "
          'the answers (answerers.py)'),
    Param('swap_resolution', 64, 'swapped: the camera pixels the partner tasks are seen at (the simulator\'s)',
          span=(16, 1024)),
    Param('tasks_file', '', "swapped: the split file of the tasks played ('' = the shipped split of the task id)"),
    Param('human', False, 'ask a person in the terminal (see above)'),
    Param('human_timeout', 0.0, 'human: seconds a person may take to answer before the robot hears "I don\'t know." '
          '(0: as long as they need)', span=(0.0, 1e9)),
    Param('log_file', '', "append every question and answer as a JSON line (time, type, noun, valid, answer, "
          "reason, human); '' = none"),
    Param('sim_timeout', 5.0, 'seconds to wait for `sim/ground_truth`', span=(0.01, 3600.0)),
    Param('cache_ground_truth', True, 'keep the state per version as above; false fetches the whole world for every '
          'question (same answers)'))


class OracleNode(Node):
    """Thin ROS adapter over answers.answer()."""

    def __init__(self):
        super().__init__('dialfred_oracle')
        declare_parameters(self, PARAMETERS)
        p = self.get_parameter
        self.perturbation = Perturbation(p('perturb_type').value, float(p('perturb_probability').value),
                                         int(p('seed').value))
        spec = str(p('answers').value)
        self.swapped = spec == 'swapped'
        self.speaking = speaking(spec)      # an answerer of the user's (ValueError: the node does not start)
        self.swap_resolution = int(p('swap_resolution').value)
        self.tasks_file = str(p('tasks_file').value)
        self._swaps: dict[str, AnswerSwap] = {}        # split name -> its swap, made on the first question
        self.human = bool(p('human').value)
        self.human_timeout = float(p('human_timeout').value)
        self._heard: dict = {}     # (state version, task, type, noun) -> the person's Answer, for the state now
        self._lines: Optional[queue.Queue] = None    # the person's lines, read by a thread (human mode)
        self.log_file = p('log_file').value
        self.sim_timeout = float(p('sim_timeout').value)
        self.cache = bool(p('cache_ground_truth').value)
        self._state: Optional[WorldState] = None      # the newest state fetched (with the cache on)
        self._state_lock = threading.Lock()
        self._sim_settled = False
        # An answer waits on the simulator's reply inside the answer callback: the client lives on a
        # node of its own, with an executor of its own that the callback spins until the reply is in
        # (spinning the executor that runs the callback would hang: ros2/rclpy#1313).
        # It has no parameter services or rosout of its own: fewer endpoints for DDS discovery to match.
        self.sim_side = rclpy.create_node('dialfred_oracle_sim_client', context=self.context,
                                          start_parameter_services=False, enable_rosout=False)
        self.sim_cli = self.sim_side.create_client(GroundTruth, 'sim/ground_truth', qos_profile=SERVICE_QOS)
        self.sim_executor = make_executor()
        self.sim_executor.add_node(self.sim_side)
        self.create_service(OracleAnswer, 'oracle/answer', self.on_answer, qos_profile=SERVICE_QOS)
        mode = 'asking a person in this terminal' if self.human else 'from the simulator\'s ground truth'
        cache = 'kept per simulator state' if self.cache else 'fetched whole for every question'
        self.get_logger().info(f'serving oracle/answer, {mode} ({cache})')

    def on_answer(self, request: OracleAnswer.Request, response: OracleAnswer.Response) -> OracleAnswer.Response:
        qtype, noun = request.question_type, request.object_noun
        self._about = ''        # the task the answer is about: set once the simulator's state is read
        try:
            result = self.answer(qtype, noun)
        except (SimulatorUnavailable, AnswersError) as exc:
            result = Answer(False, reason=str(exc), question_type=qtype, object_noun=noun)
        except Exception as exc:   # a bad question must never take the node down
            self.get_logger().error(f'answering {qtype!r} {noun[:80]!r} failed: {exc!r}')
            result = Answer(False, reason=f'internal error: {type(exc).__name__}', question_type=qtype,
                            object_noun=noun)
        response.valid, response.answer, response.reason = bool(result.valid), result.text, result.reason
        response.task_id = self._about
        self._log(qtype, noun, result)
        return response

    def answer(self, qtype: str, noun: str) -> Answer:
        # Questions that are malformed on their face never reach the simulator.
        qtype, refusal = refusal_on_its_face(qtype, noun)
        if refusal is not None:
            return refusal
        state = self.world_state()
        snap = state.snapshot
        self._about = snap.task_id

        def with_looks(object_id: str) -> Snapshot:
            held = state if self.cache and object_id in state.appearances else self.world_state([object_id])
            return held.with_appearance(object_id)

        result = answer_now(snap, qtype, noun, with_looks)
        if self.swapped:
            try:
                return self.swap_for(snap.task_id).apply(result, snap.task_id, noun)
            except (ValueError, KeyError, OSError) as exc:
                return Answer(False, reason=f'no swapped answer: {exc}', question_type=qtype, object_noun=noun)
        # The paper's ablation: the human does not know (the question itself was fine).
        withheld = self.perturbation.apply(result, situation_key(snap, qtype, noun))
        if withheld is not result:
            return withheld
        if self.speaking is not None:
            return self.speaking.apply(result, snap.task_id, noun)
        if self.human and result.valid:
            key = (state.version, snap.task_id, qtype, noun)
            if key not in self._heard:     # a copy of a question already put to the person is not put again
                self._heard = {k: v for k, v in self._heard.items() if k[0] == state.version}
                self._heard[key] = self.ask_person(qtype, noun, result)
            result = self._heard[key]
        return result

    def swap_for(self, task_id: str) -> AnswerSwap:
        """The swap of the split that task `task_id` belongs to (ValueError without a task)."""
        if not task_id:
            raise ValueError('swapped answers need a task: the simulator plays none')
        if self.tasks_file:
            key = self.tasks_file
            if key not in self._swaps:
                self._swaps[key] = AnswerSwap(read_tasks_file(self.tasks_file).tasks, self.swap_resolution)
        else:
            key = task_id.split('/')[0]
            if key not in self._swaps:
                self._swaps[key] = AnswerSwap(load_split(key), self.swap_resolution)
        return self._swaps[key]

    def world_state(self, appearance_of: tuple[str, ...] | list[str] = ()) -> WorldState:
        """The simulator's state now, with the looks of `appearance_of`. With the cache, the request
        carries the version held, and an unchanged state costs a reply of a few bytes."""
        held = self._state if self.cache else None
        for _ in range(3):
            need = [oid for oid in appearance_of if held is None or oid not in held.appearances]
            reply = self.fetch(GroundTruth.Request(appearance_of=need, known_version=held.version if held else 0))
            if reply.unchanged and held is not None:
                state = held
            else:
                state = WorldState(reply.version, replace(snapshot_from_msg(reply), appearances={}))
            with self._state_lock:
                state.appearances.update(appearances_from_msg(reply))
                if self.cache and (self._state is None or state.version > self._state.version):
                    self._state = state
            if all(oid in state.appearances for oid in appearance_of):
                return state
            held = state      # the state changed since: the looks kept were of the old one
        return state

    def fetch(self, request: GroundTruth.Request) -> GroundTruth.Response:
        """One /sim/ground_truth call; SimulatorUnavailable when it cannot be had."""
        # Right after start-up, discovery may not have found the simulator yet: give it time.
        if not self.sim_cli.service_is_ready() and not self.sim_cli.wait_for_service(timeout_sec=self.sim_timeout):
            raise SimulatorUnavailable('the simulator is not reachable (no sim/ground_truth service)')
        if not self._sim_settled:
            # The reply path can match a moment after the request path (DDS service discovery
            # race): a reply sent before that would be lost, so wait a moment once.
            time.sleep(0.2)
            self._sim_settled = True
        future = self.sim_cli.call_async(request)
        deadline = time.monotonic() + self.sim_timeout
        while not future.done():
            left = deadline - time.monotonic()
            if left <= 0:
                self.sim_cli.remove_pending_request(future)
                raise SimulatorUnavailable(f'the simulator did not answer within {self.sim_timeout:g} s')
            self.sim_executor.spin_once(timeout_sec=min(left, 0.1))
        reply = future.result()
        if not reply.ok:
            raise SimulatorUnavailable(f'the simulator refused: {reply.error}')
        return reply

    def ask_person(self, qtype: str, noun: str, suggestion: Answer) -> Answer:
        """Print the question and read a person's answer from standard input, waiting as long as they need
        (or `human_timeout` seconds, then "I don't know.")."""
        limit = f'; after {self.human_timeout:g} s the robot hears "{WITHHELD}"' if self.human_timeout > 0 else ''
        print(f'\n[oracle] the agent asks ({qtype}): {question_text(qtype, noun)}', flush=True)
        print(f'[oracle] the simulator would say: {suggestion.text}', flush=True)
        print(f'[oracle] waiting for your answer (Enter alone: the simulator\'s{limit}):', flush=True)
        if self._lines is None:        # a thread reads the person's lines, so that waiting for one can time out
            self._lines = queue.Queue()
            threading.Thread(target=self._read_person, daemon=True).start()
        try:
            line = self._lines.get(timeout=self.human_timeout if self.human_timeout > 0 else None)
        except queue.Empty:
            print(f'[oracle] no answer in {self.human_timeout:g} s: the robot hears "{WITHHELD}" and goes on',
                  flush=True)
            return Answer(True, WITHHELD, question_type=qtype, object_noun=noun)
        if not line:
            self._lines.put('')      # standard input stays closed for every later question
            return Answer(False, reason='no person answered (standard input is closed)', question_type=qtype,
                          object_noun=noun)
        text = line.strip() or suggestion.text
        return Answer(True, text, question_type=qtype, object_noun=noun, object_id=suggestion.object_id)

    def _read_person(self) -> None:
        """Standard input's lines into `_lines` as the person types them; '' once it is closed."""
        for line in sys.stdin:
            self._lines.put(line)
        self._lines.put('')

    def destroy_node(self):
        self.sim_executor.shutdown()
        self.sim_side.destroy_node()
        super().destroy_node()

    def _log(self, qtype: str, noun: str, result: Answer) -> None:
        if not self.log_file:
            return
        row = {'time': time.time(), 'question_type': qtype, 'object_noun': noun[:200], 'valid': result.valid,
               'answer': result.text, 'reason': result.reason, 'human': self.human}
        with open(self.log_file, 'a') as f:
            f.write(json.dumps(row) + '\n')


def main(args=None):
    run_node(OracleNode, args)


if __name__ == '__main__':
    main()
