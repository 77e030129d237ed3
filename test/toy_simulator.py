"""
A toy simulator of ROS 2's simulation standard, right by default and wrong on demand.

It serves all 22 services and the action of ``simulation_interfaces`` (Jazzy
1.5) in a context of its own, from a thread of its own, under ``/toy`` with
names of its own choosing (``/toy/SpawnEntity``, as Isaac Sim 5 names them):
the conformance kit must find them by type. There is no physics: bodies are
boxes that move along their twist while time runs, one step is 10 ms, and
``/clock`` is published after every step. Two worlds, ``yard`` and ``hall``,
each with start-up entities and named poses.

``ToySimulator(domain_id, defect='STATE-08')`` breaks the one behaviour that
clause checks, the way a real implementation got it wrong where one did
(answering OK to the current state as Gazebo and Isaac Sim do, stepping while
playing as Gazebo does, the twist in the entity's frame as O3DE does,
``steps=1`` taken as 2 as Isaac Sim 5 did, the requested name returned after
a rename as Gazebo does...). :data:`DEFECTS` says, for each clause id, what
its defect is. Everything else stays right, so the kit's clause fails and,
with no defect, every clause passes. :data:`MORE_DEFECTS` are violations an
audit of the kit injected that a clause's own defect does not cover, each
with the clauses that must fail on it; :data:`VARIANTS` are readings the
standard allows besides the toy's own, each with the clauses that must still
pass; :data:`HOSTILE` are a simulator that answers slowly or hugely, which the
kit must outlast.

``prefix`` is the namespace the toy serves in (``/`` is the root): two toys on
one domain are two simulators, and ``changes`` counts the requests that
would change a toy (the kit must never send one to a toy it was not meant for).
"""

import math
import re
import threading
import time
from typing import Dict, List, Optional, Sequence, Tuple
import xml.etree.ElementTree as ElementTree

from action_msgs.msg import GoalStatus  # noqa: F401 (documents the statuses used)
from geometry_msgs.msg import Vector3
import rclpy
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from simulation_interfaces import action, msg, srv

from r2d2_sim.model.transforms import compose, rotate, rotate_inverse, Transform

DT_NS = 10_000_000
PREFIX = '/toy'
WORLD_LIMIT_M = 1000.0
R = msg.Result
S = msg.SimulationState
F = msg.SimulatorFeatures
C = msg.EntityCategory
B = msg.Bounds

