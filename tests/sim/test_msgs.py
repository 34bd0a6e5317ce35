"""The dialfred_msgs interfaces are built, importable, and carry the documented fields."""

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from dialfred_msgs.msg import Action, AgentPose, Observation, QAPair, TaskAnswerKey, TaskDescription
from dialfred_msgs.srv import OracleAnswer, SimReset, SimStep

RGB_4X4 = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3)


def rgb_image(pixels: np.ndarray) -> Image:
    height, width, _ = pixels.shape
    return Image(height=height, width=width, encoding='rgb8', is_bigendian=0, step=width * 3,
                 data=pixels.tobytes())


def make_observation() -> Observation:
    return Observation(
        header=Header(frame_id='camera'),
        rgb=rgb_image(RGB_4X4),
        instance_ids=[3, 7],
        instance_object_ids=['Apple_3', 'Fridge_7'],
        pose=AgentPose(x=1.25, y=-0.5, camera_height=0.9, rotation_deg=90.0, horizon_deg=30.0),
        held_object='Apple_3',
        last_action_success=False,
        last_action_error='blocked',
        step_count=12,
        failed_actions=1,
        done=False,
    )


def test_action_names_are_alfreds():
    assert {
        Action.MOVE_AHEAD, Action.ROTATE_LEFT, Action.ROTATE_RIGHT, Action.LOOK_UP, Action.LOOK_DOWN,
        Action.PICKUP, Action.PUT, Action.OPEN, Action.CLOSE, Action.TOGGLE_ON, Action.TOGGLE_OFF,
        Action.SLICE, Action.STOP,
    } == {
        'MoveAhead', 'RotateLeft', 'RotateRight', 'LookUp', 'LookDown', 'Pickup', 'Put', 'Open',
        'Close', 'ToggleOn', 'ToggleOff', 'Slice', 'Stop',
    }
    assert Action.get_fields_and_field_types() == {'action': 'string', 'x': 'int32', 'y': 'int32'}


def test_question_types():
    assert (QAPair.LOCATION, QAPair.APPEARANCE, QAPair.DIRECTION) == (
        'location', 'appearance', 'direction')
    assert QAPair.get_fields_and_field_types() == {
        'question_type': 'string', 'object_noun': 'string', 'question': 'string',
        'answer': 'string', 'valid': 'boolean', 'heard': 'string'}


def test_observation_fields():
    assert Observation.get_fields_and_field_types() == {
        'header': 'std_msgs/Header',
        'rgb': 'sensor_msgs/Image',
        'depth': 'sensor_msgs/Image',
        'segmentation': 'sensor_msgs/Image',
        'instance_ids': 'sequence<int32>',
        'instance_object_ids': 'sequence<string>',
        'pose': 'dialfred_msgs/AgentPose',
        'held_object': 'string',
        'last_action_success': 'boolean',
        'last_action_error': 'string',
        'step_count': 'uint32',
        'failed_actions': 'uint32',
        'done': 'boolean',
    }
    assert AgentPose.get_fields_and_field_types() == {
        'x': 'double', 'y': 'double', 'camera_height': 'double', 'rotation_deg': 'double',
        'horizon_deg': 'double'}
    # What any client that resets sees: no type, plan, expert length or end pose (TaskAnswerKey has them).
    assert TaskDescription.get_fields_and_field_types() == {
        'task_id': 'string', 'scene': 'string', 'split': 'string', 'instruction': 'string',
        'object_nouns': 'sequence<string>'}
    assert TaskAnswerKey.get_fields_and_field_types() == {
        'task_type': 'string', 'step_instructions': 'sequence<string>', 'expert_length': 'uint32',
        'expert_end_pose': 'dialfred_msgs/AgentPose', 'goal_conditions_total': 'uint32'}


def test_observation_with_a_4x4_rgb_image_round_trips():
    observation = make_observation()
    assert isinstance(observation.rgb, Image)
    assert isinstance(observation.pose, AgentPose)
    assert list(observation.instance_ids) == [3, 7]
    assert observation.step_count == 12

    restored = deserialize_message(serialize_message(observation), Observation)

    assert restored == observation
    assert (restored.rgb.height, restored.rgb.width, restored.rgb.encoding) == (4, 4, 'rgb8')
    pixels = np.frombuffer(bytes(restored.rgb.data), dtype=np.uint8).reshape(4, 4, 3)
    np.testing.assert_array_equal(pixels, RGB_4X4)
    assert restored.pose.rotation_deg == 90.0
    assert list(restored.instance_object_ids) == ['Apple_3', 'Fridge_7']


def test_field_types_are_enforced_when_checking_is_on():
    # Jazzy checks field values only with check_fields=True or ROS_PYTHON_CHECK_FIELDS=1.
    observation = Observation(check_fields=True)
    with pytest.raises(AssertionError):
        observation.step_count = -1  # uint32
    with pytest.raises(AssertionError):
        observation.done = 1  # bool, not int
    with pytest.raises(AssertionError):
        observation.rgb = 'not an image'
    with pytest.raises(AssertionError):
        Action(check_fields=True).x = 1.5  # int32


