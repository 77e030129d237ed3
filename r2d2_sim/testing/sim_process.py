"""``sim_node`` in a process of its own, driven through its services: :class:`SimProcess`."""

import json
import signal
from typing import Any, Callable, Dict, List, NoReturn, Optional, Sequence

from rclpy.client import Client
from rclpy.node import Node
from rclpy.qos import qos_check_compatible, QoSCompatibility
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool, Trigger

from r2d2_sim.client import ros_child_env, stamp_ns, step_count
from r2d2_sim.errors import StartupError
from r2d2_sim.testing.domains import (
    DomainLease, DomainUnavailable, env_domain_id, held_here, lease_domain)
from r2d2_sim.testing.executor import check_timeout, HarnessError
from r2d2_sim.testing.process import ChildProcess, parse_ros_args, ProcessResult, sim_node_command
from r2d2_sim.testing.remote import ask_until, RemoteProbe
from r2d2_sim.testing.robots import (
    expected_namespaces, FirstRobot, RemoteRobot, simulator_parameters)
from r2d2_sim.testing.standard import StandardClient
from r2d2_sim.testing.tf import TransformLookup
from r2d2_sim.testing.world_verbs import StandardWorld, WorldVerbs

__all__ = ['SimProcess', 'ProcessStartupError', 'STATUS_RESEND_S', 'matchable_readers']

# SimProcess sends an idempotent query (get_status, get_joint_info) again after
# this long without a reply (wall s); a reply sent before the server had found
# our reply reader is lost. Replies take 0.5-1.5 ms here.
STATUS_RESEND_S = 1.0
SERVICES = (('pause', SetBool), ('step', Trigger), ('reset', Trigger), ('get_readers', Trigger),
            ('get_status', Trigger))


def matchable_readers(node: Node, topic: str, writer: str) -> int:
    """
    Return how many subscriptions of ``topic`` the writers of node ``writer`` can all match.

    As ``node`` sees the graph: those whose message type is the writers' and
    whose QoS each writer's offer fits (a transient-local reader of a
    volatile topic is never matched). With no such writer seen yet, ``node``'s
    own subscriptions of the topic. The writers of ``writer``'s outputs process
    (``outputs_process``: node ``WRITER_outputs``) count as its own.
    """
    writers = [info for info in node.get_publishers_info_by_topic(topic)
               if info.node_name in (writer, f'{writer}_outputs')]
    if not writers:
        return sum(1 for s in node.subscriptions if s.topic_name == topic)
    return sum(1 for reader in node.get_subscriptions_info_by_topic(topic)
               if all(reader.topic_type == w.topic_type and qos_check_compatible(
                   w.qos_profile, reader.qos_profile)[0] != QoSCompatibility.ERROR
                      for w in writers))


class ProcessStartupError(HarnessError, StartupError):
    """
    sim_node refused its parameters or files (exit status 2): its one line.

    A :class:`StartupError`, as the in-process harness raises for the same
    mistake, and a :class:`HarnessError`, as every other failed start.
    """


