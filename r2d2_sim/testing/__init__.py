"""
Testing code against the simulator: harnesses, deadline waits, ROS domains, processes.

Names you need (a guide with examples: ``docs/testing.md``; every name:
``docs/api/testing.md``):

- Fixtures (:mod:`r2d2_sim.pytest_plugin`; an installed r2d2_sim loads it,
  a source tree needs ``pytest_plugins = ['r2d2_sim.pytest_plugin']``):
  ``r2d2_sim``, a ready SimHarness; ``r2d2_sim_parameters``, override it to
  set the simulator's parameters; ``r2d2_sim_factory(**parameters)``, more
  harnesses; ``r2d2_sim_process(**parameters)``, a SimProcess.
- :class:`SimHarness`: the simulator in the test's process; time moves only
  in ``advance(seconds=...)``; ``send_cmd_vel``, ``ground_truth()``,
  ``odom()``, ``joint_states()``; ``create_node`` for your own nodes.
- :class:`SimProcess`: ``sim_node`` in a process of its own, driven through
  its services (``step``, ``pause``, ``reset``; ``standard`` is its
  :class:`StandardClient`).
- Both: ``spawn``, ``set_entity_state``, ``entity_state``, ``delete_entity``,
  ``load_world``, ``named_pose``, ``reset_world``; ``robot(name)`` for one
  robot of several.
- Errors: :class:`RefusedError` (the simulator refused; ``code`` as the
  standard names it), :class:`StandardError` (a standard service's answer),
  :class:`HarnessError` (the harness: a deadline, no world loaded; its
  :class:`MissingInterfaceError`: tf2_msgs or simulation_interfaces not built),
  :class:`StartupError` (parameters it cannot start with).
- Your own processes: :func:`lease_domain` (a ROS domain no other test
  uses), :func:`ros_child_env` (their environment); :func:`wait_for`
  (a deadline, never a sleep).

:class:`SimHarness` runs the simulator inside the test's process, in an rclpy
context of its own, and moves simulated time only when told (``advance``).
:class:`SimProcess` runs the ``sim_node`` executable in a process of its own
and drives it through its services. Each gets a ROS domain that no other
harness on this machine uses (:func:`lease_domain`), so tests can run in
parallel (``pytest -n auto``). The pytest fixtures built on these are in
:mod:`r2d2_sim.pytest_plugin`; this package needs no pytest.

The package, by role: :mod:`~r2d2_sim.testing.domains` (domain leases),
:mod:`~r2d2_sim.testing.executor` (a context and an executor the caller can
take over), :mod:`~r2d2_sim.testing.lockstep` (the executor that makes runs
repeat bit for bit), :mod:`~r2d2_sim.testing.harness` (:class:`SimHarness`),
:mod:`~r2d2_sim.testing.remote` (:class:`RemoteProbe`),
:mod:`~r2d2_sim.testing.process` (child processes),
:mod:`~r2d2_sim.testing.sim_process` (:class:`SimProcess`),
:mod:`~r2d2_sim.testing.robots` (one robot's handle in either harness),
:mod:`~r2d2_sim.testing.world_verbs` (spawn, place, read, delete, reset, load
worlds, named poses, entity info and bounds, and the records they return),
:mod:`~r2d2_sim.testing.scenery` (a scan's range at an angle; boxes to spawn are the
core's :func:`~r2d2_sim.sim.spawnables.box_urdf`),
:mod:`~r2d2_sim.testing.standard` (a client of ROS 2's simulation standard for
any simulator), :mod:`~r2d2_sim.testing.tf` (``lookup_transform`` over
``/tf``, as tf2 does), :mod:`~r2d2_sim.testing.recordings` (a recording
read into typed messages per topic) and :mod:`~r2d2_sim.testing.live_view` (a
Foxglove WebSocket client of the live view). Every public name is importable
from here.
"""

from typing import Any

from r2d2_sim import deprecations
from r2d2_sim.client import (
    Pose2D, pose_from_odometry, ros_child_env, spin_until, stamp_ns, wait_for)
from r2d2_sim.errors import RefusedError, StartupError
from r2d2_sim.model.tf_buffer import StampedTransform, TransformBuffer, TransformException
from r2d2_sim.model.transforms import BaseState
from r2d2_sim.sim.spawnables import box_urdf
from r2d2_sim.testing import domains
from r2d2_sim.testing.domains import (
    DOMAIN_LOCK_DIR_ENV, DomainLease, domain_lock_dir, DomainUnavailable, lease_domain)
from r2d2_sim.testing.executor import (
    CallbackError, HarnessError, MissingInterfaceError, parameter_overrides, RosHarness,
    SPIN_POLL_S)
from r2d2_sim.testing.harness import LINK_NODE_NAME, SimHarness
from r2d2_sim.testing.live_view import LiveMessage, LiveViewClient, LiveViewError
from r2d2_sim.testing.process import (
    ChildProcess, ProcessResult, sim_node_command, stop_process)
from r2d2_sim.testing.recordings import read_recording, RecordedMessage, RecordingError
from r2d2_sim.testing.remote import RemoteProbe
from r2d2_sim.testing.scenery import scan_range
from r2d2_sim.testing.sim_process import SimProcess, STATUS_RESEND_S
from r2d2_sim.testing.standard import StandardClient, StandardError
from r2d2_sim.testing.tf import TfListener
from r2d2_sim.testing.world_verbs import EntityInfo, NamedPose, Region, WorldEntry

__all__ = [
    'SimHarness', 'SimProcess', 'RosHarness', 'RemoteProbe', 'ChildProcess',
    'HarnessError', 'CallbackError', 'MissingInterfaceError', 'StartupError',
    'DomainUnavailable', 'DomainLease',
    'lease_domain', 'domain_lock_dir', 'DOMAIN_IDS', 'DOMAIN_LOCK_DIR_ENV',
    'ProcessResult', 'stop_process', 'sim_node_command', 'parameter_overrides',
    'Pose2D', 'pose_from_odometry', 'spin_until', 'wait_for', 'ros_child_env', 'stamp_ns',
    'LINK_NODE_NAME', 'SPIN_POLL_S', 'STATUS_RESEND_S', 'TfListener', 'TransformBuffer',
    'StampedTransform', 'TransformException', 'StandardClient', 'StandardError', 'BaseState',
    'RefusedError', 'box_urdf', 'scan_range', 'read_recording', 'RecordedMessage',
    'RecordingError', 'LiveViewClient', 'LiveMessage', 'LiveViewError',
    'NamedPose', 'WorldEntry', 'EntityInfo', 'Region',
]


def __getattr__(name: str) -> Any:
    # DOMAIN_IDS follows R2D2_SIM_DOMAIN_IDS as it is when asked, not at import.
    if name == 'DOMAIN_IDS':
        return domains.domain_ids()
    # A name renamed here (WorldError...) works, warning, until deprecations.REMOVED_IN.
    return deprecations.renamed(__name__, name)
