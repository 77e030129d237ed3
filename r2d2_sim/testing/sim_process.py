"""``sim_node`` in a process of its own, driven through its services: :class:`SimProcess`."""

import json
import signal
import time
from typing import Any, Callable, Dict, Optional, Sequence

from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from r2d2_sim.client import ros_child_env, stamp_ns, twist_message, twist_stamped_message
from r2d2_sim.testing.domains import env_domain_id, lease_domain
from r2d2_sim.testing.executor import HarnessError
from r2d2_sim.testing.process import ChildProcess, parse_ros_args, ProcessResult, sim_node_command
from r2d2_sim.testing.remote import RemoteProbe
from r2d2_sim.testing.standard import StandardClient, StandardError
from r2d2_sim.testing.tf import TransformLookup
from r2d2_sim.testing.world_verbs import StandardWorld, world_error, WorldVerbs

__all__ = ['SimProcess', 'STATUS_RESEND_S']

# SimProcess sends an idempotent query (get_status, get_joint_info) again after
# this long without a reply (wall s); a reply sent before the server had found
# our reply reader is lost. Replies take 0.5-1.5 ms here.
STATUS_RESEND_S = 1.0
STATE_TOPICS = (('joint_states', JointState), ('odom', Odometry), ('ground_truth', Odometry),
                ('/clock', Clock))
SERVICES = (('pause', SetBool), ('step', Trigger), ('reset', Trigger),
            ('get_joint_info', Trigger), ('get_status', Trigger))
TWIST_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'


class ControlServices:
    """
    The node's own control services (``~/pause``, ``~/step``, ``~/reset``, ``~/get_status``...).

    Each reply is the node's JSON state; ``last_status`` and ``paused`` follow
    the replies. The owner gives ``probe``, ``process``, ``node_path``,
    ``timeout_s``, ``_clients`` and ``_not_before_ns``.
    """

    paused = False
    last_status: Dict[str, Any] = {}

    def _request(self, name: str, request, resend_after_s: Optional[float] = None
                 ) -> Dict[str, Any]:
        if self._exited():
            raise HarnessError(f'sim_node has exited (status {self.process.returncode})')
        reply = self.probe.call_client(self._clients[name], request, self.timeout_s,
                                       resend_after_s, abort=self._exited)
        if reply is None:
            raise HarnessError(f'{self.node_path}/{name} did not answer within '
                               f'{self.timeout_s:g} s')
        facts = json.loads(reply.message)
        if name != 'get_joint_info':
            self.last_status = facts
            self.paused = facts['paused']
        if not reply.success:
            raise HarnessError(f'~/{name} failed: {facts.get("error", reply.message)}')
        return facts

    def pause(self, paused: bool = True) -> Dict[str, Any]:
        """Pause (or with False resume) through ``~/pause``; return the reply's JSON state."""
        request = SetBool.Request()
        request.data = paused
        return self._request('pause', request)

    def resume(self) -> Dict[str, Any]:
        """Let simulated time run again; return the reply's JSON state."""
        return self.pause(False)

    def status(self) -> Dict[str, Any]:
        """
        Return the simulator's state without changing it.

        Asks ``~/get_status`` and returns its JSON reply: ``paused``, ``step``,
        ``sim_time_ns``, ``sim_time``, ``commands_received``.
        """
        return self._request('get_status', Trigger.Request(), STATUS_RESEND_S)

    def step(self, count: int = 1) -> Dict[str, Any]:
        """
        Advance a paused simulator ``count`` control periods through ``~/step``.

        Returns the last reply with ``steps``, the physics steps of all the
        calls. Raises HarnessError if it is running (pause it first).
        """
        total = 0
        facts: Dict[str, Any] = {}
        for _ in range(count):
            facts = self._request('step', Trigger.Request())
            total += facts['steps']
        facts['steps'] = total
        return facts

    def reset(self) -> Dict[str, Any]:
        """
        Put the robot back at its initial pose through ``~/reset``; return the reply's JSON.

        The node publishes the reset robot at its next publication: the state
        readers wait for one after the reply's time (while paused, step() first).
        """
        facts = self._request('reset', Trigger.Request())
        self._not_before_ns = facts['sim_time_ns'] + 1
        return facts

    def joint_info(self) -> Dict[str, Any]:
        """Return ``~/get_joint_info``'s JSON: ``robot``, ``urdf`` and ``joints``."""
        return self._request('get_joint_info', Trigger.Request(), STATUS_RESEND_S)


