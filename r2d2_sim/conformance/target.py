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

This module holds the connection (discovery, features, the typed calls);
the verbs the clauses use are mixed in, one module per concept: the
simulation's state and steps (:mod:`~r2d2_sim.conformance.simulation_verbs`),
entities (:mod:`~r2d2_sim.conformance.entity_verbs`), the clock
(:mod:`~r2d2_sim.conformance.clock_verbs`) and the undoing of a clause
(:mod:`~r2d2_sim.conformance.undo`). Every attribute is set in
``Target.__init__``.
"""

import itertools
import os
from typing import Callable, Dict, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.conformance.clause import ClauseFailed
from r2d2_sim.conformance.clock_verbs import ClockVerbs
from r2d2_sim.conformance.discovery import (
    ACTION, FEATURE_INTERFACES, FEATURES, find_interfaces, normal_prefix)
from r2d2_sim.conformance.entity_verbs import BOX_SIZE_M, EntityVerbs
from r2d2_sim.conformance.simulation_verbs import SimulationVerbs
from r2d2_sim.conformance.undo import UndoVerbs
from r2d2_sim.errors import SetupError

__all__ = ['KitOptions', 'KitError', 'Target', 'BOX_SIZE_M', 'UNKNOWN_NAME']

# A name no simulator has an entity (or named pose) of.
UNKNOWN_NAME = 'conformance_no_such_entity'
# Queries that may be sent again when a reply is slow (a reply can be lost
# for good while the server has not yet discovered a new client's reader).
IDEMPOTENT = {'GetSimulatorFeatures', 'GetSimulationState', 'GetEntities', 'GetEntitiesStates',
              'GetEntityState', 'GetEntityInfo', 'GetEntityBounds', 'GetSpawnables',
              'GetNamedPoses', 'GetNamedPoseBounds', 'GetCurrentWorld', 'GetAvailableWorlds'}
RESEND_S = 1.0


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


class Target(SimulationVerbs, EntityVerbs, ClockVerbs, UndoVerbs):
    """
    The simulator under test: its interfaces found by type, its features, its clock.

    Made by :meth:`connect` (which never raises for what the simulator does:
    ``features_error`` says why its features are unknown); closed by
    :meth:`close`. The clauses use the verbs of its mixins; each raises
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