# What each clause's defect is: the toy's own wrong behaviour, one per clause.
DEFECTS: Dict[str, str] = {
    'FEAT-01': 'GetSimulatorFeatures is not served',
    'FEAT-02': 'declares the feature value 99',
    'FEAT-03': 'declares ENTITY_BOUNDS without serving GetEntityBounds',
    'FEAT-04': 'serves GetNamedPoses without declaring NAMED_POSES (advisory: noted, passes)',
    'FEAT-05': 'declares SIMULATION_RESET_TIME without SIMULATION_RESET',
    'RESULT-01': 'GetSimulationState leaves its Result at 0',
    'RESULT-02': 'GetEntities leaves its Result at 0',
    'RESULT-03': 'GetEntitiesStates leaves its Result at 0',
    'RESULT-04': 'GetSpawnables leaves its Result at 0',
    'RESULT-05': 'GetEntityState of an unknown entity is OPERATION_FAILED',
    'RESULT-06': 'SetEntityState of an unknown entity is OK',
    'RESULT-07': 'GetEntityInfo of an unknown entity answers 0',
    'RESULT-08': 'SetEntityInfo of an unknown entity is OPERATION_FAILED',
    'RESULT-09': 'GetEntityBounds of an unknown entity is OK, empty',
    'RESULT-10': 'DeleteEntity of an unknown entity is OK',
    'RESULT-11': 'GetNamedPoseBounds of an unknown pose is OPERATION_FAILED',
    'STATE-01': 'GetSimulationState answers 9',
    'STATE-02': 'a stopped simulation reads PAUSED',
    'STATE-03': 'PLAYING from STOPPED answers OK and stays STOPPED',
    'STATE-04': 'PAUSED from PLAYING answers OK and keeps playing (pause and play swapped)',
    'STATE-05': 'STOPPED from PLAYING is STATE_TRANSITION_ERROR',
    'STATE-06': 'PLAYING from PAUSED is INCORRECT_TRANSITION',
    'STATE-07': 'STOPPED from PAUSED only pauses',
    'STATE-08': 'STOPPED when stopped answers OK (Gazebo, Isaac Sim)',
    'STATE-09': 'PLAYING when playing answers OK',
    'STATE-10': 'PAUSED when paused answers OK',
    'STATE-11': 'PAUSED from STOPPED answers OK and stays STOPPED (Gazebo)',
    'STATE-12': 'an undefined state answers OK',
    'STATE-13': 'STOPPED keeps spawned entities',
    'STATE-14': 'STOPPED keeps the time',
    'STEP-01': 'one step is OPERATION_FAILED',
    'STEP-02': 'several steps leave the Result at 0',
    'STEP-03': 'stepping resumes playing afterwards',
    'STEP-04': 'a step while playing pauses, steps and answers OK (Gazebo)',
    'STEP-05': 'a step refused while playing leaves it paused',
    'STEP-06': 'single steps alternate between one and two steps of time',
    'STEP-07': 'steps=1 takes two steps (Isaac Sim 5)',
    'ACTION-01': 'a goal succeeds with its Result at 0',
    'ACTION-02': 'feedback says every step remains',
    'ACTION-03': 'a goal while playing is rejected',
    'ACTION-04': 'a cancel is accepted, and the goal ends ABORTED',
    'ACTION-05': 'a goal resumes playing afterwards',
    'ACTION-06': 'a goal steps one step fewer than asked',
    'RESET-01': 'scope 0 is FEATURE_UNSUPPORTED (named scopes only)',
    'RESET-02': 'scope 0 keeps spawned entities',
    'RESET-03': 'scope 255 keeps spawned entities',
    'RESET-04': 'scope 0 keeps the time',
    'RESET-05': 'SCOPE_TIME resets the state instead of the time',
    'RESET-06': 'SCOPE_TIME resets everything (the scope ignored)',
    'RESET-07': 'SCOPE_STATE puts back only start-up entities',
    'RESET-08': 'SCOPE_STATE keeps velocities',
    'RESET-09': 'SCOPE_STATE removes spawned entities',
    'RESET-10': 'SCOPE_STATE resets the time too',
    'RESET-11': 'SCOPE_SPAWNED does nothing',
    'RESET-12': 'SCOPE_SPAWNED also removes the start-up robot',
    'RESET-13': 'a combination of scopes is NOT_FOUND (O3DE)',
    'SPAWN-01': 'a spawn by uri returns its name with a leading / (Isaac Sim)',
    'SPAWN-02': 'a spawn from text is listed under another name than returned',
    'SPAWN-03': 'an empty name gets a generated name, not the file\'s',
    'SPAWN-04': 'a taken name is renamed without allow_renaming',
    'SPAWN-05': 'a renamed entity is returned under the requested name (Gazebo)',
    'SPAWN-06': 'no name at all gets a generated name without allow_renaming',
    'SPAWN-07': 'resource_string wins over uri',
    'SPAWN-08': 'no resource is OPERATION_FAILED',
    'SPAWN-09': 'a zero quaternion is taken as no turn',
    'SPAWN-10': 'a NaN position is taken',
    'SPAWN-11': 'spawns 0.1 m above the initial_pose (ground clearance)',
    'SPAWN-12': 'the initial_pose frame is ignored',
    'SPAWN-13': 'an unknown frame is taken as the world',
    'SPAWN-14': 'the namespace is not checked',
    'SPAWN-15': 'a resource that does not parse is OPERATION_FAILED',
    'SPAWN-16': 'a resource in no format is OPERATION_FAILED',
    'SPAWN-17': 'a stamped initial_pose is INVALID_POSE',
    'BATCH-01': 'results come in reverse order',
    'BATCH-02': 'a batch with a failure answers OK',
    'BATCH-03': 'a batch with a failure spawns nothing (all or nothing)',
    'BATCH-04': 'one name twice in a batch is renamed',
    'DELETE-01': 'DeleteEntity answers OK and keeps the entity',
    'DELETE-02': 'DeleteEntity removes every spawned entity',
    'SPAWNABLES-01': 'a spawnable has no uri',
    'SPAWNABLES-02': 'an unknown source is NOT_FOUND',
    'SPAWNABLES-03': 'GetSpawnables lists a cube that cannot be spawned',
    'ENTITY-01': 'GetEntities lists the ground twice',
    'ENTITY-02': 'GetEntitiesStates leaves out the states of static entities',
    'ENTITY-03': 'GetEntityState answers in frame map',
    'ENTITY-04': 'GetEntitiesStates gives the centre of mass, 5 cm above the link',
    'ENTITY-05': 'SetEntityState keeps the old orientation',
    'ENTITY-06': 'GetEntityState gives the twist in the entity\'s frame (O3DE)',
    'ENTITY-07': 'a pose in an entity\'s frame is taken in the world',
    'ENTITY-08': 'a twist in an entity\'s frame is taken along the world axes',
    'ENTITY-09': 'a zero twist keeps the entity moving',
    'ENTITY-10': 'a zero quaternion is taken as no turn',
    'ENTITY-11': 'a NaN position is taken',
    'ENTITY-12': 'a static entity takes a twist',
    'ENTITY-13': 'the robot has category 3, which does not exist',
    'ENTITY-14': 'a stamped SetEntityState is INVALID_POSE',
    'ENTITY-15': 'SetEntityInfo drops the tags',
    'BOUNDS-01': 'a box of one point',
    'BOUNDS-02': 'bounds in the world frame (an AABB where the entity is)',
    'BOUNDS-03': 'bounds of half the entity',
    'FILTER-01': 'the filter is a plain substring, not a regex',
    'FILTER-02': 'the filter knows only ^, $ and plain text',
    'FILTER-03': 'GetEntitiesStates ignores the filters',
    'FILTER-04': 'the category filter is ignored',
    'FILTER-05': 'categories must all match',
    'FILTER-06': 'the sphere filter is ignored',
    'FILTER-07': 'the box filter is ignored',
    'FILTER-08': 'the convex hull filter is FEATURE_UNSUPPORTED though declared',
    'FILTER-09': 'an undeclared box filter answers OK with everything',
    'FILTER-10': 'ANY works as ALL',
    'FILTER-11': 'ALL works as ANY',
    'FILTER-12': 'the filters combine with OR',
    'NAMED-01': 'two named poses share a name',
    'NAMED-02': 'the named poses\' tags filter is ignored',
    'NAMED-03': 'the named poses\' ALL works as ANY',
    'NAMED-04': 'a named pose\'s bounds are a sphere of one point',
    'NAMED-05': 'the first named pose lies beyond the world\'s bounds',
    'WORLD-01': 'an available world has neither uri nor resource_string',
    'WORLD-02': 'the worlds\' tags filter is ignored',
    'WORLD-03': 'GetCurrentWorld is NO_WORLD_LOADED with a world loaded',
    'WORLD-04': 'LoadWorld answers OK with an empty world',
    'WORLD-05': 'LoadWorld keeps the simulation playing',
    'WORLD-06': 'LoadWorld keeps spawned entities',
    'WORLD-07': 'GetCurrentWorld names the world of the start after LoadWorld',
    'WORLD-08': 'LoadWorld of nothing is OPERATION_FAILED',
    'WORLD-09': 'LoadWorld of a broken string loads an empty world',
    'WORLD-10': 'GetCurrentWorld names the old world after UnloadWorld',
    'WORLD-11': 'UnloadWorld with no world answers OK',
    'WORLD-12': 'with no world the state reads STOPPED',
    'WORLD-13': 'with no world PLAYING answers OK',
    'WORLD-14': 'UnloadWorld keeps spawned entities',
}

# Violations beyond each clause's own defect, with the clauses that must fail on each.
MORE_DEFECTS: Dict[str, Tuple[str, Tuple[str, ...]]] = {
    'NAMED-empty': ('GetNamedPoses always answers an empty list',
                    ('NAMED-01', 'NAMED-02', 'NAMED-03', 'NAMED-04', 'NAMED-05')),
    'ENTITY-04-order': ('GetEntitiesStates gives the spawned entities\' states in reverse order',
                        ('ENTITY-04',)),
    'TIME-half': ('a reset of the time takes it back by half, not to the start',
                  ('STATE-14', 'RESET-04', 'RESET-05', 'RESET-13')),
    'TIME-zero-on-play': ('STOPPED keeps the time, and a clock of 0 goes out as it plays',
                          ('STATE-14',)),
    'TIME-zero-while-stopped': ('STOPPED keeps the time, and the clock says 0 while stopped',
                                ('STATE-14',)),
    'BOUNDS-constant': ('GetEntityBounds gives every entity the same 1 m box', ('BOUNDS-03',)),
    'FILTER-12-name': ('the name filter is ignored when another filter is given',
                       ('FILTER-12',)),
    'WORLD-13-others': ('with no world, STOPPED and PAUSED answer OK (only PLAYING is refused)',
                        ('WORLD-13',)),
    'ACTION-02-once': ('SimulateSteps gives one feedback a goal, at its end, not one a step',
                       ('ACTION-02',)),
    'ENTITY-12-acceleration': ('a static entity takes an acceleration (only a twist is checked)',
                               ('ENTITY-12',)),
}
# Readings the standard allows that the toy takes on demand, each with the clauses that
# must still pass: the kit may not hold a simulator to one way where the text allows more.
VARIANTS: Dict[str, Tuple[str, Tuple[str, ...]]] = {
    'BOX-AS-WRITTEN': ('a TYPE_BOX filter\'s points are read in Bounds.msg\'s order: the upper '
                       'corner, then the lower', ('FILTER-07',)),
    'CANCEL-REFUSED': ('a cancel is rejected, as a ROS 2 action server may', ('ACTION-04',)),
    'WORLD-NO-URI': ('GetCurrentWorld names the world loaded without its uri or resource '
                     'string (the kit cannot load it back, so it loads no other)',
                     ('WORLD-03', 'WORLD-08')),
    'CLOCK-EVERY-5': ('/clock goes out at every fifth step only (and at a reset of the time), '
                      'as r2d2_sim\'s with a publish_rate below its physics rate',
                      ('STATE-14', 'STEP-06', 'STEP-07', 'ACTION-06', 'RESET-04', 'RESET-05',
                       'RESET-10', 'RESET-13')),
}
# A hostile simulator: what the kit must bound (its time, what it prints).
HOSTILE: Dict[str, str] = {
    'SLOW': 'every reply comes after 0.5 s',
    'SLOW-PAUSE': 'PAUSED is taken 0.5 s after it is asked, the time running meanwhile',
    'HUGE': 'replies of megabytes: a spawn format, an entity name, a frame, error messages',
}
HUGE_TEXT = 2_000_000  # characters of each huge string
SLOW_S = 0.5
HOLD_S = 60.0  # longest a held request waits for its release
# The requests that change a simulator.
CHANGES = {'SetSimulationState', 'StepSimulation', 'ResetSimulation', 'SetEntityState',
           'SetEntityInfo', 'SpawnEntity', 'SpawnEntities', 'DeleteEntity', 'LoadWorld',
           'UnloadWorld'}

