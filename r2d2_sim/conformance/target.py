"""
The simulator under test, as the kit's clauses see it: :class:`Target`.

A node of the kit's own (a :class:`~r2d2_sim.testing.RemoteProbe`: its
context on the simulator's ROS domain, spun in the caller's thread) finds the
services and the action by type under a prefix, reads the declared features
once, listens to ``/clock`` if someone publishes it, and offers the clauses
typed calls: a reply that is not what a clause expects becomes a
:class:`~r2d2_sim.conformance.clause.ClauseFailed` with a one-line reason,
never a traceback. It also keeps what the kit changed (entities it spawned,
the world it loaded) so that each clause can be undone.
"""

import itertools
import math
import os
from typing import Callable, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.discovery import (
    ACTION, FEATURE_INTERFACES, FEATURES, find_interfaces, normal_prefix)
from r2d2_sim.errors import SetupError

__all__ = ['KitOptions', 'KitError', 'Target', 'BOX_SIZE_M', 'UNKNOWN_NAME']

# The kit's own box: a cube this wide, 1 kg, from a resource string.
BOX_SIZE_M = 0.2
# A name no simulator has an entity (or named pose) of.
UNKNOWN_NAME = 'conformance_no_such_entity'
# Queries that may be sent again when a reply is slow (a reply can be lost
# for good while the server has not yet discovered a new client's reader).
IDEMPOTENT = {'GetSimulatorFeatures', 'GetSimulationState', 'GetEntities', 'GetEntitiesStates',
              'GetEntityState', 'GetEntityInfo', 'GetEntityBounds', 'GetSpawnables',
              'GetNamedPoses', 'GetNamedPoseBounds', 'GetCurrentWorld', 'GetAvailableWorlds'}
RESEND_S = 1.0
# How long the kit waits for a /clock publisher once the services are found (s).
CLOCK_WAIT_S = 2.0
# At most this many callbacks are run to take the /clock messages already in.
DRAIN_SPINS = 1000


class KitError(SetupError):
    """The kit cannot run at all (simulation_interfaces missing, a bad option): one line."""


class KitOptions(NamedTuple):
    """
    Where the simulator is and what the kit may use there.

    ``prefix``: the namespace its services are under (``/``, ``/gzserver``);
    ``domain_id``: its ROS domain (None: ``ROS_DOMAIN_ID``, else 0);
    ``asset``: a URI its SpawnEntity takes (``cube.urdf``, a ``.usd``);
    ``world``: a URI its LoadWorld takes; ``timeout_s``: the longest wait
    for any one reply or discovery; ``free_space``: a point with free room
    around it (20 m along x) where the kit puts what it spawns;
    ``world_frame``: the world frame's name besides '' and ``world``;
    ``clock_topic``: where simulated time is published.
    """

    prefix: str = '/'
    domain_id: Optional[int] = None
    asset: str = ''
    world: str = ''
    timeout_s: float = 10.0
    free_space: Tuple[float, float, float] = (20.0, 20.0, 5.0)
    world_frame: str = 'world'
    clock_topic: str = '/clock'


def default_domain_id() -> int:
    """Return ``ROS_DOMAIN_ID`` as ROS reads it (0 when unset or empty)."""
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    try:
        return int(text) if text else 0
    except ValueError:
        raise KitError(f'ROS_DOMAIN_ID is not a number: {text[:20]!r}') from None


def _close(a: Sequence[float], b: Sequence[float], tolerance: float) -> bool:
    return all(abs(x - y) <= tolerance for x, y in zip(a, b))


def vector(v) -> Tuple[float, float, float]:
    """Return a geometry_msgs Vector3 or Point as a tuple."""
    return (v.x, v.y, v.z)


def quaternion(q) -> Tuple[float, float, float, float]:
    """Return a geometry_msgs Quaternion as an (x, y, z, w) tuple."""
    return (q.x, q.y, q.z, q.w)


def yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """Return the quaternion of a turn by ``yaw`` radians about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def same_rotation(a: Sequence[float], b: Sequence[float], tolerance: float = 1e-3) -> bool:
    """Return True when two quaternions turn alike (q and -q are one rotation)."""
    return _close(a, b, tolerance) or _close(a, [-v for v in b], tolerance)


def close(a: Sequence[float], b: Sequence[float], tolerance: float = 1e-3) -> bool:
    """Return True when two vectors agree within ``tolerance`` on every axis."""
    return _close(a, b, tolerance)


def fmt(values: Iterable[float]) -> str:
    """Return numbers as a short tuple for a reason: (1.0, 2.5, 0.0)."""
    return '(' + ', '.join(f'{v:.4g}' for v in values) + ')'


class Target:
    """
    The simulator under test: its interfaces found by type, its features, its clock.

    Made by :meth:`connect` (which never raises for what the simulator does:
    ``features_error`` says why its features are unknown); closed by
    :meth:`close`. The clauses use the verbs below; each raises
    ClauseFailed with a reason when the simulator does not answer as asked.
    """

    def __init__(self, options: KitOptions) -> None:
        try:
            from simulation_interfaces import action, msg, srv
            msg.Result.__class__.__import_type_support__()
        except Exception as exc:  # ImportError, or its type support missing
            raise KitError('simulation_interfaces (Jazzy 1.5) cannot be imported '
                           f'({type(exc).__name__}): source a ROS install that has it, or '
                           'build it with tools/build_interfaces.sh') from None
        from action_msgs.msg import GoalStatus
        from r2d2_sim.testing.remote import RemoteProbe
        self.options = options
        self.msg, self.srv, self.action = msg, srv, action
        self.GoalStatus = GoalStatus
        self.prefix = normal_prefix(options.prefix)
        self.domain_id = (options.domain_id if options.domain_id is not None
                          else default_domain_id())
        self.timeout_s = options.timeout_s
        self.probe = RemoteProbe(self.domain_id, '_sim_conformance')
        self.node = self.probe.node
        self.interfaces: Dict[str, str] = {}  # interface -> service (or action) name
        self.several: Dict[str, List[str]] = {}  # interface -> every name seen, when several
        self.features: Optional[frozenset] = None  # declared feature names; None: unknown
        self.feature_values: List[int] = []
        self.spawn_formats: List[str] = []
        self.features_error = ''
        self.has_clock = False
        self.spawned: List[str] = []  # names the kit spawned and has not deleted
        self.initial_state: Optional[int] = None
        self.initial_world = None  # the WorldResource current at connect, when told
        self.initial_world_known = False  # GetCurrentWorld answered (a world, or none)
        self.world_changed = False
        self._clients: Dict[str, object] = {}
        self._action_client = None
        self._feedback: List[Tuple[bytes, int, int]] = []
        self._feedback_subscription = None
        self._clock_ns: Optional[int] = None
        self._clock_count = 0
        self._clock_subscription = None
        self._cleanups: List[Callable[[], None]] = []
        self._names = itertools.count(1)

    # -- connecting --------------------------------------------------------------------

    def scan(self) -> Dict[str, str]:
        """Look at the ROS graph again; return {interface: name} of those under the prefix."""
        self.interfaces, self.several = find_interfaces(
            self.node.get_service_names_and_types(), self.prefix)
        return self.interfaces

    def connect(self) -> None:
        """
        Find the interfaces, read the features, find ``/clock``; never raises for the simulator.

        Waits up to the timeout for GetSimulatorFeatures, then (up to the
        timeout again) for every interface the features declare, so that a
        slow discovery is not taken for a missing service.
        """
        timeout = self.timeout_s
        if not self.probe.spin_until(lambda: 'GetSimulatorFeatures' in self.scan(), timeout):
            seen = ', '.join(sorted(self.interfaces)) or 'none of the standard\'s services'
            self.features_error = (f'no service of type GetSimulatorFeatures under '
                                   f'{self.prefix!r} within {timeout:g} s (found: {seen})')
            return
        try:
            self.read_features()
        except ClauseFailed as exc:
            self.features_error = str(exc)
            return
        wanted = [alternatives for feature in self.features
                  for alternatives in FEATURE_INTERFACES.get(feature, ())]

        def all_found() -> bool:
            found = self.scan()
            return all(any(kind in found for kind in alt.split('|')) for alt in wanted)
        self.probe.spin_until(all_found, timeout)
        self._make_clients()
        self._listen_to_clock()
        if 'SIMULATION_STATE_GETTING' in self.features and 'GetSimulationState' in self.interfaces:
            reply = self.call('GetSimulationState', self.srv.GetSimulationState.Request(),
                              check=False)
            if reply is not None and reply.result.result == self.msg.Result.RESULT_OK:
                self.initial_state = reply.state.state
        if 'WORLD_INFO_GETTING' in self.features and 'GetCurrentWorld' in self.interfaces:
            reply = self.call('GetCurrentWorld', self.srv.GetCurrentWorld.Request(), check=False)
            no_world = self.srv.GetCurrentWorld.Response.NO_WORLD_LOADED
            if reply is not None and reply.result.result in (self.msg.Result.RESULT_OK, no_world):
                self.initial_world_known = True
                if reply.result.result == self.msg.Result.RESULT_OK:
                    self.initial_world = reply.world

    def read_features(self):
        """Ask GetSimulatorFeatures again; return its SimulatorFeatures (names in ``features``)."""
        features = self.call('GetSimulatorFeatures',
                             self.srv.GetSimulatorFeatures.Request()).features
        by_value = {getattr(self.msg.SimulatorFeatures, name): name for name in FEATURES}
        self.feature_values = list(features.features)
        self.features = frozenset(by_value[v] for v in features.features if v in by_value)
        self.spawn_formats = [f.strip().lower() for f in features.spawn_formats]
        return features

    def _make_clients(self) -> None:
        """Make a client for every service found, GetSimulatorFeatures' again last."""
        for kind in self.interfaces:
            if kind != ACTION:
                self._client(kind)
        # Servers learn of our reply readers in the order we made them: once the
        # last one made gets its answer, every client can (see RemoteProbe).
        old = self._clients.pop('GetSimulatorFeatures', None)
        if old is not None:
            self.node.destroy_client(old)
        try:
            self.read_features()
        except ClauseFailed:
            pass

    def _listen_to_clock(self) -> None:
        """Subscribe to the clock with the publisher's reliability, once one is there."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        topic = self.options.clock_topic
        if not self.probe.spin_until(lambda: self.node.count_publishers(topic) > 0,
                                     min(CLOCK_WAIT_S, self.timeout_s)):
            return
        reliable = any(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                       for info in self.node.get_publishers_info_by_topic(topic))
        # Depth 1: only the newest time is of use, and a burst (a fast SimulateSteps
        # goal publishes one per step) must not queue up ahead of it.
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE if reliable
                         else ReliabilityPolicy.BEST_EFFORT)

        def keep(msg) -> None:
            self._clock_ns = msg.clock.sec * 10**9 + msg.clock.nanosec
            self._clock_count += 1
        self._clock_subscription = self.node.create_subscription(Clock, topic, keep, qos)
        self.has_clock = self.probe.spin_until(
            lambda: self._clock_subscription.get_publisher_count() > 0, self.timeout_s)

    def close(self) -> None:
        """Close the kit's node (the simulator is left as it is)."""
        self.probe.close()

    # -- calls -------------------------------------------------------------------------

    def declared(self, *features: str) -> bool:
        """Return True when each feature given is declared; ``A|B`` means either of the two."""
        have = self.features or frozenset()
        return all(any(f in have for f in wanted.split('|')) for wanted in features)

    def _client(self, kind: str):
        client = self._clients.get(kind)
        if client is None:
            name = self.interfaces.get(kind)
            if name is None:
                raise ClauseFailed(f'no {kind} service under {self.prefix!r}')
            client = self._clients[kind] = self.node.create_client(getattr(self.srv, kind), name)
        return client

    def call(self, kind: str, request, check: bool = True):
        """
        Call the service of interface ``kind`` (``'SpawnEntity'``); return its reply.

        ClauseFailed when it is not found, not ready or silent within the
        timeout (with ``check=False``: None instead).
        """
        try:
            client = self._client(kind)
        except ClauseFailed:
            if check:
                raise
            return None
        timeout = self.timeout_s
        if not self.probe.spin_until(client.service_is_ready, timeout):
            if check:
                raise ClauseFailed(f'{client.srv_name} was not ready within {timeout:g} s')
            return None
        resend = RESEND_S if kind in IDEMPOTENT else None
        reply = self.probe.call_client(client, request, timeout, resend)
        if reply is None and check:
            raise ClauseFailed(f'{client.srv_name} did not answer within {timeout:g} s')
        return reply

    def code_name(self, kind: str, value: int) -> str:
        """Name a result value: RESULT_* first, then the service's own constants."""
        owners = [self.msg.Result]
        if kind is not None:
            owners.append(getattr(self.srv, kind).Response)
        for owner in owners:
            for name in dir(owner):
                if name.isupper() and getattr(owner, name) == value:
                    return f'{name.replace("RESULT_", "")} ({value})'
        return f'code {value}'

    def describe(self, kind: str, reply) -> str:
        """Return a reply's result for a reason: ``NAME_NOT_UNIQUE (101): 'taken'``."""
        result = reply.result
        text = self.code_name(kind, result.result)
        if result.error_message:
            text += f': {result.error_message.splitlines()[0][:120]!r}'
        return text

    def expect(self, kind: str, request, codes: Sequence[int], doing: str):
        """Call and return the reply if its result is one of ``codes``; else ClauseFailed."""
        reply = self.call(kind, request)
        if reply.result.result not in codes:
            wanted = ' or '.join(self.code_name(kind, c) for c in codes)
            unsupported = (' (0 means unsupported: a declared interface answered with a '
                           'default Result)' if reply.result.result == 0 else '')
            raise ClauseFailed(f'{doing}: expected {wanted}, got '
                               f'{self.describe(kind, reply)}{unsupported}')
        return reply

    def ok(self, kind: str, request, doing: str):
        """Call and return the reply if its result is OK; else ClauseFailed."""
        return self.expect(kind, request, (self.msg.Result.RESULT_OK,), doing)

    # -- the simulation's state ---------------------------------------------------------

    @property
    def S(self):
        """Return SimulationState (its ``STATE_*`` constants)."""
        return self.msg.SimulationState

    def state_name(self, value: int) -> str:
        """Name a SimulationState value: PLAYING (1)."""
        for name in dir(self.S):
            if name.startswith('STATE_') and getattr(self.S, name) == value:
                return f'{name[6:]} ({value})'
        return f'undefined state {value}'

    def state(self) -> int:
        """Return the simulation state GetSimulationState gives."""
        return self.ok('GetSimulationState', self.srv.GetSimulationState.Request(),
                       'GetSimulationState').state.state

    def request_state(self, state: int):
        """Ask SetSimulationState for ``state``; return the reply, whatever its result."""
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        return self.call('SetSimulationState', request)

    def set_state(self, state: int) -> None:
        """Go to ``state``: OK or ALREADY_IN_TARGET_STATE, else ClauseFailed."""
        codes = (self.msg.Result.RESULT_OK,
                 self.srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE)
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        self.expect('SetSimulationState', request, codes,
                    f'SetSimulationState {self.state_name(state)}')

    def expect_state(self, state: int, after: str) -> None:
        """Raise ClauseFailed unless the state reads ``state`` (unchecked if not declared)."""
        if not self.declared('SIMULATION_STATE_GETTING'):
            return
        now = self.state()
        if now != state:
            raise ClauseFailed(f'after {after} the state reads {self.state_name(now)}, '
                               f'not {self.state_name(state)}')

    def stop(self) -> None:
        """Go to STOPPED."""
        self.set_state(self.S.STATE_STOPPED)

    def play(self) -> None:
        """Go to PLAYING."""
        self.set_state(self.S.STATE_PLAYING)

    def pause(self) -> None:
        """
        Go to PAUSED by a route every simulator takes: from STOPPED through PLAYING.

        The standard disagrees with itself on pausing a stopped simulation
        (SimulationState.msg allows it, SetSimulationState.srv calls it an
        incorrect transition), so the kit plays first.
        """
        S = self.S
        if self.declared('SIMULATION_STATE_GETTING'):
            now = self.state()
            if now == S.STATE_PAUSED:
                return
            if now != S.STATE_PLAYING:
                self.play()
        else:
            self.play()
        self.set_state(S.STATE_PAUSED)

    def step(self, steps: int) -> None:
        """Step ``steps`` times through StepSimulation (OK expected)."""
        self.ok('StepSimulation', self.srv.StepSimulation.Request(steps=steps),
                f'StepSimulation of {steps}')

    def advance(self, steps: int) -> None:
        """Step a paused simulation: StepSimulation where declared, else the action."""
        single = steps == 1 and self.declared('STEP_SIMULATION_SINGLE')
        multiple = steps > 1 and self.declared('STEP_SIMULATION_MULTIPLE')
        if (single or multiple) and 'StepSimulation' in self.interfaces:
            return self.step(steps)
        if self.declared('STEP_SIMULATION_ACTION'):
            status, result = self.run_goal(steps)
            if result.result.result != self.msg.Result.RESULT_OK:
                raise ClauseFailed(f'SimulateSteps of {steps}: {self.describe(None, result)}')
            return None
        raise ClauseSkipped('the simulator declares no way to step this many steps')

    def reset(self, scope: int) -> None:
        """Reset with ``scope`` (OK expected)."""
        self.ok('ResetSimulation', self.srv.ResetSimulation.Request(scope=scope),
                f'ResetSimulation scope {scope}')

    # -- entities ----------------------------------------------------------------------

    def filters(self, pattern: str = '', categories: Sequence[int] = (),
                tags: Sequence[str] = (), mode: int = 0,
                bounds: Optional[Tuple[int, list]] = None):
        """Return EntityFilters: a name regex, categories, tags (ANY 0 / ALL 1), (type, points)."""
        msg = self.msg
        filters = msg.EntityFilters(filter=pattern)
        filters.categories = [msg.EntityCategory(category=c) for c in categories]
        filters.tags = msg.TagsFilter(tags=list(tags), filter_mode=mode)
        if bounds is not None:
            kind, points = bounds
            filters.bounds = self.bounds(kind, points)
        return filters

    def bounds(self, kind: int, points: Sequence[Sequence[float]]):
        """Return a Bounds message of ``kind`` through ``points``."""
        from geometry_msgs.msg import Vector3
        return self.msg.Bounds(type=kind, points=[Vector3(x=float(p[0]), y=float(p[1]),
                                                          z=float(p[2])) for p in points])

    def names(self, filters=None, doing: str = 'GetEntities') -> List[str]:
        """Return GetEntities' names for ``filters`` (default: all)."""
        request = self.srv.GetEntities.Request()
        if filters is not None:
            request.filters = filters
        return list(self.ok('GetEntities', request, doing).entities)

    def entity_state(self, name: str):
        """Return GetEntityState's EntityState of ``name``."""
        return self.ok('GetEntityState', self.srv.GetEntityState.Request(entity=name),
                       f'GetEntityState of {name}').state

    def position(self, name: str) -> Tuple[float, float, float]:
        """Return the position GetEntityState gives ``name``."""
        return vector(self.entity_state(name).pose.position)

    def set_request(self, name: str, position: Sequence[float],
                    orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
                    linear: Sequence[float] = (0.0, 0.0, 0.0),
                    angular: Sequence[float] = (0.0, 0.0, 0.0), frame: str = '',
                    stamp: Tuple[int, int] = (0, 0)):
        """Return a SetEntityState request: a pose and a twist in ``frame``."""
        request = self.srv.SetEntityState.Request(entity=name)
        state = request.state
        state.header.frame_id = frame
        state.header.stamp.sec, state.header.stamp.nanosec = stamp
        fill_pose(state.pose, position, orientation)
        fill_vector(state.twist.linear, linear)
        fill_vector(state.twist.angular, angular)
        return request

    def place(self, name: str, position: Sequence[float], orientation=(0.0, 0.0, 0.0, 1.0),
              linear=(0.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0), frame: str = '') -> None:
        """Place ``name`` with SetEntityState (OK expected)."""
        self.ok('SetEntityState', self.set_request(name, position, orientation, linear, angular,
                                                   frame), f'SetEntityState of {name}')

    def info(self, name: str):
        """Return GetEntityInfo's EntityInfo of ``name``."""
        return self.ok('GetEntityInfo', self.srv.GetEntityInfo.Request(entity=name),
                       f'GetEntityInfo of {name}').info

    # -- spawning ----------------------------------------------------------------------

    def new_name(self, stem: str = 'box') -> str:
        """Return a name for something the kit spawns: ``conformance_box_7``."""
        return f'conformance_{stem}_{next(self._names)}'

    def slot(self, index: int, z_offset: float = 0.0) -> Tuple[float, float, float]:
        """Return the ``index``-th place for the kit's entities: 3 m apart along x, in the air."""
        x, y, z = self.options.free_space
        return (x + 3.0 * index, y, z + z_offset)

    def resource_format(self) -> Optional[str]:
        """Return 'urdf' or 'sdf' when the kit may spawn from a resource string, else None."""
        if not self.declared('SPAWNING_RESOURCE_STRING'):
            return None
        for fmt in ('urdf', 'sdf'):
            if fmt in self.spawn_formats:
                return fmt
        return None

    def box_text(self, name: str, fmt: Optional[str] = None, size: float = BOX_SIZE_M) -> str:
        """Return the kit's box (``size`` wide, 1 kg) named ``name``, as URDF or SDF text."""
        fmt = fmt or self.resource_format() or 'urdf'
        inertia = size * size / 6.0
        geometry = f'<box size="{size} {size} {size}"/>'
        if fmt == 'sdf':
            return (f'<?xml version="1.0"?><sdf version="1.6"><model name="{name}"><link '
                    f'name="box"><inertial><mass>1</mass><inertia><ixx>{inertia}</ixx><iyy>'
                    f'{inertia}</iyy><izz>{inertia}</izz></inertia></inertial><collision '
                    f'name="c"><geometry><box><size>{size} {size} {size}</size></box>'
                    f'</geometry></collision><visual name="v"><geometry><box><size>{size} '
                    f'{size} {size}</size></box></geometry></visual></link></model></sdf>')
        return (f'<?xml version="1.0"?><robot name="{name}"><link name="box"><inertial><mass '
                f'value="1"/><inertia ixx="{inertia}" iyy="{inertia}" izz="{inertia}" ixy="0" '
                f'ixz="0" iyz="0"/></inertial><collision><geometry>{geometry}</geometry>'
                f'</collision><visual><geometry>{geometry}</geometry></visual></link></robot>')

    def need_resource_string(self) -> str:
        """Return the resource format; ClauseSkipped when the kit cannot send its own box."""
        fmt = self.resource_format()
        if fmt is None:
            raise ClauseSkipped('needs a resource string the kit can write: '
                                'SPAWNING_RESOURCE_STRING and urdf or sdf in spawn_formats')
        return fmt

    def source(self, name: str) -> Tuple[str, str]:
        """Return (uri, resource_string) for a spawn: the kit's box, else ``--asset``."""
        if self.resource_format() is not None:
            return '', self.box_text(name)
        if self.options.asset:
            return self.options.asset, ''
        raise ClauseSkipped('nothing to spawn: give --asset URI (or declare '
                            'SPAWNING_RESOURCE_STRING with urdf or sdf in spawn_formats)')

    def spawn_request(self, name: str, position: Sequence[float],
                      orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0), *,
                      uri: Optional[str] = None, resource: Optional[str] = None,
                      frame: str = '', allow_renaming: bool = False, namespace: str = '',
                      stamp: Tuple[int, int] = (0, 0)):
        """Return a SpawnEntity request; without ``uri`` and ``resource``, from :meth:`source`."""
        if uri is None and resource is None:
            uri, resource = self.source(name)
        request = self.srv.SpawnEntity.Request(
            name=name, allow_renaming=allow_renaming, uri=uri or '',
            resource_string=resource or '', entity_namespace=namespace)
        pose = request.initial_pose
        pose.header.frame_id = frame
        pose.header.stamp.sec, pose.header.stamp.nanosec = stamp
        fill_pose(pose.pose, position, orientation)
        return request

    def spawn_call(self, request, codes: Optional[Sequence[int]] = None, doing: str = ''):
        """Send a SpawnEntity request; keep the name if it spawned; return the reply."""
        codes = codes or (self.msg.Result.RESULT_OK,)
        reply = self.expect('SpawnEntity', request, codes,
                            doing or f'SpawnEntity of {request.name or "(no name)"}')
        if reply.result.result == self.msg.Result.RESULT_OK and reply.entity_name:
            self.spawned.append(reply.entity_name)
        return reply

    def spawn(self, index: int = 0, *, name: Optional[str] = None, yaw: float = 0.0,
              position: Optional[Sequence[float]] = None, frame: str = '') -> str:
        """
        Spawn the kit's box (or ``--asset``) at slot ``index``; return its name.

        Without allow_renaming, so the name must come back as asked.
        """
        name = name or self.new_name()
        request = self.spawn_request(name, position or self.slot(index), yaw_quaternion(yaw),
                                     frame=frame)
        got = self.spawn_call(request).entity_name
        if got != name:
            raise ClauseFailed(f'spawned {name!r} without allow_renaming and got back the '
                               f'name {got!r}')
        return got

    def delete(self, name: str) -> None:
        """Delete ``name`` (OK expected)."""
        self.ok('DeleteEntity', self.srv.DeleteEntity.Request(entity=name),
                f'DeleteEntity of {name}')
        if name in self.spawned:
            self.spawned.remove(name)

    # -- the clock ---------------------------------------------------------------------

    def need_clock(self) -> None:
        """Raise ClauseSkipped when nobody publishes the clock topic."""
        if not self.has_clock:
            raise ClauseSkipped(f'no {self.options.clock_topic} publisher')

    def clock_settled(self) -> Optional[int]:
        """
        Return the latest clock after one round trip to the simulator.

        A /clock published before a reply may arrive after it (another
        writer): the round trip gives it the time to come.
        """
        self.call('GetSimulatorFeatures', self.srv.GetSimulatorFeatures.Request())
        self._drain_clock()
        return self._clock_ns

    def _drain_clock(self) -> None:
        """Take every /clock message already received: one spin_once runs one callback."""
        for _ in range(DRAIN_SPINS):
            seen = self._clock_count
            self.probe.executor.spin_once(timeout_sec=0.0)
            if self._clock_count == seen:
                self.probe.executor.spin_once(timeout_sec=0.0)  # another callback ran first?
                if self._clock_count == seen:
                    return

    def clock_after(self, action: Callable[[], None], doing: str) -> int:
        """Run ``action``, then wait for a clock newer than before it; return the clock after."""
        before = self.clock_settled()
        action()
        if not self.probe.spin_until(
                lambda: self._clock_ns is not None and (before is None or self._clock_ns > before),
                self.timeout_s):
            raise ClauseFailed(f'{self.options.clock_topic} did not move within '
                               f'{self.timeout_s:g} s after {doing} (it read {before} ns)')
        return self.clock_settled()

    def step_ns(self) -> Tuple[int, int]:
        """
        Return (the clock now, one step's length), a paused simulation stepped three times.

        The first step lets /clock messages from before it arrive.
        """
        self.clock_after(lambda: self.advance(1), 'one step')
        t0 = self.clock_after(lambda: self.advance(1), 'one step')
        t1 = self.clock_after(lambda: self.advance(1), 'one step')
        return t1, t1 - t0

    def expect_clock(self, expected_ns: int, steps: int, doing: str) -> int:
        """Raise ClauseFailed unless the clock comes to ``expected_ns`` (a ns a step)."""
        tolerance = steps + 1
        self.probe.spin_until(lambda: self._clock_ns is not None
                              and self._clock_ns >= expected_ns - tolerance, self.timeout_s)
        got = self.clock_settled()
        if got is None or abs(got - expected_ns) > tolerance:
            raise ClauseFailed(f'after {doing}, {self.options.clock_topic} reads {got} ns, '
                               f'expected {expected_ns} ns')
        return got

    def expect_time_back(self, before_ns: int, doing: str) -> None:
        """Raise ClauseFailed unless a step from here reads a time before ``before_ns``."""
        got = self.clock_after(lambda: self.advance(1), f'{doing} and one step')
        if got >= before_ns:
            raise ClauseFailed(f'after {doing}, one step reads {got} ns on '
                               f'{self.options.clock_topic}: time did not go back from '
                               f'{before_ns} ns')

    # -- the action --------------------------------------------------------------------

    def action_client(self):
        """Return a ready client of the SimulateSteps action, with feedback kept."""
        from rclpy.action import ActionClient
        if self._action_client is None:
            name = self.interfaces.get(ACTION)
            if name is None:
                raise ClauseFailed(f'no SimulateSteps action under {self.prefix!r}')
            self._action_client = ActionClient(self.node, self.action.SimulateSteps, name)
            feedback = self.action.SimulateSteps.Impl.FeedbackMessage
            self._feedback_subscription = self.node.create_subscription(
                feedback, f'{name}/_action/feedback', self._keep_feedback, 1000)
        client = self._action_client
        if not self.probe.spin_until(
                lambda: client.server_is_ready()
                and self._feedback_subscription.get_publisher_count() > 0, self.timeout_s):
            raise ClauseFailed(f'the SimulateSteps action was not ready within '
                               f'{self.timeout_s:g} s')
        return client

    def _keep_feedback(self, message) -> None:
        self._feedback.append((bytes(message.goal_id.uuid), message.feedback.completed_steps,
                               message.feedback.remaining_steps))

    def feedback_of(self, handle) -> List[Tuple[int, int]]:
        """Return the (completed, remaining) feedback seen for a goal, in order."""
        uuid = bytes(handle.goal_id.uuid)
        return [(done, left) for goal, done, left in self._feedback if goal == uuid]

    def send_goal(self, steps: int):
        """Send a SimulateSteps goal; return its handle (``accepted`` says whether it was)."""
        client = self.action_client()
        sent = client.send_goal_async(self.action.SimulateSteps.Goal(steps=steps))
        if not self.probe.spin_until(sent.done, self.timeout_s):
            raise ClauseFailed('a SimulateSteps goal was not answered within '
                               f'{self.timeout_s:g} s')
        return sent.result()

    def goal_result(self, handle, timeout_s: Optional[float] = None):
        """Wait for a goal's end; return (status, SimulateSteps.Result)."""
        future = handle.get_result_async()
        timeout = timeout_s or self.timeout_s
        if not self.probe.spin_until(future.done, timeout):
            raise ClauseFailed(f'a SimulateSteps goal did not end within {timeout:g} s')
        return future.result().status, future.result().result

    def run_goal(self, steps: int):
        """Run a SimulateSteps goal to its end; return (status, result); a refusal fails."""
        handle = self.send_goal(steps)
        if not handle.accepted:
            raise ClauseFailed(f'a SimulateSteps goal of {steps} was rejected (a rejected goal '
                               'carries no Result)')
        return self.goal_result(handle)

    def status_name(self, status: int) -> str:
        """Name a GoalStatus value: CANCELED (5)."""
        for name in dir(self.GoalStatus):
            if name.startswith('STATUS_') and getattr(self.GoalStatus, name) == status:
                return f'{name[7:]} ({status})'
        return f'status {status}'

    # -- before and after each clause ----------------------------------------------------

    def on_cleanup(self, undo: Callable[[], None]) -> None:
        """Run ``undo`` after the clause, pass or fail (last registered first)."""
        self._cleanups.append(undo)

    def prepare(self, stop: bool = True) -> None:
        """
        Forget the last clause; with ``stop``, put the simulator in the start state: STOPPED.

        Through SetSimulationState where declared (STOPPED is "pausing and
        resetting with ALL"), else a full ResetSimulation where that is.
        """
        self._cleanups.clear()
        self.spawned.clear()
        self._feedback.clear()
        if not stop:
            return
        if self.declared('SIMULATION_STATE_SETTING'):
            self.stop()
        elif self.declared('SIMULATION_RESET'):
            self.reset(0)

    def cleanup(self) -> List[str]:
        """Undo what the clause did; return what could not be undone (one line each)."""
        problems = []
        while self._cleanups:
            try:
                self._cleanups.pop()()
            except (ClauseFailed, ClauseSkipped) as exc:
                problems.append(str(exc))
        if self.spawned and self.declared('DELETING'):
            try:
                present = set(self.names())
            except ClauseFailed as exc:
                return problems + [str(exc)]
            for name in list(self.spawned):
                if name in present:
                    try:
                        self.delete(name)
                    except ClauseFailed as exc:
                        problems.append(str(exc))
        self.spawned.clear()
        return problems

    def load_world(self, resource, doing: str):
        """Load the world of a Resource (uri or resource_string), OK expected; return the reply."""
        request = self.srv.LoadWorld.Request(uri=resource.uri,
                                             resource_string=resource.resource_string)
        self.world_changed = True
        return self.ok('LoadWorld', request, doing)

    def unload_world(self) -> None:
        """UnloadWorld, OK expected."""
        self.world_changed = True
        self.ok('UnloadWorld', self.srv.UnloadWorld.Request(), 'UnloadWorld')

    def put_world_back(self) -> None:
        """
        Load the world found at the start again (or unload, if there was none).

        Without WORLD_INFO_GETTING the kit cannot know it: the last world it
        loaded stays.
        """
        if not self.world_changed or not self.initial_world_known:
            return
        world = self.initial_world
        resource = world.world_resource if world is not None else None
        if resource is not None and (resource.uri or resource.resource_string):
            self.load_world(resource, 'LoadWorld of the world found at the start')
        elif world is None and self.declared('WORLD_UNLOADING'):
            no_world = self.srv.UnloadWorld.Response.NO_WORLD_LOADED
            self.expect('UnloadWorld', self.srv.UnloadWorld.Request(),
                        (self.msg.Result.RESULT_OK, no_world), 'UnloadWorld, as at the start')
        self.world_changed = False

    def restore(self) -> List[str]:
        """
        Leave the simulator as found: the world loaded again, the state it was in.

        Returns what could not be restored. The time, the entities and the
        poses are those of a fresh start (the clauses reset them).
        """
        problems = self.cleanup()
        try:
            self.put_world_back()
            if self.initial_state is not None and self.declared('SIMULATION_STATE_SETTING'):
                S = self.S
                self.stop()
                if self.initial_state == S.STATE_PLAYING:
                    self.play()
                elif (self.initial_state == S.STATE_PAUSED
                      and self.declared('SIMULATION_STATE_PAUSE')):
                    self.pause()
        except (ClauseFailed, ClauseSkipped) as exc:
            problems.append(str(exc))
        return problems


def fill_pose(pose, position: Sequence[float], orientation: Sequence[float]) -> None:
    """Write a position and an (x, y, z, w) orientation into a geometry_msgs Pose."""
    fill_vector(pose.position, position)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (float(v) for v in orientation)


def fill_vector(target, values: Sequence[float]) -> None:
    """Write three numbers into a Vector3 or Point."""
    target.x, target.y, target.z = (float(v) for v in values)
