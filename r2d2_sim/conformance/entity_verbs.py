"""
The entities of the simulation under test: asking about them, placing, spawning, deleting.

:class:`EntityVerbs` is mixed into :class:`~r2d2_sim.conformance.target.Target`:
filters and bounds as the standard writes them, GetEntities, GetEntityState,
SetEntityState and GetEntityInfo in one call each, and the kit's own box
(URDF or SDF text, or ``--asset``) spawned at slots in free space, its name
kept so that the clause can be undone. They call through the Target's typed
calls (``ok``, ``expect``, ``declared``) and read what its ``__init__`` sets.
"""

from typing import List, Optional, Sequence, Tuple

from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.values import fill_pose, fill_vector, vector, yaw_quaternion

# The kit's own box: a cube this wide, 1 kg, from a resource string.
BOX_SIZE_M = 0.2


class EntityVerbs:
    """The Target's verbs for entities: queries, placing, the kit's box spawned and deleted."""

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