class SimProcess(FirstRobot, TransformLookup, WorldVerbs):
    """
    The ``sim_node`` executable in a process of its own, driven through its services.

    ``SimProcess(start_paused=True, publish_rate=20.0)``: keywords other than
    the harness's own are the simulator's ROS parameters (None: left at the
    node's default, so ``record=None`` records nothing); ``ros_args`` are
    appended after ``--ros-args`` (remaps, ``--params-file``). Starts the
    process and returns once it serves its services, the topics of every
    robot its ``~/get_status`` lists (wherever a params file put them) are
    linked to this object's node and, unless it starts paused, ``/clock`` arrives.
    Remaps in ``ros_args`` apply to this side too: ``-r __ns:=/a`` is the
    namespace, ``-r /clock:=/a/clock`` moves the clock both sides read.

    The domain: ``domain_id`` if given; else ``ROS_DOMAIN_ID`` if the
    environment sets it and ``use_env_domain`` is true (so your own ROS tools
    see the simulator), else a free one. Either way it is leased, so two
    harnesses on this machine never share it: they take turns instead (a
    second one on ``ROS_DOMAIN_ID`` while this process holds it is refused at
    once with DomainUnavailable: pass ``use_env_domain=False``). The
    simulator inherits the lease and ends with this process: should this
    process die without ``stop()`` (SIGKILL), the domain stays leased until
    the simulator has stopped too.
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
            if domain_id is not None and lease and held_here(domain_id):
                # Waiting could never end: the holder is this test's own harness.
                raise DomainUnavailable(
                    f'ROS_DOMAIN_ID {domain_id} is leased by another harness of this process '
                    '(a SimProcess started before, not stopped): pass use_env_domain=False '
                    'for a free domain, or stop the other first')
        self.timeout_s = check_timeout(timeout_s)
        self.result: Optional[ProcessResult] = None
        self.paused = False
        self.last_status: Dict[str, Any] = {}
        self._not_before_ns = 0  # state readers take no message stamped before (a reset)
        # The simulator's process and this side's node: both made below, or the constructor
        # raises (having stopped what it had started).
        self.process: ChildProcess
        self.probe: RemoteProbe
        self._clock: Optional[Clock] = None
        self._clock_subscription: Optional[Subscription] = None
        self._clients: Dict[str, Client] = {}
        self._robots: Dict[str, RemoteRobot] = {}  # by name, once the node has said
        self._pending: List[RemoteRobot] = []  # made before the node says their names
        self._state_subscriptions = state_subscriptions
        # Refused here, before a process starts: the node would only warn of a name
        # it does not read, in a log nobody reads, and run on the default.
        parameters = simulator_parameters(parameters, ProcessStartupError)
        self._standard: Optional[StandardClient] = None
        # The node's name and namespace: ours, overridden by remaps in ros_args. The
        # command is built before the domain is leased: a mistake in it leases nothing.
        if isinstance(ros_args, (str, bytes)) or not all(
                isinstance(arg, str) for arg in (ros_args or ())):
            raise ProcessStartupError(f'ros_args must be a list of strings, got {ros_args!r:.60}')
        ros_args = list(ros_args or ())
        given = parse_ros_args(ros_args, node_name)
        node_name = given.node_name or node_name
        namespace = given.namespace if given.namespace is not None else namespace
        namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
        self.node_path = f'{namespace}/{node_name}'
        remaps = (['-r', f'__node:={node_name}'] if node_name != 'r2d2_sim' else []) + \
            (['-r', f'__ns:={namespace}'] if namespace else [])
        self.command = sim_node_command(parameters, remaps + ros_args, command)
        self.lease: Optional[DomainLease]  # None: lease=False, the caller's own domain
        if lease or domain_id is None:
            self.lease = lease_domain(domain_id, timeout_s=max(self.timeout_s, 60.0))
            self.domain_id = self.lease.domain_id
        else:
            self.lease, self.domain_id = None, domain_id
        process: Optional[ChildProcess] = None
        probe: Optional[RemoteProbe] = None
        try:
            # The simulator holds the lease too: should this process die without
            # stop(), the domain stays leased until the simulator has ended as well.
            inherited = self.lease.fds if self.lease is not None else ()
            process = self.process = ChildProcess(self.command, ros_child_env(self.domain_id),
                                                  pass_fds=inherited).start()
            probe_args = [arg for rule in given.remaps for arg in ('-r', rule)]
            probe = self.probe = RemoteProbe(self.domain_id, '_r2d2_sim_process_client',
                                             namespace=namespace or None, ros_args=probe_args)
            self._connect(expected_namespaces(parameters, namespace))
            self._wait_ready()
        except BaseException:
            self._end(process, probe)
            raise

    # -- the node's own control services (~/pause, ~/step, ~/reset, ~/get_status) ------

    def check_open(self) -> None:
        """Raise HarnessError (one line) once :meth:`stop` has ended the simulator."""
        if self.result is not None:
            raise HarnessError('the simulator process was stopped: start a new SimProcess')

    def _request(self, name: str, request: Any, resend_after_s: Optional[float] = None,
                 client: Optional[Client] = None) -> Dict[str, Any]:
        self.check_open()
        if self._exited():
            raise HarnessError(f'sim_node has exited (status {self.process.returncode})')
        client = client or self._clients[name]
        reply = self.probe.call_client(client, request, self.timeout_s,
                                       resend_after_s, abort=self._exited)
        if reply is None:
            raise HarnessError(f'{client.srv_name} did not answer within {self.timeout_s:g} s')
        facts = json.loads(reply.message)
        if name not in ('get_joint_info', 'get_readers'):
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

    def readers(self) -> Dict[str, int]:
        """
        Return how many readers the simulator's writers match, by topic (``~/get_readers``).

        The fewest of its writers on a topic (several robots share ``/tf``).
        """
        return self._request('get_readers', Trigger.Request(), STATUS_RESEND_S)

    def step(self, count: int = 1) -> Dict[str, Any]:
        """
        Advance a paused simulator ``count`` control periods through ``~/step``.

        Returns the last reply with ``steps``, the physics steps of all the
        calls. Raises HarnessError if it is running (pause it first).
        """
        total = 0
        facts: Dict[str, Any] = {}
        for _ in range(step_count(count, 'count')):
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

    def joint_info(self, robot: Optional[str] = None) -> Dict[str, Any]:
        """
        Return a robot's ``~/get_joint_info`` JSON: ``robot``, ``urdf`` and ``joints``.

        ``robot``: its name (default: the first robot). Its service is on the
        robot's node: the simulator's for the one default robot, else
        ``<robot namespace>/<node name>/get_joint_info``.
        """
        self.check_open()
        handle = self.robot(robot)
        path = f'{handle.namespace.rstrip("/")}/{self.node_path.rsplit("/", 1)[1]}'
        client = self._clients.get(path)
        if client is None:
            client = self._clients[path] = self.probe.node.create_client(
                Trigger, f'{path}/get_joint_info')
            if not self.probe.spin_until(client.service_is_ready, self.timeout_s):
                raise HarnessError(f'{path}/get_joint_info was not available within '
                                   f'{self.timeout_s:g} s')
        return self._request('get_joint_info', Trigger.Request(), STATUS_RESEND_S, client)

    def _connect(self, namespaces: Sequence[str]) -> None:
        """Create the clients, ``/clock`` and the subscriptions of robots in ``namespaces``."""
        node = self.probe.node
        if self._state_subscriptions:
            self._clock_subscription = node.create_subscription(
                Clock, '/clock', self._keep_clock, 1)
            self._listen_tf_from_now()
        self._pending = [RemoteRobot(self, namespace, subscribe=self._state_subscriptions)
                         for namespace in namespaces]
        self._clients = {name: node.create_client(srv, f'{self.node_path}/{name}')
                         for name, srv in SERVICES}

    def _keep_clock(self, msg: Clock) -> None:
        self._clock = msg

    def _exited(self) -> bool:
        return self.process.exited()

    def _wait_ready(self) -> None:
        services = [self._clients[name] for name, _ in SERVICES]
        if not self.probe.spin_until(
                lambda: self._exited() or all(c.service_is_ready() for c in services),
                self.timeout_s) or self._exited():
            self._fail_start('did not serve its services')
        # Which robots, in which namespaces: a --params-file this side never reads may
        # list them. The parameters' guess was subscribed to before the node started
        # (usually right, and linking meanwhile); the node's word decides. get_status's
        # client was created last: the server learns of our reply readers in the order
        # we made them, so once it answers here it can answer every client. Paused or
        # not comes from here too (start_paused may come from a --params-file).
        try:
            robots = self.status()['robots']
        except HarnessError:
            if not self._exited():
                raise
            self._fail_start('did not answer ~/get_status')
        guessed = {robot.namespace: robot for robot in self._pending}
        pending: List[RemoteRobot] = []
        for name, facts in robots.items():
            robot = guessed.pop(facts['namespace'], None)
            if robot is None:
                robot = RemoteRobot(self, facts['namespace'], subscribe=self._state_subscriptions)
            pending.append(robot.bind(name, facts))
        for robot in guessed.values():
            robot.close()  # no robot there: the parameters were overridden
        self._pending = pending

        def linked() -> bool:
            return self._exited() or (all(robot.linked() for robot in pending)
                                      and (self._clock_subscription is None or
                                           self._clock_subscription.get_publisher_count() > 0))
        if not self.probe.spin_until(linked, self.timeout_s) or self._exited():
            unlinked = [robot.name or robot.namespace for robot in pending
                        if not robot.linked()]
            self._fail_start(f'did not link the topics of {", ".join(unlinked)}' if unlinked
                             else 'did not publish /clock')
        for robot in pending:
            robot.attach()
        if not self.probe.spin_until(
                lambda: all(r.cmd_vel_linked() for r in pending) or self._exited(),
                self.timeout_s) or self._exited():
            self._fail_start('did not subscribe cmd_vel')
        # In the node's order: the first robot is the harness's own.
        self._robots = {robot.name: robot for robot in pending if robot.name is not None}
        self._pending = []
        self.wait_heard()
        if (self._state_subscriptions and not self.paused and not self.probe.spin_until(
                lambda: self._clock is not None or self._exited(), self.timeout_s)):
            self._fail_start('published no /clock')

    def wait_heard(self) -> None:
        """
        Wait (by deadline) until the simulator's writers match every reader on the probe's node.

        A reader matching a writer is not enough: the writer learns of the
        reader on its own, a moment later, and what it publishes before then
        never arrives (a first step's ``/tf`` lost, a state message waited for
        in vain). The harness calls this when it starts and when it makes a
        robot's handle; call it after making subscriptions of your own on
        ``probe.node`` and before stepping. For each topic the node subscribes
        that the simulator publishes, its ``~/get_readers`` must count every
        subscription the graph shows that its writers can match (the message
        type and QoS fit: :func:`matchable_readers`), ours among them.
        HarnessError naming the topics when the deadline passes.
        """
        node = self.probe.node
        writer = self.node_path.rsplit('/', 1)[1]  # the robots' nodes share the name
        topics = sorted({s.topic_name for s in node.subscriptions})
        late: List[str] = []

        def heard() -> bool:
            readers = self.readers()
            late[:] = [t for t in topics
                       if t in readers and readers[t] < matchable_readers(node, t, writer)]
            return not late
        if not ask_until(heard, self.probe.spin_until, self.timeout_s):
            raise HarnessError(f'the simulator did not match the readers of '
                               f'{", ".join(late)} within {self.timeout_s:g} s')

    def robot(self, name: Optional[str] = None) -> RemoteRobot:
        """
        Return the handle of the robot ``name`` (default: the first robot).

        A robot spawned with a namespace has one from its spawn on. HarnessError
        for a robot the world does not have.
        """
        robots = None
        if name is None and self._robots:  # kept in the simulator's order
            return next(iter(self._robots.values()))
        if name is None:
            robots = self.status()['robots']
            if not robots:
                raise HarnessError('the world has no robot')
            name = next(iter(robots))
        handle = self._robots.get(name)
        if handle is not None:
            return handle
        robots = robots or self.status()['robots']
        if name not in robots:
            raise HarnessError(f'no robot named {name!r}; the robots are: {", ".join(robots)}')
        facts = robots[name]
        handle = self._robots[name] = RemoteRobot(
            self, facts['namespace'], name, facts,
            subscribe=self._state_subscriptions).connect()
        return handle

    @property
    def robot_names(self) -> List[str]:
        """Return the names of the robots in the world, in the simulator's order."""
        return list(self.status()['robots'])

    def _after_spawn(self, name: str, namespace: str) -> None:
        if namespace:
            self.robot(name)  # listening from now on

    def _after_delete(self, name: str) -> None:
        handle = self._robots.pop(name, None)
        if handle is not None:
            handle.close()

    def _fail_start(self, what: str) -> NoReturn:
        if self._exited():
            result = self.stop()
            refusals = [line.split(': error: ', 1)[1] for line in result.stderr.splitlines()
                        if ': error: ' in line]
            if result.returncode == 2 and refusals:  # sim_node refused a parameter or file
                raise ProcessStartupError(refusals[-1])
            raise HarnessError(f'sim_node exited with status {result.returncode} while '
                               f'starting: {result.stderr.strip()[-2000:]}')
        raise HarnessError(f'sim_node {what} within {self.timeout_s:g} s')

    @property
    def standard(self) -> StandardClient:
        """Return the client of the node's simulation_interfaces services (made on first use)."""
        self.check_open()
        if self._standard is None:
            namespace = self.node_path.rsplit('/', 1)[0]
            # Queries sent again, as ~/get_status is: a reply can be lost on a busy machine.
            self._standard = StandardClient(self.probe.node, self.probe.spin_until, namespace,
                                            self.timeout_s, resend_s=STATUS_RESEND_S)
        return self._standard

    def _world_backend(self) -> StandardWorld:
        return StandardWorld(self.standard)

    def _after_reset(self) -> None:
        """Make the readers wait for the reset world, published at the next publication."""
        facts = self.status()
        self._not_before_ns = facts['sim_time_ns'] + 1
        self._clock = None
        for name in [n for n in self._robots if n not in facts['robots']]:
            self._robots.pop(name).close()
        for robot in self._robots.values():
            robot.forget()
        # A full reset builds deleted start-up robots again, maybe ahead of those
        # with handles: keep the handles in the simulator's order, the first one first.
        first = next(iter(facts['robots']), None)
        if first is not None and first not in self._robots:
            self.robot(first)
        self._robots = {name: self._robots[name] for name in facts['robots']
                        if name in self._robots}

    def _after_time_back(self) -> None:
        """Listen to TF afresh, the harness and every robot's handle: the old frames go."""
        self._restart_tf()
        for handle in self._robots.values():
            handle._restart_tf()

    def step_physics(self, steps: int) -> Dict[str, Any]:
        """
        Step a paused simulator ``steps`` physics steps (step_simulation); return its status.

        Raises StandardError (OPERATION_FAILED) while the simulator is playing,
        ValueError (nothing sent) for a count that is not a whole number >= 0.
        """
        self.standard.step(steps)
        self._not_before_ns = 0
        return self.status()

    def _tf_node(self) -> Node:
        self.check_open()
        return self.probe.node

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        return self.probe.spin_until(condition, self.timeout_s)

    def _wait_latest(self, key: str, latest: Dict[str, Any], what: str) -> Any:
        """
        Paused: wait for the latest state publication's message. Running: the newest.

        The node's status says the stamp of its latest state publication, asked
        afresh each time: another client (the standard's ``step_simulation``,
        a second harness) may have stepped it since this one's last reply.
        Running, what is published from the reply on. ``latest`` holds a
        robot's latest message of each topic, ``what`` names the topic.
        """
        if not self._state_subscriptions:
            raise HarnessError(f'no {key}: this SimProcess was made with '
                               'state_subscriptions=False')
        facts = self.status()
        wanted = facts['published_ns'] if self.paused else facts['sim_time_ns']
        if self.paused and wanted < self._not_before_ns:
            raise HarnessError(f'no {key} yet: the reset robot is published at the next '
                               'publication; step() first')
        floor = max(wanted, self._not_before_ns)

        def arrived() -> bool:
            msg = latest[key]
            if msg is None:
                return False
            stamp = stamp_ns(msg.header.stamp)
            return stamp == wanted if self.paused else stamp >= floor
        if not self.probe.spin_until(arrived, self.timeout_s):
            hint = (': a simulator that started paused has published nothing since this '
                    'client connected; step() it first'
                    if self.paused and facts.get('step') == 0 else '')
            raise HarnessError(f'no {what} of t={wanted / 1e9:.6f} s within '
                               f'{self.timeout_s:g} s{hint}')
        return latest[key]

    def stop(self, timeout_s: float = 10.0) -> ProcessResult:
        """
        Stop the simulator with SIGINT (SIGKILL after ``timeout_s``); return how it ended.

        Also closes this object's node and releases the domain. Safe to call
        twice: later calls return the first result.
        """
        return self._end(self.process, self.probe, timeout_s)

    def _end(self, process: Optional[ChildProcess], probe: Optional[RemoteProbe],
             timeout_s: float = 10.0) -> ProcessResult:
        """Stop ``process``, close ``probe`` (either None: start-up never made it), release."""
        if self.result is not None:
            return self.result
        try:
            result = self.result = (process.stop(signal.SIGINT, timeout_s)
                                    if process is not None else ProcessResult(-1, '', ''))
        finally:
            if probe is not None:
                probe.close()
            if self.lease is not None:
                self.lease.release()
        return result

    def __enter__(self) -> 'SimProcess':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.stop()