INVALID_POSE_SET = srv.SetEntityState.Response.INVALID_POSE
# A handler returns this to leave its reply's Result at 0 ("unsupported").
LEAVE_ZERO = object()
# Features a defect leaves undeclared.
UNDECLARED = {'FEAT-04': 'NAMED_POSES', 'FEAT-05': 'SIMULATION_RESET',
              'FILTER-09': 'ENTITY_BOUNDS_BOX'}

ALL_FEATURES = [getattr(F, name) for name in dir(F)
                if name.isupper() and isinstance(getattr(F, name), int)]


class Entity:
    """A box: pose, twist, what it is; where it started."""

    def __init__(self, category: int, position, orientation=(0.0, 0.0, 0.0, 1.0),
                 half=(0.1, 0.1, 0.1), static: bool = False, spawned: bool = False,
                 description: str = '', tags=()) -> None:
        self.category = category
        self.position, self.orientation = tuple(position), tuple(orientation)
        self.linear, self.angular = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        self.half, self.static, self.spawned = tuple(half), static, spawned
        self.description, self.tags = description, list(tags)
        self.start = (self.position, self.orientation)

    def aabb(self):
        """Return the world box around it (a turn is ignored: the toy's boxes are small)."""
        low = tuple(p - h for p, h in zip(self.position, self.half))
        high = tuple(p + h for p, h in zip(self.position, self.half))
        return low, high


WORLDS = {
    'yard': {'uri': 'toy://worlds/yard', 'tags': ['outdoor'], 'description': 'a yard',
             'entities': {'tree': ((5.0, 5.0, 1.0), (0.3, 0.3, 1.0))},
             'poses': [('gate', (1.0, 2.0, 0.0), 0.5, ['spawn', 'door']),
                       ('dock', (-3.0, 1.0, 0.0), 0.0, ['parking', 'spawn']),
                       ('start', (0.0, 0.0, 0.0), 0.0, [])]},
    'hall': {'uri': 'toy://worlds/hall', 'tags': ['indoor', 'big'], 'description': 'a hall',
             'entities': {'shelf': ((2.0, 0.0, 1.0), (0.2, 1.0, 1.0))},
             'poses': [('entrance', (0.0, -2.0, 0.0), 0.0, ['spawn'])]},
}
ASSETS = {'toy://box': ('toy_box', (0.1, 0.1, 0.1)), 'toy://crate': ('toy_crate', (0.25,) * 3)}
NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')


def yaw_q(yaw: float):
    """Return the quaternion of a turn by ``yaw`` about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def _finite(*values) -> bool:
    return all(math.isfinite(v) for v in values)


class Refused(Exception):
    """A request the toy refuses: a result code and a message."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