class SimProcess(ControlServices, TransformLookup, WorldVerbs):
    """
    The ``sim_node`` executable in a process of its own, driven through its services.

    ``SimProcess(start_paused=True, publish_rate=20.0)``: keywords other than
    the harness's own are the simulator's ROS parameters; ``ros_args`` are
    appended after ``--ros-args`` (remaps, ``--params-file``). Starts the
    process and returns once it serves its services, its topics are linked
    to this object's node and, unless it starts paused, ``/clock`` arrives.
    Remaps in ``ros_args`` apply to this side too: ``-r __ns:=/a`` is the
    namespace, ``-r /clock:=/a/clock`` moves the clock both sides read.

    The domain: ``domain_id`` if given; else ``ROS_DOMAIN_ID`` if the
    environment sets it and ``use_env_domain`` is true (so your own ROS tools
    see the simulator), else a free one. Either way it is leased, so two
    harnesses on this machine never share it: they take turns instead.
    ``timeout_s`` bounds start-up and every wait (wall clock).
    ``state_subscriptions=False`` leaves out the state subscriptions (a
    benchmark that must not add a subscriber); the state readers then refuse.
    ``lease=False`` uses ``domain_id`` without leasing it (a program, such as
    the demo, that runs on the user's own domain beside whatever holds it).

    Attributes: ``domain_id``, ``node_path`` (the node's fully qualified name,
    under which its ``~/`` services are), ``process`` (a
    :class:`~r2d2_sim.testing.process.ChildProcess`), ``probe`` (the
    :class:`~r2d2_sim.testing.remote.RemoteProbe` whose node you may give
    subscriptions of your own), ``paused`` and ``last_status``.

    With simulation_interfaces installed, ``standard`` is a
    :class:`~r2d2_sim.testing.standard.StandardClient` of its services, and
    the world verbs (``spawn``, ``entity_state``, ``set_entity_state``,
    ``delete_entity``, ``reset_world``, ``step_physics``) go through it.
    """

    def __init__(self, *, node_name: str = 'r2d2_sim', namespace: str = '',
                 domain_id: Optional[int] = None, use_env_domain: bool = True,
                 ros_args: Sequence[str] = (), command: Optional[Sequence[str]] = None,
                 timeout_s: float = 30.0, state_subscriptions: bool = True,
                 lease: bool = True, **parameters: Any) -> None:
        if domain_id is None and use_env_domain:
            domain_id = env_domain_id()
        self.timeout_s = timeout_s
        self.result: Optional[ProcessResult] = None
        self.paused = False
        self.last_status: Dict[str, Any] = {}
        self._not_before_ns = 0  # state readers take no message stamped before (a reset)
        self.process: Optional[ChildProcess] = None
        self.probe: Optional[RemoteProbe] = None
        self._latest: Dict[str, Any] = {topic.lstrip('/'): None for topic, _ in STATE_TOPICS}
        self._subscriptions: Dict[str, Any] = {}
        self._clients: Dict[str, Any] = {}
        self._cmd_vel = None
        self._stamped = False
        self._state_subscriptions = state_subscriptions
        self._standard: Optional[StandardClient] = None
        if lease or domain_id is None:
            self.lease = lease_domain(domain_id, timeout_s=max(timeout_s, 60.0))
            self.domain_id = self.lease.domain_id
        else:
            self.lease, self.domain_id = None, domain_id
        # The node's name and namespace: ours, overridden by remaps in ros_args.
        given = parse_ros_args(ros_args, node_name)
        node_name = given.node_name or node_name
        namespace = given.namespace if given.namespace is not None else namespace
        namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
        self.node_path = f'{namespace}/{node_name}'
        remaps = (['-r', f'__node:={node_name}'] if node_name != 'r2d2_sim' else []) + \
            (['-r', f'__ns:={namespace}'] if namespace else [])
        self.command = sim_node_command(parameters, remaps + list(ros_args), command)
        try:
            self.process = ChildProcess(self.command, ros_child_env(self.domain_id)).start()
            probe_args = [arg for rule in given.remaps for arg in ('-r', rule)]
            self.probe = RemoteProbe(self.domain_id, '_r2d2_sim_process_client',
                                     namespace=namespace or None, ros_args=probe_args)
            self._connect()
            self._wait_ready()
        except BaseException:
            self.stop()
            raise

    def _connect(self) -> None:
        """Create this side's subscriptions and service clients."""
        node = self.probe.node
        if self._state_subscriptions:
            for topic, msg_type in STATE_TOPICS:
                key = topic.lstrip('/')
                self._subscriptions[key] = node.create_subscription(
                    msg_type, topic, self._keeper(key), 1)
        self._clients = {name: node.create_client(srv, f'{self.node_path}/{name}')
                         for name, srv in SERVICES}

    def _keeper(self, key: str) -> Callable[[Any], None]:
        def keep(msg) -> None:
            self._latest[key] = msg
        return keep

    def _exited(self) -> bool:
        return self.process.exited()

    def _cmd_vel_type(self) -> Optional[str]:
        """Return the type the node subscribes ``cmd_vel`` with, once the graph shows it."""
        node = self.probe.node
        for info in node.get_subscriptions_info_by_topic(node.resolve_topic_name('cmd_vel')):
            if info.node_name != node.get_name():
                return info.topic_type
        return None

    def _wait_ready(self) -> None:
        # odom is left out: a robot without wheels has none.
        state = [self._subscriptions[key] for key in ('joint_states', 'ground_truth', 'clock')
                 if key in self._subscriptions]

        def linked():
            return self._exited() or (all(c.service_is_ready() for c in self._clients.values())
                                      and self._cmd_vel_type() is not None
                                      and all(s.get_publisher_count() > 0 for s in state))
        if not self.probe.spin_until(linked, self.timeout_s) or self._exited():
            self._fail_start('did not serve its services')
        # Twist or TwistStamped (enable_stamped_cmd_vel, maybe from a params
        # file): publish what the node takes, which the middleware delivers.
        self._stamped = self._cmd_vel_type() == TWIST_STAMPED_TYPE
        msg_type = type(twist_stamped_message() if self._stamped else twist_message())
        self._cmd_vel = self.probe.node.create_publisher(msg_type, 'cmd_vel', 10)
        if not self.probe.spin_until(
                lambda: self._cmd_vel.get_subscription_count() > 0 or self._exited(),
                self.timeout_s) or self._exited():
            self._fail_start('did not subscribe cmd_vel')
        # Paused or not (start_paused may come from a --params-file). get_status's
        # client is created last: the server learns of our reply readers in the
        # order we made them, so once it answers here it can answer every client.
        self.status()
        if (self._state_subscriptions and not self.paused and not self.probe.spin_until(
                lambda: self._latest['clock'] is not None or self._exited(), self.timeout_s)):
            self._fail_start('published no /clock')

    def _fail_start(self, what: str) -> None:
        if self._exited():
            result = self.stop()
            raise HarnessError(f'sim_node exited with status {result.returncode} while '
                               f'starting: {result.stderr.strip()[-2000:]}')
        raise HarnessError(f'sim_node {what} within {self.timeout_s:g} s')

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *, twist=None) -> None:
        """
        Publish a command on ``cmd_vel`` and return once the simulator has counted it.

        ``linear`` m/s along x and ``angular`` rad/s about z, or a whole
        ``twist`` (a Twist, or a TwistStamped for a node that takes them). A
        node with ``enable_stamped_cmd_vel`` gets a TwistStamped stamped 0
        ("now"). Confirmed through the ``commands_received`` of its services.
        """
        if twist is None:
            twist = twist_message(linear, angular)
        if self._stamped and not hasattr(twist, 'header'):
            twist = twist_stamped_message(twist=twist)
        before = self.status()['commands_received']
        self._cmd_vel.publish(twist)
        deadline = time.monotonic() + self.timeout_s
        while self.status()['commands_received'] <= before:
            if time.monotonic() > deadline:
                raise HarnessError(f'the simulator did not take cmd_vel within '
                                   f'{self.timeout_s:g} s')
            self.probe.spin_until(lambda: False, 0.002)

    def ground_truth(self) -> Odometry:
        """Return the latest ``ground_truth`` (when paused: of the time the last reply gave)."""
        return self._wait_latest('ground_truth')

    def odom(self) -> Odometry:
        """Return the latest ``odom`` (wheel odometry; when paused: of the last reply's time)."""
        return self._wait_latest('odom')

    def joint_states(self) -> JointState:
        """Return the latest ``joint_states`` (when paused: of the time the last reply gave)."""
        return self._wait_latest('joint_states')

    @property
    def standard(self) -> StandardClient:
        """Return the client of the node's simulation_interfaces services (made on first use)."""
        if self._standard is None:
            namespace = self.node_path.rsplit('/', 1)[0]
            self._standard = StandardClient(self.probe.node, self.probe.spin_until, namespace,
                                            self.timeout_s)
        return self._standard

    def _world_backend(self) -> StandardWorld:
        return StandardWorld(self.standard)

    def _after_reset(self) -> None:
        """Make the readers wait for the reset world, published at the next publication."""
        facts = self.status()
        self._not_before_ns = facts['sim_time_ns'] + 1
        for key in self._latest:
            self._latest[key] = None

    def step_physics(self, steps: int) -> Dict[str, Any]:
        """
        Step a paused simulator ``steps`` physics steps (step_simulation); return its status.

        Raises WorldError (OPERATION_FAILED) while the simulator is playing.
        """
        try:
            self.standard.step(steps)
        except StandardError as exc:
            raise world_error(exc) from None
        self._not_before_ns = 0
        return self.status()

    def _tf_node(self):
        return self.probe.node

    def _tf_wait(self, condition) -> bool:
        return self.probe.spin_until(condition, self.timeout_s)

    def _wait_latest(self, key: str):
        """
        Paused: wait for the message stamped with the last reply's time. Running: the newest.

        A paused simulator has published its state at the time its last reply
        gives (pause lands on a publication, a step ends with one).
        """
        if not self._state_subscriptions:
            raise HarnessError(f'no {key}: this SimProcess was made with '
                               'state_subscriptions=False')
        if not (self.paused and self.last_status):
            self.status()  # running: wait for what is published from now on
        wanted = self.last_status['sim_time_ns']
        if self.paused and wanted < self._not_before_ns:
            raise HarnessError(f'no {key} yet: the reset robot is published at the next '
                               'publication; step() first')
        floor = max(wanted, self._not_before_ns)

        def arrived():
            msg = self._latest[key]
            if msg is None:
                return False
            stamp = stamp_ns(msg.header.stamp)
            return stamp == wanted if self.paused else stamp >= floor
        if not self.probe.spin_until(arrived, self.timeout_s):
            hint = (': a simulator that started paused has published nothing since this '
                    'client connected; step() it first'
                    if self.paused and self.last_status.get('step') == 0 else '')
            raise HarnessError(f'no {key} of t={wanted / 1e9:.6f} s within '
                               f'{self.timeout_s:g} s{hint}')
        return self._latest[key]

    def stop(self, timeout_s: float = 10.0) -> ProcessResult:
        """
        Stop the simulator with SIGINT (SIGKILL after ``timeout_s``); return how it ended.

        Also closes this object's node and releases the domain. Safe to call
        twice: later calls return the first result.
        """
        if self.result is not None:
            return self.result
        try:
            if self.process is not None:
                self.result = self.process.stop(signal.SIGINT, timeout_s)
            else:
                self.result = ProcessResult(-1, '', '')
        finally:
            if self.probe is not None:
                self.probe.close()
            if self.lease is not None:
                self.lease.release()
        return self.result

    def __enter__(self) -> 'SimProcess':
        return self

    def __exit__(self, *exc_info) -> None:
        self.stop()
