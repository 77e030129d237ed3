"""
The simulator under test, as the kit's clauses see it: :class:`Target`.

A node of the kit's own (a :class:`~r2d2_sim.testing.RemoteProbe`: its
context on the simulator's ROS domain, spun in the caller's thread) finds the
services and the action by type under a prefix, reads the declared features
once, and calls them through the package's one client of the standard, a
:class:`~r2d2_sim.testing.StandardClient` given the names found, a resend for
idempotent queries and the kit's timeout. A reply that is not what a clause
expects becomes a :class:`~r2d2_sim.conformance.clause.ClauseFailed` with a
one-line reason, never a traceback.

The Target is the connection (discovery, features, the typed calls
``call``, ``ok``, ``expect``) composed with parts that own their data:
``t.sim`` the simulation's state, steps and action
(:mod:`~r2d2_sim.conformance.simulation_verbs`), ``t.entities`` the
entities and what the kit spawned (:mod:`~r2d2_sim.conformance.entity_verbs`),
``t.clock`` simulated time on ``/clock``
(:mod:`~r2d2_sim.conformance.clock_verbs`), ``t.world`` the world found at
the start and put back (:mod:`~r2d2_sim.conformance.world_verbs`) and
``t.undo`` the undoing of a clause (:mod:`~r2d2_sim.conformance.undo`).
"""

import math
import os
import re
import time
from typing import (
    Any, Callable, Dict, FrozenSet, List, Optional, Sequence)

from r2d2_sim.apps.cli import domain_env_problem, MAX_DOMAIN_ID
from r2d2_sim.conformance.clause import ClauseFailed, one_line
from r2d2_sim.conformance.clock_verbs import TargetClock
from r2d2_sim.conformance.discovery import (
    ACTION, FEATURE_INTERFACES, FEATURES, find_interfaces, normal_prefix, simulator_levels)
from r2d2_sim.conformance.entity_verbs import BOX_SIZE_M, TargetEntities
from r2d2_sim.conformance.options import KitOptions
from r2d2_sim.conformance.simulation_verbs import TargetSimulation
from r2d2_sim.conformance.undo import TargetUndo
from r2d2_sim.conformance.world_verbs import TargetWorld
from r2d2_sim.errors import SetupError

__all__ = ['KitOptions', 'KitError', 'Target', 'BOX_SIZE_M', 'UNKNOWN_NAME', 'options_problem',
           'topic_problem', 'namespace_problem']

# The kit's own node.
NODE_NAME = '_sim_conformance'
# A name no simulator has an entity (or named pose) of.
UNKNOWN_NAME = 'conformance_no_such_entity'
# An idempotent query is sent again after this long without a reply (s): a reply
# can be lost for good while the server has not yet discovered a new client's reader.
RESEND_S = 1.0
# Before its first change the kit watches the ROS graph until it has stood still this long
# (s): a second simulator, discovered a little later than the first, shows by then.
SETTLE_S = 0.25


class KitError(SetupError):
    """The kit cannot run at all (simulation_interfaces missing, a bad option): one line."""


def _nothing() -> None:
    """Do nothing: a Target's ``check`` until its owner gives one."""


