"""`protocol.Observation`: what an agent is given, typed and made in one place per path, and the optional
capabilities of agents and questioners as `Protocol` classes.

Claims: the graph's Observation message and the local `EnvServer` give the same `protocol.Observation`
for the same state (frames, pose, hand, the last action's outcome, counts); an image the simulator was
asked not to send is None; a malformed frame is refused with the reason; `as_observation` takes an
Observation or a bare frame and refuses anything else (a dict, a message), saying what it got; the
capability protocols classify the built-in agents and questioners as their docs say; and no module of
src/ or examples/ probes an agent, a questioner, a performer, a policy or an observation with
getattr / hasattr, or reads an observation as a dict.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from std_msgs.msg import Header

from dialfred_msgs.msg import Observation as ObservationMsg
from dialfred_msgs.srv import SimReset, SimStep
from dialfred_oracle.in_process import EnvServer
from dialfred_questioner.baselines import AllQuestioner, ModelConfusionQuestioner, RandomQuestioner
from dialfred_sim.agents import ExpertAgent, RandomAgent
from dialfred_sim.env import DialfredEnv
from dialfred_sim.episode import RESET, Step
from dialfred_sim.messages import observation_from_msg, sim_reply
from dialfred_sim.protocol import (ConfusionSource, GapQuestioner, Listener, MapPainter, Observation, PerformerAware,
                                   Privileged, as_observation, fill_image, is_privileged)
from dialfred_sim.tasks.split_files import load_split

REPO = Path(__file__).resolve().parents[2]


def message_of(observation: Observation, with_depth: bool = True) -> ObservationMsg:
    """The Observation message the simulator node would send for `observation` (its fill_image path)."""
    msg, header = ObservationMsg(), Header(frame_id='camera')
    fill_image(msg.rgb, observation.rgb, 'rgb8', header)
    if with_depth:
        fill_image(msg.depth, observation.depth, '32FC1', header)
        fill_image(msg.segmentation, observation.segmentation, '32SC1', header)
    msg.pose.x, msg.pose.y, msg.pose.rotation_deg, msg.pose.horizon_deg = observation.pose
    msg.held_object, msg.last_action_error = observation.held_object, observation.last_action_error
    msg.last_action_success = observation.last_action_success
    msg.step_count, msg.failed_actions = observation.step_count, observation.failed_actions
    return msg


@pytest.fixture(scope='module')
def played():
    """The local server's observations of a valid_unseen task: after the reset and after two actions, one
    of which fails (a Pickup of the floor)."""
    task = load_split('valid_unseen')[0]
    env = DialfredEnv(resolution=32)
    serve = EnvServer(env, task)
    replies = [serve(RESET), serve(Step('RotateLeft', -1, -1)), serve(Step('Pickup', 16, 31))]
    env.close()
    return replies


def test_the_local_server_gives_typed_observations(played):
    reset, turned, failed = (r.observation for r in played)
    assert all(isinstance(o, Observation) for o in (reset, turned, failed))
    assert reset.rgb.shape == (32, 32, 3) and reset.depth.shape == (32, 32) and reset.segmentation.dtype == np.int32
    assert (reset.step_count, turned.step_count, failed.step_count) == (0, 1, 2)
    assert turned.last_action_success and not failed.last_action_success and failed.last_action_error
    assert failed.failed_actions == 1 == played[2].failed_actions
    assert (turned.pose[2] - reset.pose[2]) % 360 == 90           # RotateLeft: counter-clockwise
    assert reset.pose[3] == 30                                    # the start pitch, 30 degrees down


def test_the_graph_message_gives_the_same_observation(played):
    for reply in played:
        local = reply.observation
        msg = observation_from_msg(message_of(local))
        assert np.array_equal(msg.rgb, local.rgb) and np.array_equal(msg.depth, local.depth)
        assert np.array_equal(msg.segmentation, local.segmentation)
        rest = ('pose', 'held_object', 'last_action_success', 'last_action_error', 'step_count', 'failed_actions')
        assert [getattr(msg, k) for k in rest] == [getattr(local, k) for k in rest]
        without = observation_from_msg(message_of(local, with_depth=False))
        assert without.depth is None and without.segmentation is None and np.array_equal(without.rgb, local.rgb)


def test_a_sim_reply_carries_the_typed_observation_and_the_message(played):
    local = played[1].observation
    response = SimStep.Response(ok=True, observation=message_of(local), goal_conditions_total=2)
    reply = sim_reply(response)
    assert isinstance(reply.observation, Observation) and reply.raw is response
    assert np.array_equal(reply.observation.rgb, local.rgb) and reply.step_count == 1
    refused = sim_reply(SimReset.Response(ok=False, error='unknown task'))
    assert refused.observation is None and not refused.ok and refused.error == 'unknown task'


def test_a_malformed_frame_is_refused_with_the_reason(played):
    msg = message_of(played[0].observation)
    msg.rgb.data = msg.rgb.data[:-3]
    with pytest.raises(ValueError, match='bytes of data'):
        observation_from_msg(msg)
    msg = message_of(played[0].observation)
    msg.rgb.encoding = '32FC1'
    with pytest.raises(ValueError, match='expected an rgb8 image'):
        observation_from_msg(msg)


def test_as_observation_takes_an_observation_or_a_frame_and_nothing_else(played):
    obs = played[0].observation
    assert as_observation(obs) is obs
    assert np.array_equal(as_observation(obs.rgb).rgb, obs.rgb) and as_observation(obs.rgb).last_action_success
    for bad, said in (({'rgb': obs.rgb}, 'dict'), (obs.rgb.astype(np.float32), 'float32 array'),
                      (obs.depth, 'shape \\(32, 32\\)'), (None, 'NoneType')):
        with pytest.raises(ValueError, match=said):
            as_observation(bad)
    with pytest.raises(ValueError, match='HxWx3 uint8'):
        Observation(rgb=obs.depth)


def test_the_capability_protocols_classify_the_built_in_agents_and_questioners():
    expert, random_agent = ExpertAgent(), RandomAgent()
    assert is_privileged(expert) and is_privileged(ExpertAgent) and isinstance(expert, Privileged)
    assert not is_privileged(random_agent) and not is_privileged(object())
    assert isinstance(random_agent, ConfusionSource) and not isinstance(expert, ConfusionSource)
    assert not isinstance(expert, (Listener, MapPainter))
    confusion = ModelConfusionQuestioner()
    assert isinstance(confusion, PerformerAware) and isinstance(confusion, GapQuestioner) and confusion.needs_gap
    for q in (RandomQuestioner(), AllQuestioner()):
        assert isinstance(q, Listener) and not isinstance(q, (GapQuestioner, PerformerAware))
    with pytest.raises(ValueError, match='action_probabilities'):
        confusion.attach(expert)
    with pytest.raises(ValueError, match='top-2 gap'):
        confusion.ask_given_gap(None, 0, None)


# getattr / hasattr with an agent, questioner, performer, policy or observation as the object probed
PROBE = re.compile(r'\b(?:get|has)attr\(\s*(?:self\.)?(?:agent|questioner|performer|policy|observation|obs)\b')
DICT_READ = re.compile(r'\bobservation\[')


def test_no_module_probes_agents_questioners_or_observations():
    found = []
    for path in sorted([*(REPO / 'src').rglob('*.py'), *(REPO / 'examples').rglob('*.py'),
                        *(REPO / 'benchmarks').rglob('*.py')]):
        if 'build' in path.parts or 'install' in path.parts:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if PROBE.search(line) or DICT_READ.search(line):
                found.append(f'{path.relative_to(REPO)}:{n}: {line.strip()}')
    assert not found, 'probing instead of the protocol classes:\n' + '\n'.join(found)
