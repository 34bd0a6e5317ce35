"""Conversions between dialfred_msgs messages and the ROS-free `protocol` (no rclpy).

The nodes and the evaluation client use these, so that a QA or a task reads the same whichever
process made it: `qa_msg`/`qa_from_msg` (protocol.QA <-> QAPair, the question worded by `protocol.question_text`),
`qa_from_answer` (an /oracle/answer reply, checked to be about the task played), `public_task_from_msg`
(TaskDescription -> tasks.PublicTask: what an agent is told, never more), `observation_from_msg`
(Observation message -> protocol.Observation, the one conversion of what an agent is given) and
`sim_reply` (a /sim/reset or /sim/step response -> the episode loop's SimReply).
"""

from __future__ import annotations

from dialfred_msgs.msg import QAPair, TaskDescription
from dialfred_msgs.srv import SimReset

from .protocol import QA, Observation, Question, image_array
from .episode import SimReply
from .tasks.schema import PublicTask


def qa_msg(qa: QA, heard: str = '') -> QAPair:
    """The QAPair of `qa` (an invalid answer's reason is not carried: the answer is then empty), with what the
    performer took from it (`heard`, protocol.heard_by)."""
    q = qa.question
    return QAPair(question_type=q.question_type, object_noun=q.object_noun, question=q.text,
                  answer=qa.answer if qa.valid else '', valid=bool(qa.valid), heard=heard)


def qa_from_msg(msg: QAPair) -> QA:
    return QA(Question(msg.question_type, msg.object_noun), bool(msg.valid), msg.answer if msg.valid else '')


def qa_from_answer(question: Question, msg, task_id: str) -> QA:
    """The QA of an /oracle/answer reply `msg` to `question`, asked while playing task `task_id`. An answer about
    another task (the simulator was reset to another since, or a reset failed and left the one before) is
    invalid, with both tasks named: it says nothing true about this one."""
    if msg.valid and msg.task_id != task_id:
        about = repr(msg.task_id) if msg.task_id else 'no task'
        return QA(question, False, '', f'the oracle answered about {about}, not {task_id!r}')
    return QA(question, bool(msg.valid), msg.answer, msg.reason)


def public_task_from_msg(msg: TaskDescription) -> PublicTask:
    return PublicTask(task_id=msg.task_id, scene=msg.scene, split=msg.split, instruction=msg.instruction,
                      object_nouns=tuple(msg.object_nouns))


def task_description_msg(task: PublicTask) -> TaskDescription:
    return TaskDescription(task_id=task.task_id, scene=task.scene, split=task.split, instruction=task.instruction,
                           object_nouns=list(task.object_nouns))


def observation_from_msg(msg) -> Observation:
    """A dialfred_msgs/Observation as what an agent is given: the frames as arrays (depth and segmentation
    None when the simulator was asked not to send them), the pose, the hand and the last action's outcome.
    ValueError for a malformed image."""
    def optional(image, encoding):
        return image_array(image, encoding) if image.encoding or len(image.data) else None

    p = msg.pose
    return Observation(rgb=image_array(msg.rgb, 'rgb8'), depth=optional(msg.depth, '32FC1'),
                       segmentation=optional(msg.segmentation, '32SC1'),
                       pose=(float(p.x), float(p.y), float(p.rotation_deg), float(p.horizon_deg)),
                       held_object=msg.held_object, last_action_success=bool(msg.last_action_success),
                       last_action_error=msg.last_action_error, step_count=int(msg.step_count),
                       failed_actions=int(msg.failed_actions))


def sim_reply(msg):
    """A /sim/reset or /sim/step response as the episode loop's SimReply (the message kept as `raw`; a
    refused request's empty observation is None)."""
    obs = msg.observation
    is_reset = isinstance(msg, SimReset.Response)
    return SimReply(observation=observation_from_msg(obs) if msg.ok else None, step_count=int(obs.step_count), failed_actions=int(obs.failed_actions),
                    last_action_success=bool(obs.last_action_success), last_action_error=obs.last_action_error,
                    goal_conditions_met=0 if is_reset else int(msg.goal_conditions_met),
                    goal_conditions_total=int(msg.goal_conditions_total),
                    success=False if is_reset else bool(msg.success),
                    terminated=False if is_reset else bool(msg.terminated),
                    truncated=False if is_reset else bool(msg.truncated),
                    task=public_task_from_msg(msg.task) if is_reset else None, ok=bool(msg.ok), error=msg.error, raw=msg)