def _ros_text(exc: Exception) -> str:
    """Return rclpy's reason for a bad name without its source location."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    text = text.split(', at /')[0].split(' is invalid: ')[-1]
    return re.sub(r'^Invalid [a-z ]+: ', '', text).rstrip(':')


def topic_problem(topic: str) -> str:
    """Return why ``topic`` is no ROS topic name, in one line ('' when it is one)."""
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    try:
        validate_full_topic_name(expand_topic_name(topic, NODE_NAME, '/'))
    except Exception as exc:  # rclpy raises ValueError or its own exception types
        return _ros_text(exc)
    return ''


def namespace_problem(prefix: str) -> str:
    """Return why ``prefix`` is no ROS namespace, in one line ('' when it is one)."""
    from rclpy.validate_namespace import validate_namespace
    try:
        validate_namespace(normal_prefix(prefix))
    except Exception as exc:  # rclpy's InvalidNamespaceException
        return _ros_text(exc)
    return ''


def options_problem(options: KitOptions) -> str:
    """Return what is wrong with ``options``, in one line ('' when nothing is)."""
    for name, value in (('timeout_s', options.timeout_s),
                        ('total_timeout_s', options.total_timeout_s)):
        if value is None and name == 'total_timeout_s':
            continue
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            return f'{name} must be a finite number of seconds > 0, got {value!r}'
    domain = options.domain_id
    if domain is not None and not (isinstance(domain, int) and 0 <= domain <= MAX_DOMAIN_ID):
        return f'domain_id must be in 0..{MAX_DOMAIN_ID}, got {domain!r}'
    problem = namespace_problem(options.prefix)
    if problem:
        return one_line(f'prefix {options.prefix!r}: {problem}')
    problem = topic_problem(options.clock_topic)
    if problem:
        return one_line(f'clock_topic {options.clock_topic!r}: {problem}')
    return ''


def default_domain_id() -> int:
    """Return ``ROS_DOMAIN_ID`` as ROS reads it (0 when unset or empty); KitError if bad."""
    problem = domain_env_problem()  # before ROS starts: Fast DDS would end the process itself
    if problem is not None:
        raise KitError(one_line(problem))
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    return int(text) if text else 0


class Target:
    """
    The simulator under test: its interfaces found by type, its features, the calls; its parts.

    Made by :meth:`connect` (which never raises for what the simulator does:
    ``features_error`` says why its features are unknown); closed by
    :meth:`close`. The clauses call through ``call``, ``ok`` and
    ``expect`` and use the parts ``sim``, ``entities``, ``clock``,
    ``world`` and ``undo``; each raises ClauseFailed with a reason when
    the simulator does not answer as asked.
    """

    def __init__(self, options: KitOptions) -> None:
        problem = options_problem(options)
        if problem:
            raise KitError(problem)
        try:
            from simulation_interfaces import action, msg, srv
            msg.Result.__class__.__import_type_support__()
        except Exception as exc:  # ImportError, or its type support missing
            raise KitError('simulation_interfaces (Jazzy 1.5) cannot be imported '
                           f'({type(exc).__name__}): source a ROS install that has it, or '
                           'build it with tools/build_interfaces.sh') from None
        from r2d2_sim.testing.remote import RemoteProbe
        from r2d2_sim.testing.standard import StandardClient
        self.options = options
        self.msg, self.srv, self.action = msg, srv, action
        self.prefix = normal_prefix(options.prefix)
        self.domain_id = (options.domain_id if options.domain_id is not None
                          else default_domain_id())
        self.timeout_s = options.timeout_s
        self.probe = RemoteProbe(self.domain_id, NODE_NAME)
        self.node = self.probe.node
        # The one client of the standard, on the names discovery finds (none yet).
        # Called between spins of every wait: may raise (KeyboardInterrupt) to end it there.
        self.check: Callable[[], None] = _nothing
        self.client = StandardClient(
            self.node, self._spin_until, self.prefix, self.timeout_s, names={},
            resend_s=RESEND_S)
        self.interfaces: Dict[str, str] = {}  # interface -> service (or action) name
        self.several: Dict[str, List[str]] = {}  # interface -> every name seen, when several
        self.features: Optional[FrozenSet[str]] = None  # declared feature names; None: unknown
        self.feature_values: List[int] = []
        self.spawn_formats: List[str] = []
        self.features_error = ''
        self.others: List[str] = []  # namespaces of the other simulators seen on the domain
        self.refusal = ''  # why the kit checks no simulator here ('' when it checks this one)
        self.sim = TargetSimulation(self)
        self.entities = TargetEntities(self)
        self.clock = TargetClock(self, self.sim)
        self.world = TargetWorld(self)
        self.undo = TargetUndo(self, self.sim, self.entities, self.world)

    # -- connecting --------------------------------------------------------------------

    def scan(self) -> Dict[str, str]:
        """Look at the ROS graph again; return {interface: name} of those under the prefix."""
        self.interfaces, self.several = find_interfaces(
            self.node.get_service_names_and_types(), self.prefix)
        self.client.use_names(self.interfaces)
        return self.interfaces

    def connect(self) -> None:
        """
        Find the interfaces, read the features, find ``/clock``; never raises for the simulator.

        Waits up to the timeout for GetSimulatorFeatures at the prefix, then
        (up to the timeout again) for every interface the features declare,
        so that a slow discovery is not taken for a missing service. Then
        remembers the state and the world it found, to leave them so, and
        loads a world for the run where there is none (see
        :meth:`~r2d2_sim.conformance.world_verbs.TargetWorld.load_for_run`). When
        it cannot tell which simulator the user meant (none at the prefix
        but some elsewhere, or several at the prefix), ``refusal`` says why
        in one line and nothing is asked of any simulator but its features.
        """
        timeout = self.timeout_s
        waited = self.client.wait_s(timeout)  # the run's time limit may cut it short
        within = f'{waited:.3g} s' + (' (the run\'s time limit)' if waited < timeout else '')
        if not self.wait(lambda: 'GetSimulatorFeatures' in self.scan(), timeout):
            levels = self.simulator_levels()
            if levels:
                self.refusal = one_line(
                    f'no simulator at {self.prefix!r} (its own level) within {within}, but '
                    f'{len(levels)} on ROS domain {self.domain_id} under {", ".join(levels)}: '
                    f'give --prefix {levels[0]} to check {"it" if len(levels) == 1 else "one"}')
                return
            seen = ', '.join(sorted(self.interfaces)) or 'none of the standard\'s services'
            self.features_error = (f'no service of type GetSimulatorFeatures under '
                                   f'{self.prefix!r} within {within} (found: {seen})')
            return
        self.refusal = self.rivals()
        if self.refusal:
            return
        try:
            features = self.read_features()
        except ClauseFailed as exc:
            self.features_error = str(exc)
            return
        wanted = [alternatives for feature in features
                  for alternatives in FEATURE_INTERFACES.get(feature, ())]

        def all_found() -> bool:
            found = self.scan()
            return all(any(kind in found for kind in alt.split('|')) for alt in wanted)
        self.wait(all_found, timeout)
        self._settle()
        self.refusal = self.rivals()  # the last look before a change
        if self.refusal:
            return
        self.others = [level for level in self.simulator_levels() if level != self.prefix]
        self._make_clients()
        self.clock.listen()
        self.undo.remember()
        self.world.remember(no_world=self.undo.initial_state == self.msg.SimulationState
                            .STATE_NO_WORLD)
        self.world.load_for_run()  # where there is none: no clause could start from STOPPED

    def _settle(self) -> None:
        """Watch the graph's nodes and services until they stand still for SETTLE_S."""
        seen: List[Any] = [None, 0.0]  # the graph last seen, and since when

        def still() -> bool:
            graph = (sorted(self.node.get_node_names_and_namespaces()),
                     sorted(name for name, _ in self.node.get_service_names_and_types()))
            now = time.monotonic()
            if graph != seen[0]:
                seen[:] = [graph, now]
            return now - seen[1] >= SETTLE_S
        self.wait(still, self.timeout_s)

    def simulator_levels(self) -> List[str]:
        """Return the namespaces on the domain that serve GetSimulatorFeatures (simulators)."""
        return simulator_levels(self.node.get_service_names_and_types())

    def rivals(self) -> str:
        """
        Return why a request to the prefix may reach another simulator ('' when none can).

        Two names of one interface at the prefix are two simulators; so are
        two servers of one name (simulators in the same namespace): a
        request reaches every server of its name.
        """
        found, several = find_interfaces(self.node.get_service_names_and_types(), self.prefix)
        advice = 'run each on a ROS domain (or in a namespace) of its own'
        for kind, names in sorted(several.items()):
            return one_line(f'several simulators at {self.prefix!r}: {kind} is served as '
                            f'{", ".join(names)}; the kit checks one at a time: {advice}')
        for kind, name in sorted(found.items()):
            service = f'{name}/_action/send_goal' if kind == ACTION else name
            count = self.node.count_services(service)
            if count > 1:
                return one_line(f'several simulators at {self.prefix!r}: {count} serve {service}, '
                                f'and a request would reach them all: {advice}')
        return ''

    def read_features(self) -> FrozenSet[str]:
        """Ask GetSimulatorFeatures again; return the names of the features it declares."""
        features = self.call('GetSimulatorFeatures',
                             self.srv.GetSimulatorFeatures.Request()).features
        by_value = {getattr(self.msg.SimulatorFeatures, name): name for name in FEATURES}
        self.feature_values = list(features.features)
        self.features = frozenset(by_value[v] for v in features.features if v in by_value)
        self.spawn_formats = [f.strip().lower() for f in features.spawn_formats]
        return self.features

    def _make_clients(self) -> None:
        """Make a client for every service found, GetSimulatorFeatures' again last."""
        for kind in self.interfaces:
            if kind != ACTION:
                self.client.client(kind)
        # Servers learn of our reply readers in the order we made them: once the
        # last one made gets its answer, every client can (see RemoteProbe).
        self.client.forget('GetSimulatorFeatures')
        try:
            self.read_features()
        except ClauseFailed:
            pass

    def calls_under_way(self) -> bool:
        """
        Return True while a request sent has neither a reply nor been given up.

        A Ctrl-C leaves the one it waited for so: the simulator may still act
        on it, after the kit put it back (one that answers out of order did).
        """
        return any(client._pending_requests for client in self.node.clients)

    def close(self) -> None:
        """Close the kit's node (the simulator is left as it is)."""
        self.probe.close()

    # -- calls -------------------------------------------------------------------------

    def declared(self, *features: str) -> bool:
        """Return True when each feature given is declared; ``A|B`` means either of the two."""
        have = self.features or frozenset()
        return all(any(f in have for f in wanted.split('|')) for wanted in features)

    def _spin_until(self, condition: Callable[[], bool], timeout_s: float) -> bool:
        """Spin as ``probe.spin_until`` does, calling ``check()`` before each ``condition()``."""
        def checked() -> bool:
            self.check()
            return condition()
        return self.probe.spin_until(checked, timeout_s)

    def wait(self, condition: Callable[[], bool], timeout_s: Optional[float] = None) -> bool:
        """Spin the kit's node until ``condition()`` holds (True) or the timeout passes."""
        return self.client.wait(condition, timeout_s)

    def call(self, kind: str, request: Any, check: bool = True) -> Any:
        """
        Call the service of interface ``kind`` (``'SpawnEntity'``); return its reply.

        ClauseFailed when it is not found, not ready or silent within the
        timeout (with ``check=False``: None instead).
        """
        from r2d2_sim.testing.standard import StandardError
        try:
            return self.client.send(kind, request)
        except StandardError as exc:
            if check:
                raise ClauseFailed(exc.message) from None
            return None

    def code_name(self, kind: Optional[str], value: int) -> str:
        """Name a result value: RESULT_* first, then the service's own: ``NOT_FOUND (2)``."""
        from r2d2_sim.testing.standard import code_name
        name = code_name(value, kind)
        return f'{name} ({value})' if name is not None else f'code {value}'

    def describe(self, kind: Optional[str], reply: Any) -> str:
        """Return a reply's result for a reason: ``NAME_NOT_UNIQUE (101): 'taken'``."""
        result = reply.result
        text = self.code_name(kind, result.result)
        if result.error_message:
            text += f': {result.error_message.splitlines()[0][:120]!r}'
        return text

    def expect(self, kind: str, request: Any, codes: Sequence[int], doing: str) -> Any:
        """Call and return the reply if its result is one of ``codes``; else ClauseFailed."""
        reply = self.call(kind, request)
        if reply.result.result not in codes:
            wanted = ' or '.join(self.code_name(kind, c) for c in codes)
            unsupported = (' (0 means unsupported: a declared interface answered with a '
                           'default Result)' if reply.result.result == 0 else '')
            raise ClauseFailed(f'{doing}: expected {wanted}, got '
                               f'{self.describe(kind, reply)}{unsupported}')
        return reply

    def ok(self, kind: str, request: Any, doing: str) -> Any:
        """Call and return the reply if its result is OK; else ClauseFailed."""
        return self.expect(kind, request, (self.msg.Result.RESULT_OK,), doing)
