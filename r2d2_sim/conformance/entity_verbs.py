"""
The entities of the simulation under test: asking about them, placing, spawning, deleting.

:class:`TargetEntities` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.entities``): filters and bounds as the standard writes them,
GetEntities, GetEntityState, SetEntityState and GetEntityInfo in one call
each, and the kit's own box (URDF or SDF text, or ``--asset``) spawned at
slots in free space. It owns the names of what the kit spawned and has not
deleted, so that a clause can be undone. Requests are built by the
Target's client; the calls go through the Target's (``ok``, ``expect``).
"""

import itertools
from typing import Any, List, Optional, Sequence, Tuple

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped, one_line
from r2d2_sim.conformance.values import vector, yaw_quaternion

# The kit's own box: a cube this wide, 1 kg, from a resource string.
BOX_SIZE_M = 0.2

Point = Sequence[float]
IDENTITY = (0.0, 0.0, 0.0, 1.0)
STILL = (0.0, 0.0, 0.0)


class TargetEntities:
    """The entities of ``target``: queries, placing, the kit's box spawned and deleted."""

    def __init__(self, target: TargetCalls) -> None:
        self.target = target
        self.spawned: List[str] = []  # names the kit spawned and has not deleted
        self._names = itertools.count(1)
        self.problem = ''  # the asset given could not be spawned: the setup line
        self._given_spawns = False  # the asset given was spawned once (it is not tried again)

    # -- asking and placing ------------------------------------------------------------

    def filters(self, pattern: str = '', categories: Sequence[int] = (),
                tags: Sequence[str] = (), mode: int = 0,
                bounds: Optional[Tuple[int, Sequence[Point]]] = None) -> Any:
        """Return EntityFilters: a name regex, categories, tags (ANY 0 / ALL 1), (type, points)."""
        msg = self.target.msg
        filters = msg.EntityFilters(filter=pattern)
        filters.categories = [msg.EntityCategory(category=c) for c in categories]
        filters.tags = msg.TagsFilter(tags=list(tags), filter_mode=mode)
        if bounds is not None:
            kind, points = bounds
            filters.bounds = self.bounds(kind, points)
        return filters

    def bounds(self, kind: int, points: Sequence[Point]) -> Any:
        """Return a Bounds message of ``kind`` through ``points``."""
        from geometry_msgs.msg import Vector3
        return self.target.msg.Bounds(type=kind, points=[
            Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points])

    def names(self, filters: Any = None, doing: str = 'GetEntities') -> List[str]:
        """Return GetEntities' names for ``filters`` (default: all)."""
        t = self.target
        request = t.srv.GetEntities.Request()
        if filters is not None:
            request.filters = filters
        return list(t.ok('GetEntities', request, doing).entities)

    def state(self, name: str) -> Any:
        """Return GetEntityState's EntityState of ``name``."""
        t = self.target
        return t.ok('GetEntityState', t.srv.GetEntityState.Request(entity=name),
                    f'GetEntityState of {name}').state

    def position(self, name: str) -> Tuple[float, float, float]:
        """Return the position GetEntityState gives ``name``."""
        return vector(self.state(name).pose.position)

    def set_request(self, name: str, position: Point, orientation: Sequence[float] = IDENTITY,
                    linear: Point = STILL, angular: Point = STILL, frame: str = '',
                    stamp: Tuple[int, int] = (0, 0)) -> Any:
        """Return a SetEntityState request: a pose and a twist in ``frame``."""
        return self.target.client.entity_state_request(name, position, orientation, linear,
                                                       angular, frame, stamp)

    def place(self, name: str, position: Point, orientation: Sequence[float] = IDENTITY,
              linear: Point = STILL, angular: Point = STILL, frame: str = '') -> None:
        """Place ``name`` with SetEntityState (OK expected)."""
        self.target.ok('SetEntityState', self.set_request(name, position, orientation, linear,
                                                          angular, frame),
                       f'SetEntityState of {name}')

    def info(self, name: str) -> Any:
        """Return GetEntityInfo's EntityInfo of ``name``."""
        t = self.target
        return t.ok('GetEntityInfo', t.srv.GetEntityInfo.Request(entity=name),
                    f'GetEntityInfo of {name}').info

    # -- spawning ----------------------------------------------------------------------

    def new_name(self, stem: str = 'box') -> str:
        """Return a name for something the kit spawns: ``conformance_box_7``."""
        return f'conformance_{stem}_{next(self._names)}'

    def slot(self, index: int, z_offset: float = 0.0) -> Tuple[float, float, float]:
        """Return the ``index``-th place for the kit's entities: 3 m apart along x, in the air."""
        x, y, z = self.target.options.free_space
        return (x + 3.0 * index, y, z + z_offset)

    def resource_format(self) -> Optional[str]:
        """Return 'urdf' or 'sdf' when the kit may spawn from a resource string, else None."""
        t = self.target
        if not t.declared('SPAWNING_RESOURCE_STRING'):
            return None
        for fmt in ('urdf', 'sdf'):
            if fmt in t.spawn_formats:
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
        if self.target.options.asset:
            return self.target.options.asset, ''
        raise ClauseSkipped('nothing to spawn: give --asset URI (or declare '
                            'SPAWNING_RESOURCE_STRING with urdf or sdf in spawn_formats)')

    def spawn_request(self, name: str, position: Point, orientation: Sequence[float] = IDENTITY,
                      *, uri: Optional[str] = None, resource: Optional[str] = None,
                      frame: str = '', allow_renaming: bool = False, namespace: str = '',
                      stamp: Tuple[int, int] = (0, 0)) -> Any:
        """Return a SpawnEntity request; without ``uri`` and ``resource``, from :meth:`source`."""
        if uri is None and resource is None:
            uri, resource = self.source(name)
        return self.target.client.spawn_request(uri or '', resource or '', name, position,
                                                orientation, allow_renaming, namespace, frame,
                                                stamp)

    def spawn_call(self, request: Any, codes: Optional[Sequence[int]] = None,
                   doing: str = '') -> Any:
        """
        Send a SpawnEntity request; keep the name if it spawned; return the reply.

        The asset the user gave (``--asset``) is tried once: the first spawn of
        it alone refused is a setup problem (``problem``, one line), not the
        simulator's failure, and every clause that needs it is skipped.
        """
        t = self.target
        uri = t.options.asset
        given = bool(uri) and request.uri == uri
        if given and self.problem:
            raise ClauseSkipped(self.problem)
        doing = doing or f'SpawnEntity of {request.name or "(no name)"}'
        if given and not codes and not request.resource_string and not self._given_spawns:
            reply = t.call('SpawnEntity', request)
            if reply.result.result != t.msg.Result.RESULT_OK:
                self.problem = one_line(f'the asset given, {uri!r}, could not be spawned: '
                                        f'SpawnEntity answered '
                                        f'{t.describe("SpawnEntity", reply)}')
                raise ClauseSkipped(self.problem)
            self._given_spawns = True
        else:
            reply = t.expect('SpawnEntity', request, codes or (t.msg.Result.RESULT_OK,), doing)
        if reply.result.result == t.msg.Result.RESULT_OK and reply.entity_name:
            self.spawned.append(reply.entity_name)
        return reply

    def spawn(self, index: int = 0, *, name: Optional[str] = None, yaw: float = 0.0,
              position: Optional[Point] = None, frame: str = '') -> str:
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

    def delete(self, name: str, missing_ok: bool = False) -> None:
        """Delete ``name``: OK expected (or NOT_FOUND, with ``missing_ok``)."""
        t = self.target
        R = t.msg.Result
        codes = (R.RESULT_OK, R.RESULT_NOT_FOUND) if missing_ok else (R.RESULT_OK,)
        t.expect('DeleteEntity', t.srv.DeleteEntity.Request(entity=name), codes,
                 f'DeleteEntity of {name}')
        if name in self.spawned:
            self.spawned.remove(name)
