"""
The real sim_node's parameters as ``ros2 param dump`` reads them, from another process.

The same read in process, and why every parameter must hold a typed value,
are ros/test_parameter_services.py's.
"""

from helpers import (
    _check_all, _read_everything, next_domain_id, start_sim_process, stop_process)
from rcl_interfaces.msg import ParameterType

from r2d2_sim.testing import RemoteProbe


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
