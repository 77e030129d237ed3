"""
Without the interface build (tf2_msgs, simulation_interfaces), the testing API says so in one line.

A new user's pip-only venv, ``tools/build_interfaces.sh`` not run (the README
calls it optional): ``lookup_transform`` raised a bare ``ModuleNotFoundError``
from inside the TF listener, five frames deep. Now the verb raises
:class:`~r2d2_sim.testing.MissingInterfaceError` (a HarnessError) naming the
package and the build. The import is made to fail (``None`` in ``sys.modules``),
nothing is uninstalled.
"""

import pytest

from common import assert_says_build, block_package
from r2d2_sim.testing import HarnessError


@pytest.mark.parametrize('package', ['tf2_msgs', 'simulation_interfaces'])
def test_import_interface_names_the_package_and_the_build(monkeypatch, package):
    from r2d2_sim.testing.executor import import_interface
    block_package(monkeypatch, package)
    with pytest.raises(HarnessError) as error:
        import_interface(package + '.msg', 'my_verb')
    assert_says_build(error, package)
    assert 'my_verb' in str(error.value)


def test_a_harness_lookup_without_tf2_msgs_says_what_to_build(r2d2_sim, monkeypatch):
    """The in-process harness listens from its first lookup: that lookup says it."""
    block_package(monkeypatch, 'tf2_msgs')
    for verb in (lambda: r2d2_sim.lookup_transform('odom', 'base_link'), r2d2_sim.listen_tf,
                 lambda: r2d2_sim.robot().lookup_transform('odom', 'base_link')):
        with pytest.raises(HarnessError) as error:
            verb()
        assert_says_build(error, 'tf2_msgs')
        assert 'lookup_transform' in str(error.value)
    r2d2_sim.advance(seconds=0.1)  # everything else works