def test_services_have_the_documented_request_and_response():
    assert SimReset.Request.get_fields_and_field_types() == {
        'scene': 'string', 'seed': 'int64', 'task_id': 'string', 'with_depth': 'boolean',
        'with_segmentation': 'boolean', 'protocol': 'string', 'carry_on': 'boolean'}
    assert SimReset.Response.get_fields_and_field_types() == {
        'ok': 'boolean', 'error': 'string', 'observation': 'dialfred_msgs/Observation',
        'task': 'dialfred_msgs/TaskDescription', 'goal_conditions_total': 'uint32'}
    assert SimStep.Request.get_fields_and_field_types() == {
        'action': 'dialfred_msgs/Action', 'with_depth': 'boolean', 'with_segmentation': 'boolean'}
    # Replies carry every channel unless the caller opts out.
    for request in (SimReset.Request(), SimStep.Request()):
        assert request.with_depth and request.with_segmentation
    assert SimStep.Response.get_fields_and_field_types() == {
        'ok': 'boolean', 'error': 'string', 'observation': 'dialfred_msgs/Observation',
        'reward': 'double', 'terminated': 'boolean', 'truncated': 'boolean', 'success': 'boolean',
        'goal_conditions_met': 'uint32', 'goal_conditions_total': 'uint32'}
    assert OracleAnswer.Request.get_fields_and_field_types() == {
        'question_type': 'string', 'object_noun': 'string'}
    assert OracleAnswer.Response.get_fields_and_field_types() == {
        'valid': 'boolean', 'answer': 'string', 'reason': 'string', 'task_id': 'string'}

    request = SimStep.Request(action=Action(action=Action.PICKUP, x=150, y=200))
    restored = deserialize_message(serialize_message(request), SimStep.Request)
    assert (restored.action.action, restored.action.x, restored.action.y) == ('Pickup', 150, 200)


def test_run_task_action_has_the_documented_goal_result_and_feedback():
    from dialfred_msgs.action import RunTask
    assert RunTask.Goal.get_fields_and_field_types() == {'task_id': 'string', 'seed': 'int64', 'checkpoint': 'string',
                                                         'protocol': 'string', 'carry_on': 'boolean'}
    assert RunTask.Result.get_fields_and_field_types() == {
        'success': 'boolean', 'steps': 'uint32', 'goal_conditions_met': 'uint32', 'goal_conditions_total': 'uint32',
        'failed_actions': 'uint32', 'questions': 'uint32', 'invalid_questions': 'uint32', 'end_reason': 'string',
        'error': 'string', 'last_action': 'string', 'dialogue': 'sequence<dialfred_msgs/QAPair>',
        'actions': 'sequence<dialfred_msgs/Action>', 'asked_at': 'sequence<uint32>'}
    assert RunTask.Feedback.get_fields_and_field_types() == {
        'step': 'uint32', 'action': 'dialfred_msgs/Action', 'action_success': 'boolean', 'questions': 'uint32'}
    # The action's hidden services and topic carry the goal id (action_msgs) with the goal.
    assert 'goal_id' in RunTask.Impl.SendGoalService.Request.get_fields_and_field_types()
    feedback = RunTask.Feedback(step=3, action=Action(action=Action.OPEN, x=10, y=20), questions=2)
    restored = deserialize_message(serialize_message(feedback), RunTask.Feedback)
    assert (restored.step, restored.action.action, restored.action.x, restored.questions) == (3, 'Open', 10, 2)


def test_questioner_ask_carries_task_frame_dialogue_step_and_gap():
    from dialfred_msgs.srv import QuestionerAsk
    assert QuestionerAsk.Request.get_fields_and_field_types() == {
        'task': 'dialfred_msgs/TaskDescription', 'seed': 'int64', 'step': 'uint32', 'rgb': 'sensor_msgs/Image',
        'dialogue': 'sequence<dialfred_msgs/QAPair>', 'confusion_gap': 'double', 'episode': 'string'}
    assert QuestionerAsk.Request().confusion_gap < 0       # unknown unless the performer sends it
    assert QuestionerAsk.Response.get_fields_and_field_types() == {
        'ok': 'boolean', 'error': 'string', 'ask': 'boolean', 'question_type': 'string', 'object_noun': 'string'}
    request = QuestionerAsk.Request(task=TaskDescription(task_id='valid_unseen/000001', object_nouns=['apple']),
                                    step=4, rgb=rgb_image(RGB_4X4), confusion_gap=0.25,
                                    dialogue=[QAPair(question_type=QAPair.LOCATION, object_noun='apple',
                                                     answer='The apple is in the fridge.', valid=True)])
    restored = deserialize_message(serialize_message(request), QuestionerAsk.Request)
    assert restored.dialogue[0].answer == 'The apple is in the fridge.' and restored.confusion_gap == 0.25
    assert bytes(restored.rgb.data) == RGB_4X4.tobytes()
