"""
The simulator in the test's process, advanced only when told: :class:`SimHarness`.

Simulated time moves only in :meth:`SimHarness.advance` and
:meth:`SimHarness.advance_until`; with nodes of the user's own in the harness
they run in lockstep with the simulator, so a run repeats bit for bit.
"""

import inspect
import json
from typing import Any, Callable, Dict, List, Optional, Set, Tuple, Type, TYPE_CHECKING
import weakref

from rclpy.exceptions import NameValidationException
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy
from rclpy.subscription import Subscription
from rclpy.validate_namespace import validate_namespace
from rclpy.validate_node_name import validate_node_name
from std_srvs.srv import Trigger

from r2d2_sim.client import sim_seconds, step_count
from r2d2_sim.errors import StartupError
from r2d2_sim.ros.quiet_node import NO_TYPE_DESCRIPTION_SERVICE, QuietNode
from r2d2_sim.testing.executor import (
    CallbackError, HarnessError, parameter_overrides, RosHarness)
from r2d2_sim.testing.lockstep import TakenOnDemand
from r2d2_sim.testing.robots import (
    expected_namespaces, FirstRobot, LocalRobot, simulator_parameters)
from r2d2_sim.testing.tf import TransformLookup
from r2d2_sim.testing.world_verbs import CoreWorld, WorldVerbs

if TYPE_CHECKING:  # PyBullet is imported only when a simulator is made
    from r2d2_sim.ros.node import SimNode
    from r2d2_sim.sim.oracles import RunWatch

__all__ = ['SimHarness', 'LINK_NODE_NAME']

# Name of the node through which a harness talks to the simulator (the
# leading underscore hides it from `ros2 node list`).
LINK_NODE_NAME = '_r2d2_sim_harness'


def _check_names(node_name: Any, namespace: Any) -> None:
    """Raise StartupError (one line) unless rclpy takes ``node_name`` and ``namespace``."""
    for what, value, validate in (('node_name', node_name, validate_node_name),
                                  ('namespace', namespace, validate_namespace)):
        if not isinstance(value, str):
            raise StartupError(f'{what} must be a string, got {value!r}')
        if what == 'namespace':
            if not value:
                continue  # the root namespace
            value = value if value.startswith('/') else '/' + value  # as rclpy reads it
        try:
            validate(value)
        except NameValidationException as exc:  # rclpy's message points at the character
            reason = str(exc).splitlines()[0].rstrip(':')
            raise StartupError(f'{what} {value!r}: {reason}') from None


def _noting(subscription: Subscription, delivered: Set[int]) -> Callable[..., Any]:
    """
    Return the subscription's callback that first notes its id in ``delivered``.

    Of the same kind: a coroutine stays one, and one that takes the message's
    info takes it too (rclpy tells them apart by the callback's signature).
    """
    callback, key = subscription.callback, id(subscription)
    with_info = subscription._callback_type is Subscription.CallbackType.WithMessageInfo
    if inspect.iscoroutinefunction(callback):
        if with_info:
            async def noted_async_info(msg: Any, info: Any) -> Any:
                delivered.add(key)
                return await callback(msg, info)
            return noted_async_info

        async def noted_async(msg: Any) -> Any:
            delivered.add(key)
            return await callback(msg)
        return noted_async
    if with_info:
        def noted_info(msg: Any, info: Any) -> Any:
            delivered.add(key)
            return callback(msg, info)
        return noted_info

    def noted(msg: Any) -> Any:
        delivered.add(key)
        return callback(msg)
    return noted


