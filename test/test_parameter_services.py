"""
The node's parameters as ``ros2 param dump``, ``ros2 param describe`` and rqt read them.

Those tools call ``list_parameters``, then ``get_parameters`` with every name
listed, from another process. rclpy answers a GetParameters request with no
values at all when one name in it is declared without a value, so every
declared parameter must hold a typed value, empty lists included.
"""

import math

from helpers import make_sim, next_domain_id, start_sim_process, stop_process
import pytest
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import (
    DescribeParameters, GetParameters, GetParameterTypes, ListParameters, SetParameters)
from rclpy.parameter import Parameter, parameter_value_to_python

from r2d2_sim.sim.parameters import PARAMETERS, PARAMETERS_BY_NAME
from r2d2_sim.ros.parameters import ROS_TYPES
from r2d2_sim.testing import RemoteProbe

NODE = '/r2d2_sim'
TIMEOUT_S = 20.0


def _read_everything(probe):
    """Return {name: (ParameterValue, ParameterDescriptor)} the way ros2 param dump gets it."""
    listed = probe.call(ListParameters, f'{NODE}/list_parameters', ListParameters.Request(),
                        TIMEOUT_S, resend_after_s=2.0)
    names = list(listed.result.names)
    values = probe.call(GetParameters, f'{NODE}/get_parameters',
                        GetParameters.Request(names=names), TIMEOUT_S, resend_after_s=2.0)
    assert len(values.values) == len(names), (
        f'get_parameters returned {len(values.values)} values for {len(names)} names')
    types = probe.call(GetParameterTypes, f'{NODE}/get_parameter_types',
                       GetParameterTypes.Request(names=names), TIMEOUT_S, resend_after_s=2.0)
    assert len(types.types) == len(names)
    described = probe.call(DescribeParameters, f'{NODE}/describe_parameters',
                           DescribeParameters.Request(names=names), TIMEOUT_S,
                           resend_after_s=2.0)
    assert len(described.descriptors) == len(names)
    for name, value, type_ in zip(names, values.values, types.types):
        assert value.type == type_, name
    return {name: (value, descriptor)
            for name, value, descriptor in zip(names, values.values, described.descriptors)}


def _expected(name, overrides):
    """Return the value the node should report: the override, else the table's default."""
    spec = PARAMETERS_BY_NAME[name]
    value = overrides.get(name, spec.default)
    if spec.ros_type == 'double':
        return float(value)
    if spec.ros_type.endswith('_array'):
        return list(value)
    return value


def _check_all(read, overrides=None):
    overrides = overrides or {}
    assert set(PARAMETERS_BY_NAME) <= set(read), set(PARAMETERS_BY_NAME) - set(read)
    for spec in PARAMETERS:
        value, descriptor = read[spec.name]
        assert value.type == ROS_TYPES[spec.ros_type].value, (
            f'{spec.name}: type {value.type}, expected {spec.ros_type}')
        assert value.type != ParameterType.PARAMETER_NOT_SET, spec.name
        got = parameter_value_to_python(value)
        if spec.ros_type.endswith('_array'):
            got = list(got)
        assert got == _expected(spec.name, overrides), spec.name
        assert descriptor.type == value.type, spec.name
        assert descriptor.read_only, spec.name
        assert descriptor.description == spec.description, spec.name
        bounds = spec.bounds
        if spec.ros_type == 'double' and bounds is not None and bounds.zero is None:
            (fp,) = descriptor.floating_point_range
            assert math.isclose(fp.from_value, bounds.low) and \
                math.isclose(fp.to_value, bounds.high), spec.name
        if spec.ros_type == 'integer' and bounds is not None and bounds.zero is None:
            (ir,) = descriptor.integer_range
            assert (ir.from_value, ir.to_value) == (bounds.low, bounds.high), spec.name
    assert read['use_sim_time'][0].type == ParameterType.PARAMETER_BOOL


def test_sim_node_answers_get_parameters_for_every_listed_name():
    """The real executable: list, then get every name, from another process; all typed."""
    domain = next_domain_id()
    process = start_sim_process(domain)
    probe = RemoteProbe(domain, 'param_dump')
    try:
        read = _read_everything(probe)
    finally:
        probe.close()
        code, out, err = stop_process(process)
    assert code == 0 and 'Traceback' not in err, err
    _check_all(read)
    value, _ = read['extra_models']
    assert value.type == ParameterType.PARAMETER_STRING_ARRAY
    assert list(value.string_array_value) == []


@pytest.mark.parametrize('overrides', [
    {'urdf': 'cube.urdf', 'left_wheel_names': [], 'right_wheel_names': [],
     'extra_models': []},
    {'extra_models': ['cube.urdf 3 0 0.5'], 'physics_rate': 120, 'gravity': [0, 0, -9]},
], ids=['empty_lists', 'set_lists'])
def test_every_parameter_reads_back_typed_over_dds(ros, overrides):
    """A node in another context on the same domain reads every value with its table type."""
    make_sim(ros, **overrides)
    with RemoteProbe(ros.domain_id, 'param_dump') as probe:
        read = _read_everything(probe)
    _check_all(read, {name: ([float(v) for v in value] if name == 'gravity' else value)
                      for name, value in overrides.items()})


def test_parameters_stay_read_only_after_start(ros):
    """Setting a parameter over the service is refused, empty lists included."""
    make_sim(ros)
    request = SetParameters.Request(parameters=[
        Parameter('extra_models', Parameter.Type.STRING_ARRAY, ['cube.urdf 0 0 1'])
        .to_parameter_msg(),
        Parameter('physics_rate', Parameter.Type.DOUBLE, 100.0).to_parameter_msg()])
    with RemoteProbe(ros.domain_id, 'param_set') as probe:
        response = probe.call(SetParameters, f'{NODE}/set_parameters', request, TIMEOUT_S)
    assert [r.successful for r in response.results] == [False, False]
    assert all('read-only' in r.reason for r in response.results), response.results
