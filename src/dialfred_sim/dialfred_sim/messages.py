"""Conversions between dialfred_msgs messages and the ROS-free `protocol` (no rclpy).

The nodes and the evaluation client use these, so that a QA or a task reads the same whichever
process made it: `qa_msg`/`qa_from_msg` (protocol.QA <-> QAPair, the question worded by `protocol.question_text`),
`qa_from_answer` (an /oracle/answer reply, checked to be about the task played), `public_task_from_msg`
(TaskDescription -> tasks.PublicTask: what an agent is told, never more).
"""

from __future__ import annotations

from dialfred_msgs.msg import QAPair, TaskDescription

from .protocol import QA, Question
from .episode import SimReply
from .tasks.schema import PublicTask


def qa_msg(qa: QA) -> QAPair:
    """The QAPair of `qa` (an invalid answer's reason is not carried: the answer is then empty)."""
    q = qa.question
    return QAPair(question_type=q.question_type, object_noun=q.object_noun, question=q.text,
                  answer=qa.answer if qa.valid else '', valid=bool(qa.valid))


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


def sim_reply(msg):
    """A /sim/reset or /sim/step response as the episode loop's SimReply (the message kept as `raw`)."""
    obs = msg.observation
    is_reset = hasattr(msg, 'task')
    return SimReply(observation=obs, step_count=int(obs.step_count), failed_actions=int(obs.failed_actions),
                    last_action_success=bool(obs.last_action_success), last_action_error=obs.last_action_error,
                    goal_conditions_met=0 if is_reset else int(msg.goal_conditions_met),
                    goal_conditions_total=int(msg.goal_conditions_total),
                    success=False if is_reset else bool(msg.success),
                    terminated=False if is_reset else bool(msg.terminated),
                    truncated=False if is_reset else bool(msg.truncated),
                    task=public_task_from_msg(msg.task) if is_reset else None, ok=bool(msg.ok), error=msg.error, raw=msg)