class SimHarness(RosHarness, FirstRobot, TransformLookup, WorldVerbs):
    """
    The simulator in this process, advanced only when told, plus nodes of your own.

    ``SimHarness(cmd_vel_timeout=0.0, urdf='r2d2.urdf')``: keywords other than
    the harness's own are the simulator's ROS parameters (``sim_node`` takes
    the same names). ``node_name`` and ``namespace`` place the simulator (its
    services are ``<namespace>/<node_name>/pause`` and so on). Raises
    :class:`r2d2_sim.ros.node.StartupError` when they or the parameters are unusable
    (``outputs_process`` too: lockstep needs delivery within this process).

    Several robots: ``robots=['a', 'b']`` with ``**{'b.initial_pose': [...]}``,
    or ``robots={'a': {}, 'b': {'initial_pose': [2.0, 0.0, 3.14]}}``.
    :meth:`robot` returns a handle per robot (``send_cmd_vel``,
    ``ground_truth``, ``odom``, ``joint_states``); the harness's own are the
    first robot's.

    Simulated time moves only in :meth:`advance` and :meth:`advance_until`.
    With nodes of your own (:meth:`create_node`, :meth:`add_node`), they go
    one control period at a time and let every callback that a period's
    publications trigger run before the next one (lockstep): a controller
    that answers ``odom`` with ``cmd_vel`` sees every state, its command takes
    effect at the next step, and a run repeats bit for bit.

    The world verbs (:class:`~r2d2_sim.testing.world_verbs.WorldVerbs`:
    ``spawn``, ``entity_state``, ``set_entity_state``, ``delete_entity``,
    ``reset_world``, ``load_world``, ``named_pose``...) act on the simulation
    directly; ``advance(steps=n)`` steps n physics steps.
    """

    def __init__(self, node_name: str = 'r2d2_sim', *, namespace: str = '',
                 domain_id: Optional[int] = None, timeout_s: float = 10.0,
                 **parameters: Any) -> None:
        parameters = simulator_parameters(parameters, StartupError)  # before anything is built
        _check_names(node_name, namespace)
        if parameters.get('outputs_process') is True:  # a wrong type: the node's own line
            raise StartupError(
                'outputs_process: SimHarness delivers every message within this process, '
                'which its lockstep needs; a second process publishing would make a run '
                'depend on timing (SimProcess runs sim_node with it)')
        super().__init__(domain_id=domain_id, timeout_s=timeout_s)
        self.namespace = namespace
        # The simulator and the harness's own node: both made below, or the constructor raises.
        self.sim: SimNode
        self._link: Node
        self._lockstep = False
        # Latched subscriptions served (their message in before time moved), and every
        # subscription looked at: weakly, as a destroyed one's id may be another's later.
        self._latched_served: 'weakref.WeakSet[Subscription]' = weakref.WeakSet()
        self._subscriptions_seen: 'weakref.WeakSet[Subscription]' = weakref.WeakSet()
        # Before a world change (spawn, reset, load) with nodes of the user's: the latched
        # publishers there were, and how many messages each subscription had handled.
        self._world_mark: Optional[Tuple[List[Publisher], Dict[Subscription, int]]] = None
        self._robots: Dict[str, LocalRobot] = {}  # by name, in the simulator's order
        # advance(seconds=...) since time last went back: the seconds asked for in all, and
        # the steps taken for them, so each call steps to the nearest step of the total.
        self._seconds_asked = 0.0
        self._steps_for_seconds = 0
        try:
            from r2d2_sim.ros.node import SimNode  # PyBullet: only when a simulator is wanted
            # Without parameter services, rosout, type descriptions or QoS
            # event handlers: fewer entities for the executor to gather on every
            # wait of a lockstep run.
            link = self._link = QuietNode(
                LINK_NODE_NAME, context=self.context, namespace=namespace or None,
                start_parameter_services=False, enable_rosout=False,
                parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
            RosHarness.add_node(self, link, use_sim_time=False)
            # The robots' state readers take the latest message when asked (a
            # callback group no executor runs), so a lockstep period spends
            # nothing on them. Subscribed before the simulator exists: it
            # publishes its first state from its constructor, and delivery
            # within one context is synchronous once matched.
            waiting = [LocalRobot(self, link, ns)
                       for ns in expected_namespaces(parameters, namespace)]
            self.sim = SimNode(node_name, context=self.context, namespace=namespace or None,
                               parameter_overrides=parameter_overrides(parameters))
            RosHarness.add_node(self, self.sim, use_sim_time=False)
            if self.sim.standard is not None:  # its services, on a node of their own
                RosHarness.add_node(self, self.sim.standard.node, use_sim_time=False)
            self.sim.watch_robot_nodes(self._robot_node_added, self._robot_node_removed)
            for interfaces in self.sim.robots:
                handle = next((h for h in waiting if h.namespace == interfaces.namespace), None)
                if handle is None:
                    handle = LocalRobot(self, link, interfaces.namespace)
                else:
                    waiting.remove(handle)
                self._robots[interfaces.name] = handle.attach(interfaces)
            for handle in waiting:
                handle.close()
        except BaseException:
            self.close()
            raise

    def _robot_node_added(self, node: Node) -> None:
        RosHarness.add_node(self, node, use_sim_time=False)

    def _robot_node_removed(self, node: Node) -> None:
        self.executor.remove_node(node)
        if node in self.nodes:
            self.nodes.remove(node)

    def robot(self, name: Optional[str] = None) -> LocalRobot:
        """
        Return the handle of the robot ``name`` (default: the first robot).

        A robot spawned with a namespace has one from its spawn on. HarnessError
        for a robot the world does not have.
        """
        self.check_open()
        self._drop_departed()
        if name is None:
            if not self._robots:
                raise HarnessError('the world has no robot')
            return next(iter(self._robots.values()))  # kept in the simulator's order
        handle = self._robots.get(name)
        if handle is None:
            try:
                interfaces = self.sim.robot(name)
            except KeyError as exc:
                raise HarnessError(str(exc.args[0])) from None
            # Spawned by someone else: its state is readable from the next publication.
            handle = self._robots[name] = LocalRobot(
                self, self._link, interfaces.namespace).attach(interfaces)
        return handle

    @property
    def robot_names(self) -> List[str]:
        """Return the names of the robots in the world, in the simulator's order."""
        return [interfaces.name for interfaces in self.sim.robots]

    def _drop_departed(self) -> None:
        """Close the handles of robots that left the world (deleted, or a reset)."""
        live = {interfaces.name: interfaces for interfaces in self.sim.robots}
        for name, handle in list(self._robots.items()):
            if not handle.bound_to(live.get(name)):  # gone, or another robot of that name
                self._robots.pop(name).close()

    def _before_world_change(self) -> None:
        """
        Note the latched publishers and what each subscription handled (see _serve_new_latched).

        The first change since the last advance counts: a second one before
        the next advance adds publishers, not subscriptions that are served.
        """
        if self._lockstep and self._world_mark is None:
            self._world_mark = (self._latched_publishers(), dict(self._handled))

    def _after_spawn(self, name: str, namespace: str) -> None:
        if namespace:
            self.robot(name)  # listening before its first publication

    def _after_delete(self, name: str) -> None:
        self._drop_departed()

    def create_node(self, name: str, *, use_sim_time: bool = True, **node_kwargs: Any) -> Node:
        """Create a node of yours (in the simulator's namespace unless given one); see add_node."""
        node_kwargs.setdefault('namespace', self.namespace or None)
        return super().create_node(name, use_sim_time=use_sim_time, **node_kwargs)

    def add_node(self, node: Node, *, use_sim_time: bool = True) -> Node:
        """
        Spin a node of yours with the simulator; from now on advance in lockstep with it.

        Returns once the node's transient-local subscriptions to the
        simulator's latched topics (``robot_description``, ``/tf_static``)
        have their message: delivery of a latched message waits for the
        middleware to match the new subscription, which took 40-430 ms of
        wall time, so without this a node would start on a simulated time
        that depends on the machine's load.
        """
        self._check_new_node(node)  # before its callbacks are wrapped below
        self._lockstep = True
        self._serve_latched([node], lambda: super(SimHarness, self).add_node(
            node, use_sim_time=use_sim_time))
        return node

    def _serve_latched(self, nodes: List[Node], spin: Callable[[], Any] = lambda: None) -> None:
        """
        Return once ``nodes``' latched subscriptions not served yet have their message.

        For :meth:`add_node` (``spin`` adds the node to the executor), and
        before each lockstep advance, for subscriptions a node made after it
        was added: else their message would reach them at a simulated time
        that depends on the machine's load.
        """
        # A message some callback already handled (the spinning thread took it
        # before anyone looked, or a settle() did) came before time moved: served.
        pending = [sub for node in nodes for sub in self._latched_subscriptions(node)
                   if sub not in self._latched_served and sub not in self._handled]
        self._wait_latched(pending, 'the latched topics did not reach '
                           f'{", ".join(sorted({n.get_name() for n in nodes}))}', spin)
        self._latched_served.update(pending)

    def _wait_latched(self, pending: List[Subscription], what: str,
                      spin: Callable[[], Any] = lambda: None) -> None:
        """Call ``spin``, then return once each of ``pending`` has had a message; else ``what``."""
        delivered: Set[int] = set()
        originals = [(sub, sub.callback) for sub in pending]
        # Noted before the node is spun: the spinning thread may take a latched
        # message as soon as the node is in the executor.
        for sub, _ in originals:
            sub.callback = _noting(sub, delivered)
        try:
            spin()
            if pending:
                with self._own_executor():
                    self._wait(lambda: len(delivered) == len(pending), what)
        except CallbackError:
            raise  # a callback of the user's raised: that error, its cause kept
        except HarnessError as exc:
            missing = ', '.join(sub.topic_name for sub in pending if id(sub) not in delivered)
            if not missing:
                raise
            raise HarnessError(f'{exc} (still missing: {missing})') from None
        finally:
            for sub, callback in originals:
                sub.callback = callback

    def _serve_new_latched(self) -> None:
        """
        Before a lockstep advance: serve latched subscriptions made since (see above).

        The caller owns the executor: the spinning thread, parked, cannot take
        a message between the look at what was handled and the wrapping.
        """
        seen = self._subscriptions_seen
        fresh = [node for node in self.nodes if any(sub not in seen for sub in node.subscriptions)]
        old = set(seen)  # made before the last advance: a world change since is news to them
        if fresh:
            self._serve_latched(fresh)
            for node in fresh:
                seen.update(node.subscriptions)
        mark, self._world_mark = self._world_mark, None
        if mark is not None:
            self._serve_new_publishers(*mark, old)

    def _serve_new_publishers(self, before: List[Publisher],
                              handled_before: Dict[Subscription, int],
                              old: Set[Subscription]) -> None:
        """
        Return once latched subscriptions had a message from publishers new since the mark.

        A robot spawned with a namespace (or built again by a reset or
        load_world) brings latched publishers (``<ns>/robot_description``...)
        that subscriptions made before it match in wall time: without this,
        their message arrived at a simulated time that depends on the machine's
        load. One message since the mark serves a subscription (a depth-1
        history may keep only the last of several new publishers' messages).
        """
        known = {id(publisher) for publisher in before}
        topics = {publisher.topic_name for publisher in self._latched_publishers()
                  if id(publisher) not in known}
        if not topics:
            return
        handled = self._handled
        pending = [sub for node in self.nodes for sub in self._latched_subscriptions(node)
                   if sub.topic_name in topics and sub in old
                   and handled.get(sub, 0) == handled_before.get(sub, 0)]
        self._wait_latched(pending, 'the latched topics of the new robots did not reach '
                           f'{", ".join(sorted({s.topic_name for s in pending}))}')

    def _latched_publishers(self) -> List[Publisher]:
        """Return the simulator's transient-local publishers, its robots' own nodes' too."""
        publishers = self.sim.all_publishers() + [
            p for robot in self.sim.robots if robot.own_node for p in robot.publishers]
        return [publisher for publisher in publishers
                if publisher.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL]

    def _latched_subscriptions(self, node: Node) -> List[Subscription]:
        """Return the node's transient-local subscriptions to the simulator's latched topics."""
        latched = {publisher.topic_name for publisher in self._latched_publishers()}
        return [sub for sub in node.subscriptions if sub.topic_name in latched
                and sub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                and not isinstance(sub.callback_group, TakenOnDemand)]

    @property
    def physics_rate_hz(self) -> float:
        """Return physics steps per simulated second."""
        return self.sim.config.physics_rate_hz

    def advance(self, steps: Optional[int] = None, *, seconds: Optional[float] = None) -> int:
        """
        Step the physics ``steps`` times, or for ``seconds`` of simulated time; return the steps.

        Seconds add up: each call steps to the nearest physics step of the
        simulated time asked for by every ``seconds=`` call so far (since time
        last went back), so 100 calls of 0.01 s step 1 s at any rate. A call
        shorter than a step may step nothing (it returns 0); its time is carried
        to the next call. With neither, one control period: up to and including
        the next state publication (as ``~/step``).
        Pause does not apply here: the harness decides when time moves.
        ValueError (one line, nothing stepped) unless ``steps`` is a whole
        number >= 0 (numpy's too; not 2.0: time goes as ``seconds=``) and
        ``seconds`` a finite number >= 0.
        """
        if steps is not None and seconds is not None:
            raise ValueError('give steps or seconds, not both')
        asked = None if seconds is None else sim_seconds(seconds)
        if steps is not None:
            steps = step_count(steps)
        self._check_world()
        self.raise_callback_error()
        if asked is not None:
            steps = self._steps_to_total(asked)
        elif steps is None:
            steps = self.sim.steps_to_next_publish()
        if not self._lockstep:
            self.sim.advance(steps)
            return steps
        with self._own_executor():
            self._serve_new_latched()
            self._run_periods(steps)
        return steps

    def advance_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """
        Advance one control period at a time until ``predicate()`` is true.

        ``timeout_s`` is simulated time, rounded to the nearest physics step but
        at least one step when it is > 0 (0: only look). Returns True as soon as
        the predicate holds (checked first before any step, then after each
        publication), False when the time is up: write
        ``assert harness.advance_until(...)``, or ``assert not ...`` for
        something that must not happen. ValueError (one line) unless
        ``timeout_s`` is a finite number >= 0.
        """
        timeout = sim_seconds(timeout_s)
        limit = round(timeout * self.physics_rate_hz)
        if timeout > 0:
            limit = max(limit, 1)
        self._check_world()
        # Driven from this thread: each period's messages are handled before
        # the predicate looks, with no hand-over to the executor thread.
        with self._own_executor():
            if self._lockstep:
                self._serve_new_latched()
            return predicate() or self._run_periods(limit, predicate)

    def _check_world(self) -> None:
        self.check_open()
        if not self.sim.world_is_loaded:
            raise HarnessError('no world is loaded (unload_world): load_world first')

    def _run_periods(self, steps: int,
                     predicate: Optional[Callable[[], bool]] = None) -> bool:
        """
        Advance ``steps`` one control period at a time, handling each period's messages.

        Returns True as soon as ``predicate`` holds after a period (False if
        it never did, or without one).
        """
        done = 0
        while done < steps:
            chunk = min(self.sim.steps_to_next_publish(), steps - done)
            self.sim.advance(chunk)
            done += chunk
            self._run_until_idle(self.timeout_s)
            self.raise_callback_error()
            if predicate is not None and predicate():
                return True
        return False

    def _steps_to_total(self, seconds: float) -> int:
        """Return the steps that bring the time stepped nearest to all the seconds asked for."""
        self._seconds_asked += seconds
        steps = round(self._seconds_asked * self.physics_rate_hz) - self._steps_for_seconds
        self._steps_for_seconds += steps
        return steps

    def _tf_node(self) -> Node:
        self.check_open()
        return self._link

    def _tf_default_time_ns(self) -> int:
        return self.last_publication_ns()  # the current state, never one on its way

    def _tf_sent_before(self) -> Tuple[bytes, ...]:
        return tuple(interfaces.outputs.tf.latest for interfaces in self.sim.robots
                     if interfaces.outputs.tf is not None and interfaces.outputs.tf.latest
                     and interfaces.tf_topics[0] == self._tf_topics()[0])

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        try:
            self._wait(condition, 'no transform')
        except CallbackError:
            raise  # a callback's error, for the caller: not "no transform"
        except HarnessError:
            return False
        return True

    def _tf_frozen(self) -> bool:
        return True  # time moves only when this harness advances it

    def last_publication_ns(self) -> int:
        """Return the simulated time (ns) of the simulator's latest state publication."""
        return self.sim.last_publication_ns

    def reset(self) -> Dict[str, Any]:
        """
        Put the robot back at its initial pose through ``~/reset``; return the reply's JSON.

        The node publishes the reset robot at its next publication (never a
        second state at a stamp already published), so this then advances one
        control period: simulated time goes on, and the state readers return
        the reset robot.
        """
        self.check_open()
        self._before_reset()
        reply = self.call_service(Trigger, self.sim.get_fully_qualified_name() + '/reset',
                                  Trigger.Request())
        self._after_reset()
        return json.loads(reply.message)

    def _world_backend(self) -> CoreWorld:
        self.check_open()
        return CoreWorld(self.sim)

    def _before_reset(self) -> None:
        """Note what is there (robots a full reset builds again publish latched topics anew)."""
        self._before_world_change()
        self._drop_departed()

    def _after_reset(self) -> None:
        """Make the state readers wait for the reset world (published one control period on)."""
        self._drop_departed()
        for handle in self._robots.values():
            handle.forget()
        # A full reset builds deleted start-up robots again: every robot gets its
        # handle before that publication, and the handles keep the simulator's order.
        names = self.robot_names
        for name in names:
            self.robot(name)
        self._robots = {name: self._robots[name] for name in names}
        self.advance()

    def watch(self, entity: Optional[str] = None, **options: Any) -> 'RunWatch':
        """
        Watch a robot's run from now on: contacts, clearance, regions reached, tipping.

        Returns a :class:`~r2d2_sim.sim.oracles.RunWatch` the physics fills
        step by step while the test advances (``entity``: a robot's or any
        entity's name, default the first robot; ``regions``,
        ``clearance_range_m``, ``tip_angle_rad`` as it takes them). Close it
        (or use ``with``) to stop paying for it: about 10 us per other body
        per step.
        """
        self.check_open()
        from r2d2_sim.sim.oracles import RunWatch
        with self.sim.lock:
            return RunWatch(self.sim.simulation, entity, **options)

    def _after_time_back(self) -> None:
        """Listen to TF afresh, the harness and every robot's handle: the old frames go."""
        self._seconds_asked, self._steps_for_seconds = 0.0, 0  # counted from the new time
        self._restart_tf()
        for handle in self._robots.values():
            handle._restart_tf()

    def _after_world(self, loaded: bool) -> None:
        """After load_world as after a full reset; after unload_world nothing can step."""
        if loaded:
            self._after_reset()
            return
        self._drop_departed()
        for handle in self._robots.values():
            handle.forget()

    def call_service(self, srv_type: Type, name: str, request: Any) -> Any:
        """Call a service (of the simulator or yours) from the harness's node; return the reply."""
        self.check_open()
        client = self._link.create_client(srv_type, name)
        try:
            self._wait(client.service_is_ready, f'service {name} was not available')
            future = client.call_async(request)
            self._wait(future.done, f'{name} did not answer')
            return future.result()
        finally:
            self._link.destroy_client(client)

    def __enter__(self) -> 'SimHarness':
        return self
