"""
The node's parameters as ``ros2 param dump``, ``ros2 param describe`` and rqt read them.

Those tools call ``list_parameters``, then ``get_parameters`` with every name
listed, from another process. rclpy answers a GetParameters request with no
values at all when one name in it is declared without a value, so every
declared parameter must hold a typed value, empty lists included.

Here a node in another context of this process reads them; the real
executable is read in system/test_parameter_services_system.py. How both
read and check (``_read_everything``, ``_check_all``) is in helpers.py.
"""

from helpers import _check_all, _read_everything, make_sim, NODE, TIMEOUT_S
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from r2d2_sim.testing import RemoteProbe


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
