"""The sim_node executable's ``main``, called in this process (its processes: system/)."""

from common import _check_help
from r2d2_sim.apps.sim_node import main


def test_sim_node_help_names_the_executable(capsys):
    """sim_node --help, as its console script calls main: no ROS started, usage names sim_node."""
    assert main(['/usr/lib/r2d2_sim/sim_node', '--help']) == 0
    out, err = capsys.readouterr()
    assert err == ''
    _check_help(out, 'sim_node')
