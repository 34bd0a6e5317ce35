"""Node parameters take only sensible values: each has a description and a range or choices, a node
started with a bad one exits with one line naming it, and a running node refuses a bad change (NaN,
infinity, out of range, a read-only parameter) with the reason and keeps its value."""

from __future__ import annotations

import math
import subprocess

import pytest

from dialfred_bringup.graph import Graph, NodeProcess, resolve_executable, use_project_environment
from dialfred_bringup.paths import REPO
from dialfred_sim.ros_util import Param

use_project_environment(REPO)


def test_a_param_says_what_is_wrong_with_a_value():
    p = Param('request_timeout', 60.0, 'seconds', span=(0.1, 100.0))
    assert p.problem(5.0) is None
    assert 'finite' in p.problem(math.nan) and 'finite' in p.problem(math.inf)
    assert 'must be in [0.1, 100.0]' in p.problem(0.0)
    assert 'takes a float' in p.problem('5')
    c = Param('record_format', 'raw', 'frames', choices=('raw', 'png'))
    assert c.problem('png') is None and 'must be one of' in c.problem('gif')
    assert Param('questioner', False, 'ask').problem(1) == "questioner takes a bool, got 1"


@pytest.mark.parametrize('package, parameter, value, said', [
    ('dialfred_performer', 'request_timeout', 'nan', 'request_timeout'),
    ('dialfred_performer', 'record_format', 'gif', "record_format must be one of 'raw', 'png', 'jpeg'"),
    ('dialfred_sim', 'resolution', '5', 'resolution'),
    ('dialfred_sim', 'max_steps', '0', 'max_steps'),
    ('dialfred_oracle', 'perturb_probability', '1.5', 'perturb_probability'),
    ('dialfred_oracle', 'perturb_type', 'colour', "perturb_type must be one of"),
    ('dialfred_questioner', 'epsilon', 'inf', 'epsilon'),
    ('dialfred_questioner', 'torch_threads', '0', 'torch_threads'),
])
def test_a_node_started_with_a_bad_parameter_exits_naming_it(package, parameter, value, said):
    done = subprocess.run([str(resolve_executable(package, 'node')), '--ros-args', '-p', f'{parameter}:={value}'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stdout + done.stderr
    assert said in done.stderr and 'Traceback' not in done.stderr, done.stderr


def test_a_running_node_refuses_a_bad_change_and_keeps_its_value():
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
    with Graph([NodeProcess('dialfred_performer', {'checkpoint': "''"}, namespace='/params')]) as graph:
        node = '/params/dialfred_performer'
        set_cli = graph.client(SetParameters, f'{node}/set_parameters')
        get_cli = graph.client(GetParameters, f'{node}/get_parameters')
        describe = graph.call(graph.client(DescribeParameters, f'{node}/describe_parameters'),
                              DescribeParameters.Request(names=['request_timeout', 'max_questions', 'checkpoint']))
        timeout_d, questions_d, checkpoint_d = describe.descriptors
        assert timeout_d.floating_point_range[0].from_value == 0.1 and not timeout_d.read_only and timeout_d.description
        assert questions_d.integer_range[0].to_value == 1000 and checkpoint_d.read_only

        def set_value(name, value):
            if isinstance(value, float):
                v = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
            elif isinstance(value, int):
                v = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
            else:
                v = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
            return graph.call(set_cli, SetParameters.Request(parameters=[Parameter(name=name, value=v)])).results[0]

        for name, value in [('request_timeout', math.nan), ('request_timeout', math.inf), ('request_timeout', -1.0),
                            ('max_questions', 0), ('checkpoint', '/tmp/other.pt')]:
            result = set_value(name, value)
            assert not result.successful and result.reason, (name, value)
        values = graph.call(get_cli, GetParameters.Request(names=['request_timeout', 'max_questions'])).values
        assert (values[0].double_value, values[1].integer_value) == (60.0, 20)          # unchanged
        assert set_value('request_timeout', 30.0).successful                             # a good change is taken
        assert graph.call(get_cli, GetParameters.Request(names=['request_timeout'])).values[0].double_value == 30.0
        graph.check()