class ToySimulator:
    """
    The standard's services and action on a node under ``/toy``, spun in a thread.

    ``defect``: a clause id of :data:`DEFECTS` (None: right everywhere).
    ``without``: features it leaves undeclared (``ENTITY_BOUNDS_BOX``) and
    services it does not serve (``GetEntities``, which no feature stands for).
    ``world``: the world it starts with (None: none, the state NO_WORLD).
    ``hold``: an interface (``GetEntities``) whose requests wait for
    :attr:`release` before they are answered (:attr:`held` counts them).
    Close it (or use it as a context manager).
    """

    def __init__(self, domain_id: int, defect: Optional[str] = None,
                 without: Sequence[str] = (), prefix: str = PREFIX,
                 world: Optional[str] = 'yard', hold: Optional[str] = None) -> None:
        if defect is not None and not (defect in DEFECTS or defect in MORE_DEFECTS
                                       or defect in HOSTILE or defect in VARIANTS):
            raise ValueError(f'no defect for {defect!r}')
        self.changes = 0  # requests received that change the simulation
        # Requests of interface ``hold`` are answered only once ``release`` is set: a test
        # knows the kit waits for that reply (``held`` counts them) until it lets it go.
        self.hold = hold
        self.held = 0
        self.release = threading.Event()
        self.defect = defect
        # Features left undeclared, and refused as FEATURE_UNSUPPORTED where they are parts.
        self.without = set(without) | ({UNDECLARED[defect]} if defect in UNDECLARED else set())
        self.lock = threading.RLock()
        self.state = S.STATE_STOPPED if world is not None else S.STATE_NO_WORLD
        self.step_count = 0
        self.time_offset_ns = 0  # what STEP-06's defect adds
        self.single_steps = 0
        self.world: Optional[str] = 'yard'
        self.entities: Dict[str, Entity] = {}
        self.generation = 0  # a reset or a stop ends a running goal
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node('toy_simulator', namespace=prefix, context=self.context,
                         start_parameter_services=False)
        self.clock = self.node.create_publisher(Clock, '/clock', 10)
        group = ReentrantCallbackGroup()
        for kind in ('GetSimulatorFeatures', 'GetSimulationState', 'SetSimulationState',
                     'StepSimulation', 'ResetSimulation', 'GetEntities', 'GetEntitiesStates',
                     'GetEntityState', 'SetEntityState', 'GetEntityInfo', 'SetEntityInfo',
                     'GetEntityBounds', 'SpawnEntity', 'SpawnEntities', 'DeleteEntity',
                     'GetSpawnables', 'GetNamedPoses', 'GetNamedPoseBounds', 'LoadWorld',
                     'UnloadWorld', 'GetCurrentWorld', 'GetAvailableWorlds'):
            if (kind, defect) in (('GetSimulatorFeatures', 'FEAT-01'),
                                  ('GetEntityBounds', 'FEAT-03')) or kind in self.without:
                continue
            self.node.create_service(getattr(srv, kind), kind,
                                     self._answer(getattr(self, '_' + kind), kind),
                                     callback_group=group)
        self.action_server = ActionServer(
            self.node, action.SimulateSteps, 'SimulateSteps', self._simulate_steps,
            goal_callback=self._goal, cancel_callback=self._cancel, callback_group=group)
        self.node.create_timer(DT_NS / 1e9, self._tick, callback_group=group)
        self._load_world(world)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self._closing = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while not self._closing.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Stop spinning; destroy the node; shut the context down."""
        self.release.set()  # a held request is answered, so that its thread ends
        self._closing.set()
        self.thread.join(timeout=5.0)
        # rclpy 7.1.6's Executor.shutdown does not wait for the callbacks under way
        # (it tests _is_shutdown right after setting it) and destroys the guard
        # condition each of them triggers when it ends: wait for its thread pool
        # first, so that no callback runs on what is destroyed next.
        self.executor._executor.shutdown(wait=True)
        self.executor.shutdown(timeout_sec=5.0)
        self.action_server.destroy()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> 'ToySimulator':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def broken(self, clause_id: str) -> bool:
        """Return True when the toy is to get this clause wrong."""
        return self.defect == clause_id

    # -- time --------------------------------------------------------------------------

    @property
    def time_ns(self) -> int:
        """Return the simulated time."""
        return self.step_count * DT_NS + self.time_offset_ns

    def _step(self, publish: bool = True) -> None:
        with self.lock:
            self.step_count += 1
            dt = DT_NS / 1e9
            for entity in self.entities.values():
                if not entity.static:
                    entity.position = tuple(p + v * dt for p, v in
                                            zip(entity.position, entity.linear))
            if publish:
                self._publish_clock()

    def _publish_clock(self, always: bool = False) -> None:
        if self.broken('CLOCK-EVERY-5') and self.step_count % 5 and not always:
            return
        message = Clock()
        message.clock.sec, message.clock.nanosec = divmod(self.time_ns, 10**9)
        self.clock.publish(message)

    def _tick(self) -> None:
        with self.lock:
            if self.state == S.STATE_PLAYING:
                self._step()
            elif self.state == S.STATE_STOPPED and self.broken('TIME-zero-while-stopped'):
                self.clock.publish(Clock())  # 0 while stopped; playing goes on from the old time

    # -- worlds and resets -------------------------------------------------------------

    def _load_world(self, key: Optional[str]) -> None:
        """Empty the world and fill it with ``key``'s start-up entities (None: no world)."""
        self.world = key
        self.entities = {}
        if key is None:
            return
        self.entities['ground'] = Entity(C.CATEGORY_STATIC_OBJECT, (0.0, 0.0, -0.05),
                                         half=(50.0, 50.0, 0.05), static=True,
                                         description='the ground', tags=['ground'])
        self.entities['toy_bot'] = Entity(C.CATEGORY_ROBOT, (0.0, 0.0, 0.1),
                                          half=(0.2, 0.2, 0.1), description='a robot',
                                          tags=['robot'])
        for name, (position, half) in WORLDS.get(key, {}).get('entities', {}).items():
            self.entities[name] = Entity(C.CATEGORY_STATIC_OBJECT, position, half=half,
                                         static=True)

    def _reset(self, time: bool, state: bool, spawned: bool) -> None:
        with self.lock:
            self.generation += 1
            if spawned:
                self.entities = {n: e for n, e in self.entities.items() if not e.spawned}
            if state:
                for entity in self.entities.values():
                    if entity.spawned and self.broken('RESET-07'):
                        continue
                    entity.position, entity.orientation = entity.start
                    if not self.broken('RESET-08'):
                        entity.linear, entity.angular = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
            if time:
                if self.broken('TIME-half'):
                    self.step_count, self.time_offset_ns = (self.step_count // 2,
                                                            self.time_offset_ns // 2)
                else:
                    self.step_count, self.time_offset_ns = 0, 0
                self._publish_clock(always=True)

    def _stop(self) -> None:
        with self.lock:
            if self.broken('STATE-07') and self.state == S.STATE_PAUSED:
                return
            keeps = self.defect in ('STATE-14', 'TIME-zero-on-play', 'TIME-zero-while-stopped')
            self._reset(time=not keeps, state=True,
                        spawned=not self.broken('STATE-13'))
            self.state = S.STATE_STOPPED

    # -- replies -----------------------------------------------------------------------

    def _answer(self, handler, kind: str):
        """Wrap a handler: a Refused becomes its code; every other reply is OK."""
        def answer(request, response):
            if self.broken('SLOW') or (self.broken('SLOW-PAUSE') and kind == 'SetSimulationState'
                                       and request.state.state == S.STATE_PAUSED):
                time.sleep(SLOW_S)  # outside the lock: the other threads answer meanwhile
            if kind == self.hold and not self.release.is_set():
                with self.lock:
                    self.held += 1
                self.release.wait(HOLD_S)  # outside the lock, as SLOW's
            with self.lock:
                if kind in CHANGES:
                    self.changes += 1
                try:
                    leave_zero = handler(request, response) is LEAVE_ZERO
                    if hasattr(response, 'result') and response.result.result == 0 and \
                            not leave_zero:
                        response.result.result = R.RESULT_OK
                except Refused as exc:
                    response.result.result = exc.code
                    response.result.error_message = str(exc) + (
                        ' ' + 'x' * HUGE_TEXT if self.broken('HUGE') else '')
            return response
        return answer

    def _entity(self, name: str) -> Entity:
        entity = self.entities.get(name)
        if entity is None:
            raise Refused(R.RESULT_NOT_FOUND, f'no entity {name!r}')
        return entity

    def _GetSimulatorFeatures(self, request, response):
        drop = {getattr(F, name) for name in self.without if hasattr(F, name)}
        features = [f for f in ALL_FEATURES if f not in drop]
        if self.broken('FEAT-02'):
            features.append(99)
        response.features.features = features
        response.features.spawn_formats = ['urdf', 'sdf'] + (
            ['f' * HUGE_TEXT] if self.broken('HUGE') else [])
        response.features.custom_info = 'a toy of the conformance kit\'s tests'

    def _state_value(self) -> int:
        if self.broken('STATE-01'):
            return 9
        if self.broken('STATE-02') and self.state == S.STATE_STOPPED:
            return S.STATE_PAUSED
        if self.broken('WORLD-12') and self.state == S.STATE_NO_WORLD:
            return S.STATE_STOPPED
        return self.state

    def _GetSimulationState(self, request, response):
        response.state.state = self._state_value()
        if self.broken('RESULT-01'):
            return LEAVE_ZERO

    def _SetSimulationState(self, request, response):
        wanted, now = request.state.state, self.state
        transition = srv.SetSimulationState.Response
        if now == S.STATE_NO_WORLD and not (self.broken('WORLD-13') or (
                self.broken('WORLD-13-others') and wanted != S.STATE_PLAYING)):
            raise Refused(transition.INCORRECT_TRANSITION, 'there is no world: load one')
        if wanted == now:
            if self.broken({S.STATE_STOPPED: 'STATE-08', S.STATE_PLAYING: 'STATE-09',
                            S.STATE_PAUSED: 'STATE-10'}.get(wanted, '')):
                return
            raise Refused(transition.ALREADY_IN_TARGET_STATE, 'already in that state')
        if wanted == S.STATE_PLAYING:
            if self.broken('STATE-03') and now == S.STATE_STOPPED:
                return
            if self.broken('STATE-06') and now == S.STATE_PAUSED:
                raise Refused(transition.INCORRECT_TRANSITION, 'no')
            if self.broken('TIME-zero-on-play') and now == S.STATE_STOPPED:
                self.clock.publish(Clock())  # 0 as it leaves STOPPED, then the old time
            self.state = S.STATE_PLAYING
        elif wanted == S.STATE_PAUSED:
            if now == S.STATE_STOPPED:
                if self.broken('STATE-11'):
                    return
                raise Refused(transition.INCORRECT_TRANSITION, 'a stopped simulation is played')
            if self.broken('STATE-04'):
                return
            self.state = S.STATE_PAUSED
        elif wanted == S.STATE_STOPPED:
            if self.broken('STATE-05') and now == S.STATE_PLAYING:
                raise Refused(transition.STATE_TRANSITION_ERROR, 'could not stop')
            self._stop()
            if self.broken('STATE-07') and now == S.STATE_PAUSED:
                self.state = S.STATE_PAUSED
        elif self.broken('STATE-12'):
            return
        else:
            raise Refused(transition.INCORRECT_TRANSITION, f'no transition to {wanted}')

    def _StepSimulation(self, request, response):
        steps = request.steps
        if self.state == S.STATE_PLAYING:
            if self.broken('STEP-04'):
                self.state = S.STATE_PAUSED
            else:
                if self.broken('STEP-05'):
                    self.state = S.STATE_PAUSED
                raise Refused(R.RESULT_OPERATION_FAILED, 'the simulation is playing: pause it')
        if self.state not in (S.STATE_PAUSED, S.STATE_STOPPED):
            raise Refused(R.RESULT_INCORRECT_STATE, 'nothing to step')
        if steps == 1 and self.broken('STEP-01'):
            raise Refused(R.RESULT_OPERATION_FAILED, 'single steps are not supported')
        if steps == 1 and self.broken('STEP-07'):
            steps = 2
        if steps == 1 and self.broken('STEP-06'):
            self.single_steps += 1
            self.time_offset_ns += DT_NS * (self.single_steps % 2)
        self.state = S.STATE_PAUSED
        for _ in range(steps):
            self._step(publish=False)
        self._publish_clock()
        if self.broken('STEP-03'):
            self.state = S.STATE_PLAYING
        if steps > 1 and self.broken('STEP-02'):
            return LEAVE_ZERO

    def _ResetSimulation(self, request, response):
        scopes = srv.ResetSimulation.Request
        scope = request.scope
        if scope == scopes.SCOPE_DEFAULT and self.broken('RESET-01'):
            raise Refused(R.RESULT_FEATURE_UNSUPPORTED, 'name a scope')
        if self.broken('RESET-13') and scope not in (0, 1, 2, 4, 255):
            raise Refused(R.RESULT_NOT_FOUND, f'no scope {scope}')
        if scope in (scopes.SCOPE_DEFAULT, scopes.SCOPE_ALL):
            keep_spawned = ((scope == 0 and self.broken('RESET-02'))
                            or (scope == 255 and self.broken('RESET-03')))
            self._reset(time=not (scope == 0 and self.broken('RESET-04')), state=True,
                        spawned=not keep_spawned)
            return
        time, state, spawned = (bool(scope & scopes.SCOPE_TIME), bool(scope & scopes.SCOPE_STATE),
                                bool(scope & scopes.SCOPE_SPAWNED))
        if scope == scopes.SCOPE_TIME and self.broken('RESET-05'):
            time, state = False, True
        if scope == scopes.SCOPE_TIME and self.broken('RESET-06'):
            time, state, spawned = True, True, True
        if scope == scopes.SCOPE_STATE and self.broken('RESET-09'):
            spawned = True
        if scope == scopes.SCOPE_STATE and self.broken('RESET-10'):
            time = True
        if scope == scopes.SCOPE_SPAWNED and self.broken('RESET-11'):
            spawned = False
        if scope == scopes.SCOPE_SPAWNED and self.broken('RESET-12'):
            self.entities.pop('toy_bot', None)
        self._reset(time, state, spawned)

    # -- entities ----------------------------------------------------------------------

    def _matches(self, pattern: str, name: str) -> bool:
        if not pattern:
            return True
        if self.broken('FILTER-01'):
            return pattern in name
        if self.broken('FILTER-02'):
            core = pattern.lstrip('^').rstrip('$')
            if pattern.startswith('^') and pattern.endswith('$'):
                return name == core
            return core in name
        try:
            return re.search(pattern, name) is not None
        except re.error:
            raise Refused(R.RESULT_OPERATION_FAILED, 'bad regex') from None

    def _overlaps(self, entity: Entity, bounds) -> bool:
        points = [(p.x, p.y, p.z) for p in bounds.points]
        low, high = entity.aabb()
        if bounds.type == B.TYPE_SPHERE:
            if self.broken('FILTER-06'):
                return True
            nearest = [min(max(c, lo), hi) for c, lo, hi in zip(points[0], low, high)]
            return math.dist(nearest, points[0]) <= points[1][0]
        if bounds.type == B.TYPE_BOX and self.broken('FILTER-07'):
            return True
        if bounds.type == B.TYPE_BOX and self.broken('BOX-AS-WRITTEN'):
            (q_high, q_low) = points[:2]  # "upper right and lower left corners", as they come
            return all(lo <= qh and ql <= hi
                       for lo, hi, ql, qh in zip(low, high, q_low, q_high))
        # A box (its corners in either order), or a hull judged by the box around its points.
        q_low = [min(p[i] for p in points) for i in range(3)]
        q_high = [max(p[i] for p in points) for i in range(3)]
        return all(lo <= qh and ql <= hi for lo, hi, ql, qh in zip(low, high, q_low, q_high))

    def _filtered(self, filters) -> List[str]:
        bounds = filters.bounds
        if bounds.type == B.TYPE_CONVEX_HULL and self.broken('FILTER-08'):
            raise Refused(R.RESULT_FEATURE_UNSUPPORTED, 'no hulls')
        if bounds.type not in (B.TYPE_EMPTY, B.TYPE_SPHERE, B.TYPE_BOX, B.TYPE_CONVEX_HULL):
            raise Refused(R.RESULT_FEATURE_UNSUPPORTED, 'unknown bounds type')
        undeclared = {B.TYPE_BOX: 'ENTITY_BOUNDS_BOX', B.TYPE_CONVEX_HULL: 'ENTITY_BOUNDS_CONVEX'}
        if undeclared.get(bounds.type) in self.without:
            if self.broken('FILTER-09'):
                return list(self.entities)
            raise Refused(R.RESULT_FEATURE_UNSUPPORTED, 'spheres only')
        wanted = {c.category for c in filters.categories}
        tags = set(filters.tags.tags)
        all_mode = filters.tags.filter_mode == msg.TagsFilter.FILTER_MODE_ALL
        if self.broken('FILTER-10') or self.broken('FILTER-11'):
            all_mode = not all_mode
        names = []
        others = bool(wanted or tags or bounds.type != B.TYPE_EMPTY)
        for name, entity in self.entities.items():
            tests = [(others and self.broken('FILTER-12-name'))
                     or self._matches(filters.filter, name)]
            if wanted and not self.broken('FILTER-04'):
                tests.append(entity.category in wanted and not (
                    self.broken('FILTER-05') and len(wanted) > 1))
            if tags:
                have = set(entity.tags)
                tests.append(tags <= have if all_mode else bool(tags & have))
            if bounds.type != B.TYPE_EMPTY:
                tests.append(self._overlaps(entity, bounds))
            if (any(tests) if self.broken('FILTER-12') else all(tests)):
                names.append(name)
        return names

    def _GetEntities(self, request, response):
        response.entities = self._filtered(request.filters)
        if self.broken('ENTITY-01'):
            response.entities.append('ground')
        if self.broken('HUGE'):
            response.entities += ['n' * HUGE_TEXT] * 2
        if self.broken('RESULT-02'):
            return LEAVE_ZERO

    def _state_message(self, name: str, entity: Entity, lift: float = 0.0):
        state = msg.EntityState()
        state.header.frame_id = 'map' if self.broken('ENTITY-03') else 'world'
        if self.broken('HUGE'):
            state.header.frame_id = 'm' * HUGE_TEXT
        state.header.stamp.sec, state.header.stamp.nanosec = divmod(self.time_ns, 10**9)
        p, q = state.pose.position, state.pose.orientation
        p.x, p.y, p.z = entity.position[0], entity.position[1], entity.position[2] + lift
        q.x, q.y, q.z, q.w = entity.orientation
        linear, angular = entity.linear, entity.angular
        if self.broken('ENTITY-06'):
            linear = rotate_inverse(entity.orientation, linear)
            angular = rotate_inverse(entity.orientation, angular)
        v, w = state.twist.linear, state.twist.angular
        v.x, v.y, v.z = linear
        w.x, w.y, w.z = angular
        return state

    def _GetEntitiesStates(self, request, response):
        names = list(self.entities) if self.broken('FILTER-03') else self._filtered(
            request.filters)
        response.entities = names
        lift = 0.05 if self.broken('ENTITY-04') else 0.0
        response.states = [self._state_message(n, self.entities[n], lift) for n in names
                           if not (self.broken('ENTITY-02') and self.entities[n].static)]
        if self.broken('ENTITY-04-order'):
            spawned = [i for i, n in enumerate(names) if self.entities[n].spawned]
            reordered = [response.states[i] for i in reversed(spawned)]
            for i, state in zip(spawned, reordered):
                response.states[i] = state
        if self.broken('RESULT-03'):
            return LEAVE_ZERO

    def _GetEntityState(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-05'):
            raise Refused(R.RESULT_OPERATION_FAILED, 'failed')
        response.state = self._state_message(request.entity, self._entity(request.entity))

    def _frame(self, frame: str, defect: str) -> Transform:
        """Return the world pose of a request's frame: '' and world, or an entity."""
        if frame in ('', 'world') or self.broken(defect):
            return Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        entity = self.entities.get(frame)
        if entity is None:
            if self.broken('SPAWN-13'):
                return Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
            raise Refused(R.RESULT_NOT_FOUND, f'no frame {frame!r}')
        return Transform(entity.position, entity.orientation)

    def _checked_pose(self, pose, quaternion_defect: str, nan_defect: str):
        p, q = pose.position, pose.orientation
        position, orientation = (p.x, p.y, p.z), (q.x, q.y, q.z, q.w)
        norm = math.sqrt(sum(v * v for v in orientation))
        if not _finite(*position) and not self.broken(nan_defect):
            raise Refused(INVALID_POSE_SET if quaternion_defect.startswith('ENTITY')
                          else msg.SpawnResult.INVALID_POSE, 'not finite')
        if abs(norm - 1.0) > 1e-3:
            if not self.broken(quaternion_defect):
                raise Refused(INVALID_POSE_SET if quaternion_defect.startswith('ENTITY')
                              else msg.SpawnResult.INVALID_POSE, 'not a unit quaternion')
            orientation, norm = (0.0, 0.0, 0.0, 1.0), 1.0
        if any(abs(v) > WORLD_LIMIT_M for v in position if math.isfinite(v)):
            raise Refused(INVALID_POSE_SET if quaternion_defect.startswith('ENTITY')
                          else msg.SpawnResult.INVALID_POSE, 'beyond the world')
        return position, tuple(v / norm for v in orientation)

    def _SetEntityState(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-06'):
            return
        entity = self._entity(request.entity)
        state = request.state
        stamp = state.header.stamp
        if (stamp.sec or stamp.nanosec) and self.broken('ENTITY-14'):
            raise Refused(INVALID_POSE_SET, 'stamped in the future')
        position, orientation = self._checked_pose(state.pose, 'ENTITY-10', 'ENTITY-11')
        linear = (state.twist.linear.x, state.twist.linear.y, state.twist.linear.z)
        angular = (state.twist.angular.x, state.twist.angular.y, state.twist.angular.z)
        acceleration = state.acceleration
        accelerating = not self.broken('ENTITY-12-acceleration') and any(
            (acceleration.linear.x, acceleration.linear.y, acceleration.linear.z,
             acceleration.angular.x, acceleration.angular.y, acceleration.angular.z))
        if entity.static and (any(linear + angular) or accelerating) and \
                not self.broken('ENTITY-12'):
            raise Refused(R.RESULT_OPERATION_FAILED, f'{request.entity} is static')
        frame = self._frame(state.header.frame_id, 'ENTITY-07')
        pose = compose(frame, Transform(position, orientation))
        entity.position = pose.translation
        if not self.broken('ENTITY-05'):
            entity.orientation = pose.rotation
        twist_frame = (frame.rotation if not self.broken('ENTITY-08') else (0.0, 0.0, 0.0, 1.0))
        if not (self.broken('ENTITY-09') and not any(linear + angular)):
            entity.linear = rotate(twist_frame, linear)
            entity.angular = rotate(twist_frame, angular)

    def _GetEntityInfo(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-07'):
            return LEAVE_ZERO
        entity = self._entity(request.entity)
        category = entity.category
        if self.broken('ENTITY-13') and category == C.CATEGORY_ROBOT:
            category = 3
        response.info.category.category = category
        response.info.description = entity.description
        response.info.tags = list(entity.tags)

    def _SetEntityInfo(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-08'):
            raise Refused(R.RESULT_OPERATION_FAILED, 'failed')
        entity = self._entity(request.entity)
        entity.category = request.info.category.category
        entity.description = request.info.description
        if not self.broken('ENTITY-15'):
            entity.tags = list(request.info.tags)

    def _GetEntityBounds(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-09'):
            return
        entity = self._entity(request.entity)
        half = (0.5, 0.5, 0.5) if self.broken('BOUNDS-constant') else entity.half
        if self.broken('BOUNDS-03'):
            half = tuple(h / 2.0 for h in half)
        low, high = tuple(-h for h in half), half
        if self.broken('BOUNDS-02'):
            low, high = entity.aabb()
        points = [low] if self.broken('BOUNDS-01') else [low, high]
        response.bounds = msg.Bounds(type=B.TYPE_BOX, points=[Vector3(x=p[0], y=p[1], z=p[2])
                                                              for p in points])

    # -- spawning ----------------------------------------------------------------------

    def _read_resource(self, uri: str, text: str, codes):
        """Return (name in the file, half extents) of a URI or a URDF/SDF text."""
        if self.broken('SPAWN-07') and text:
            uri = ''
        if uri:
            if uri not in ASSETS:
                raise Refused(codes.NO_RESOURCE, f'no asset {uri}')
            return ASSETS[uri]
        if not text:
            if self.broken('SPAWN-08'):
                raise Refused(R.RESULT_OPERATION_FAILED, 'failed')
            raise Refused(codes.NO_RESOURCE, 'neither a uri nor a resource_string')
        try:
            root = ElementTree.fromstring(text)
        except ElementTree.ParseError:
            if self.defect in ('SPAWN-15', 'SPAWN-16'):
                raise Refused(R.RESULT_OPERATION_FAILED, 'failed') from None
            raise Refused(codes.RESOURCE_PARSE_ERROR, 'does not parse') from None
        model = root if root.tag == 'robot' else root.find('model')
        if model is None:
            raise Refused(codes.UNSUPPORTED_FORMAT, f'<{root.tag}> is no URDF or SDF')
        half = (0.1, 0.1, 0.1)
        box = root.find('.//box')
        if box is not None:
            size = box.get('size') or (box.findtext('size') or '')
            values = [float(v) for v in size.split()]
            if len(values) == 3:
                half = tuple(v / 2.0 for v in values)
        return model.get('name', ''), half

    def _spawn(self, name: str, allow_renaming: bool, uri: str, text: str, namespace: str,
               initial_pose, codes) -> str:
        """Spawn one entity; return its name; Refused with ``codes``' constants."""
        stamp = initial_pose.header.stamp
        if (stamp.sec or stamp.nanosec) and self.broken('SPAWN-17'):
            raise Refused(codes.INVALID_POSE, 'stamped in the future')
        if namespace and not self.broken('SPAWN-14') and not re.fullmatch(
                r'/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*', namespace):
            raise Refused(codes.NAMESPACE_INVALID, f'bad namespace {namespace!r}')
        position, orientation = self._checked_pose(initial_pose.pose, 'SPAWN-09', 'SPAWN-10')
        file_name, half = self._read_resource(uri, text, codes)
        frame = self._frame(initial_pose.header.frame_id, 'SPAWN-12')
        pose = compose(frame, Transform(position, orientation))
        wanted = name or file_name
        renamed = None
        if not name and self.broken('SPAWN-03'):
            wanted = renamed = self._free('entity')
        if not wanted:
            if not (allow_renaming or self.broken('SPAWN-06')):
                raise Refused(codes.NAME_INVALID, 'no name')
            wanted = renamed = self._free('entity')
        elif not NAME.match(wanted):
            if not allow_renaming:
                raise Refused(codes.NAME_INVALID, f'bad name {wanted!r}')
            wanted = renamed = self._free('entity')
        elif wanted in self.entities:
            if not (allow_renaming or self.broken('SPAWN-04')):
                raise Refused(codes.NAME_NOT_UNIQUE, f'{wanted} exists')
            renamed = self._free(wanted)
        stored = renamed or wanted
        if self.broken('SPAWN-02') and text:
            stored = wanted + '_0'
        lift = 0.1 if self.broken('SPAWN-11') else 0.0
        self.entities[stored] = Entity(
            C.CATEGORY_OBJECT, (pose.translation[0], pose.translation[1],
                                pose.translation[2] + lift), pose.rotation, half=half,
            spawned=True, description=uri or 'resource_string')
        if self.broken('SPAWN-05') and renamed and name:
            return name
        if self.broken('SPAWN-01') and uri:
            return '/' + stored
        return stored if not (self.broken('SPAWN-02') and text) else wanted

    def _free(self, stem: str) -> str:
        n = 1
        while f'{stem}_{n}' in self.entities:
            n += 1
        return f'{stem}_{n}'

    def _SpawnEntity(self, request, response):
        response.entity_name = self._spawn(
            request.name, request.allow_renaming, request.uri, request.resource_string,
            request.entity_namespace, request.initial_pose, srv.SpawnEntity.Response)

    def _SpawnEntities(self, request, response):
        failed, made = False, []
        seen = set()
        for spawn in request.spawn_requests:
            result = msg.SpawnResult()
            allow = spawn.allow_renaming or (self.broken('BATCH-04') and spawn.name in seen)
            seen.add(spawn.name)
            try:
                result.entity_name = self._spawn(
                    spawn.name, allow, spawn.entity_resource.uri,
                    spawn.entity_resource.resource_string, spawn.entity_namespace,
                    spawn.initial_pose, msg.SpawnResult)
                result.result.result = R.RESULT_OK
                made.append(result.entity_name)
            except Refused as exc:
                failed = True
                result.result.result, result.result.error_message = exc.code, str(exc)
            response.results.append(result)
        if self.broken('BATCH-01'):
            response.results.reverse()
        if failed and self.broken('BATCH-03'):
            for name in made:
                self.entities.pop(name, None)
        if failed and not self.broken('BATCH-02'):
            raise Refused(srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED, 'see results')

    def _DeleteEntity(self, request, response):
        if request.entity not in self.entities and self.broken('RESULT-10'):
            return
        self._entity(request.entity)
        if self.broken('DELETE-01'):
            return
        if self.broken('DELETE-02'):
            self.entities = {n: e for n, e in self.entities.items() if not e.spawned}
        self.entities.pop(request.entity, None)

    def _GetSpawnables(self, request, response):
        uris = ['toy://cube_v2'] if self.broken('SPAWNABLES-03') else sorted(ASSETS)
        known = ['toy://']
        unknown = [s for s in request.sources if not any(s.startswith(k) for k in known)]
        if unknown and self.broken('SPAWNABLES-02'):
            raise Refused(R.RESULT_NOT_FOUND, 'unknown sources')
        for uri in uris:
            response.spawnables.append(msg.Spawnable(uri=uri, description='a toy box'))
        if self.broken('SPAWNABLES-01'):
            response.spawnables.append(msg.Spawnable(uri='', description='nothing'))
        if unknown:
            response.result.error_message = f'unknown sources: {", ".join(unknown)}'
        if self.broken('RESULT-04'):
            return LEAVE_ZERO

    # -- named poses and worlds ----------------------------------------------------------

    def _named(self):
        poses = []
        if self.broken('NAMED-empty'):
            return poses
        for name, position, yaw, tags in WORLDS.get(self.world, {}).get('poses', []):
            pose = msg.NamedPose(name=name, description=f'the {name}', tags=list(tags))
            x, y, z = position
            if self.broken('NAMED-05') and not poses:
                x = 2 * WORLD_LIMIT_M
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
            o = pose.pose.orientation
            o.x, o.y, o.z, o.w = yaw_q(yaw)
            poses.append(pose)
        if self.broken('NAMED-01') and poses:
            poses.append(poses[0])
        return poses

    def _GetNamedPoses(self, request, response):
        tags = set(request.tags.tags)
        all_mode = request.tags.filter_mode == msg.TagsFilter.FILTER_MODE_ALL
        if self.broken('NAMED-03'):
            all_mode = False
        for pose in self._named():
            have = set(pose.tags)
            if (not tags or self.broken('NAMED-02')
                    or (tags <= have if all_mode else bool(tags & have))):
                response.poses.append(pose)

    def _GetNamedPoseBounds(self, request, response):
        names = [p.name for p in self._named()]
        if request.name not in names:
            if self.broken('RESULT-11'):
                raise Refused(R.RESULT_OPERATION_FAILED, 'failed')
            raise Refused(R.RESULT_NOT_FOUND, f'no named pose {request.name!r}')
        if self.broken('NAMED-04'):
            response.bounds = msg.Bounds(type=B.TYPE_SPHERE, points=[Vector3()])
        elif names.index(request.name) == 0:
            response.bounds = msg.Bounds(type=B.TYPE_BOX, points=[
                Vector3(x=-0.5, y=-0.5, z=0.0), Vector3(x=0.5, y=0.5, z=1.0)])
        elif names.index(request.name) == 1:
            response.bounds = msg.Bounds(type=B.TYPE_SPHERE, points=[Vector3(), Vector3(x=1.0)])

    def _world_message(self, key: Optional[str]):
        world = msg.WorldResource()
        if key is None:
            return world
        facts = WORLDS.get(key, {'uri': '', 'tags': [], 'description': ''})
        world.name, world.description, world.tags = key, facts['description'], facts['tags']
        world.world_resource.uri = facts['uri']
        if not facts['uri']:
            world.world_resource.resource_string = f'<world name="{key}"/>'
        return world

    def _GetAvailableWorlds(self, request, response):
        tags = set(request.filter.tags)
        all_mode = request.filter.filter_mode == msg.TagsFilter.FILTER_MODE_ALL
        for key in WORLDS:
            have = set(WORLDS[key]['tags'])
            if tags and not self.broken('WORLD-02') and not (
                    tags <= have if all_mode else tags & have):
                continue
            world = self._world_message(key)
            if self.broken('WORLD-01') and key == 'hall':
                world.world_resource = msg.Resource()
            response.worlds.append(world)

    def _GetCurrentWorld(self, request, response):
        key = self.world
        if self.broken('WORLD-10') and key is None:
            key = 'yard'
        if self.broken('WORLD-07'):
            key = 'yard' if key is not None else None
        if key is None or self.broken('WORLD-03'):
            raise Refused(srv.GetCurrentWorld.Response.NO_WORLD_LOADED, 'no world')
        response.world = self._world_message(key)
        if self.broken('WORLD-NO-URI'):
            response.world.world_resource = msg.Resource()

    def _LoadWorld(self, request, response):
        codes = srv.LoadWorld.Response
        if request.uri:
            key = next((k for k, w in WORLDS.items() if w['uri'] == request.uri), None)
            if key is None:
                raise Refused(codes.NO_RESOURCE, f'no world {request.uri}')
        elif request.resource_string:
            try:
                root = ElementTree.fromstring(request.resource_string)
                key = root.get('name', '')
            except ElementTree.ParseError:
                if not self.broken('WORLD-09'):
                    raise Refused(codes.RESOURCE_PARSE_ERROR, 'does not parse') from None
                key = 'empty'
        else:
            if self.broken('WORLD-08'):
                raise Refused(R.RESULT_OPERATION_FAILED, 'failed')
            raise Refused(codes.NO_RESOURCE, 'neither a uri nor a resource_string')
        self.generation += 1
        spawned = {n: e for n, e in self.entities.items() if e.spawned}
        playing = self.state == S.STATE_PLAYING
        self._load_world(key)
        if self.broken('WORLD-06'):
            self.entities.update(spawned)
        self.step_count, self.time_offset_ns = 0, 0
        self.state = S.STATE_PLAYING if playing and self.broken('WORLD-05') else S.STATE_STOPPED
        if not self.broken('WORLD-04'):
            response.world = self._world_message(key)

    def _UnloadWorld(self, request, response):
        if self.world is None and not self.broken('WORLD-11'):
            raise Refused(srv.UnloadWorld.Response.NO_WORLD_LOADED, 'no world')
        self.generation += 1
        spawned = {n: e for n, e in self.entities.items() if e.spawned}
        self._load_world(None)
        if self.broken('WORLD-14'):
            self.entities.update(spawned)
        self.state = S.STATE_NO_WORLD

    # -- the action --------------------------------------------------------------------

    def _goal(self, goal_request):
        if self.broken('ACTION-03') and self.state == S.STATE_PLAYING:
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _cancel(self, goal_handle):
        return CancelResponse.REJECT if self.broken('CANCEL-REFUSED') else CancelResponse.ACCEPT

    def _simulate_steps(self, goal_handle):
        result = action.SimulateSteps.Result()
        steps = goal_handle.request.steps
        with self.lock:
            generation = self.generation
            if self.state == S.STATE_PLAYING:
                goal_handle.abort()
                result.result.result = R.RESULT_OPERATION_FAILED
                result.result.error_message = 'the simulation is playing: pause it'
                return result
            self.state = S.STATE_PAUSED
        todo = steps - 1 if self.broken('ACTION-06') else steps
        for done in range(1, todo + 1):
            with self.lock:
                if self.generation != generation or not self.context.ok():
                    goal_handle.abort()
                    result.result.result = R.RESULT_OPERATION_FAILED
                    result.result.error_message = 'reset while stepping'
                    return result
                if goal_handle.is_cancel_requested:
                    if self.broken('ACTION-04'):
                        goal_handle.abort()
                        result.result.result = R.RESULT_OPERATION_FAILED
                        result.result.error_message = 'cancelled'
                        return result
                    goal_handle.canceled()
                    result.result.result = R.RESULT_OK
                    return result
                self._step()
            feedback = action.SimulateSteps.Feedback(
                completed_steps=done, remaining_steps=steps if self.broken('ACTION-02')
                else steps - done)
            if not (self.broken('ACTION-02-once') and done < todo):
                goal_handle.publish_feedback(feedback)
        goal_handle.succeed()
        if self.broken('ACTION-05'):
            self.state = S.STATE_PLAYING
        if not self.broken('ACTION-01'):
            result.result.result = R.RESULT_OK
        return result
