"""
The PyBullet world: bodies on a plane, stepped at a fixed time step.

No ROS here. The world owns its own physics client (never the module-global
``pybullet`` state), so several worlds can live in one process and tests can
build and tear down their own. Every body in it is a
:class:`~r2d2_sim.physics.body.Body` with a unique name; bodies are referred to
through those objects, never through ids cached elsewhere (PyBullet reuses
the ids of removed bodies, and a rebuilt world gives every body a new one),
so bodies can be added and removed while it runs, and the whole world can be
built again from them (:meth:`SimWorld.reset`). While its bodies stay the same,
a state saved (:meth:`SimWorld.save_state`) is come back to at once, contacts
included (:meth:`SimWorld.restore_state`).
"""

from contextlib import contextmanager, nullcontext
from functools import partial
import math
import os
import socket
import sys
from typing import (
    Callable, Collection, Container, Dict, Iterator, List, Mapping, NamedTuple, Optional,
    Sequence, Tuple, Union)

import numpy

from r2d2_sim.memory import malloc_trim
from r2d2_sim.model.transforms import rotate, rotate_inverse, yaw_of
from r2d2_sim.physics.body import Body, file_stamp, Loading, WorldError
from r2d2_sim.physics import records
from r2d2_sim.physics.raycast import (
    cast_rays, cast_requests, RAY_EXCLUDED_GROUP, RAY_MASK, ray_mask, RayRequest)
from r2d2_sim.physics.records import Quat, Vec3
from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import
    import pybullet
import pybullet_data  # noqa: I100 (imported after pybullet on purpose)
from pybullet_utils.bullet_client import BulletClient

__all__ = ['SimWorld', 'WorldBuild', 'SavedWorld', 'WorldError', 'display_problem',
           'SPAWN_CLEARANCE_M', 'GROUND_PLANE_NAME', 'GROUND_HALF_WIDTH_M', 'RAY_GROUPS',
           'ray_mask', 'RayRequest', 'COMPACT_AFTER_REMOVALS', 'unique_name']

# Gap left between the lowest point of the robot and the ground at spawn, so
# that it starts just above the plane instead of interpenetrating it.
SPAWN_CLEARANCE_M = 0.001
GROUND_PLANE_NAME = 'ground_plane'
# pybullet_data's plane.urdf collides as a box 200 x 200 x 10 m, its top face at z 0, about
# its origin: past 100 m along its x or y there is nothing to stand on. Kept as it is (every
# contact and recording depends on it); poses off it are refused instead (off_ground).
GROUND_HALF_WIDTH_M = 100.0
IDENTITY_QUATERNION: Quat = (0.0, 0.0, 0.0, 1.0)
# Each robot's laser passes through its own links, put in a collision group
# of that robot's (one bit each), and sees every other robot. Bits 0 and 1
# are Bullet's default groups (dynamic, static); the group is a C int.
RAY_GROUPS = tuple(RAY_EXCLUDED_GROUP << bit for bit in range(29))  # 4 ... 2**30
# PyBullet 3.2.7 keeps a loaded URDF's shapes after removeBody (14-17 kB for our
# R2D2) until resetSimulation: after this many removals the world is built again
# in place (SimWorld.compact), so spawning and deleting for hours stays bounded.
COMPACT_AFTER_REMOVALS = 64


class SavedWorld(NamedTuple):
    """A state of a world kept by PyBullet (``saveState``), and the bodies it holds."""

    state_id: int                                # PyBullet's, in this world's client
    # Every body's name, id and the Body itself, in load order: a body deleted and another
    # spawned under its name takes its id too (PyBullet reuses ids), but is another Body.
    bodies: Tuple[Tuple[str, int, Body], ...]
    built: int                                   # which build of the world (clear() makes another)


def _found(path: str) -> str:
    """Return the file loadURDF reads for ``path``: as given, else in pybullet_data."""
    if os.path.isfile(path):
        return path
    return os.path.join(pybullet_data.getDataPath(), path)


def unique_name(taken: Container[str], wanted: str,
                usable: Callable[[str], bool] = lambda name: True) -> str:
    """Return ``wanted``, or with the first ``_1``, ``_2``... suffix not ``taken``, ``usable``."""
    name, suffix = wanted, 0
    while name in taken or not usable(name):
        suffix += 1
        name = f'{wanted}_{suffix}'
    return name


def display_problem(environ: Mapping[str, str] = os.environ) -> Optional[str]:
    """
    Return why PyBullet's window cannot open here (None if an X display answers).

    PyBullet's GUI connect ends the whole process (exit status 1, three lines
    of X11 errors) when no X server answers, so this looks first: DISPLAY set,
    and its socket (``/tmp/.X11-unix/X<n>`` or TCP 6000 + n) accepting.
    """
    display = environ.get('DISPLAY', '')
    if not display:
        return ('gui needs a display, and DISPLAY is not set (on a headless machine run '
                'under Xvfb: xvfb-run -a sim_node --ros-args -p gui:=true)')
    host, _, number = display.rpartition(':')
    number = number.split('.')[0]
    family = socket.AF_UNIX if host in ('', 'unix') else socket.AF_INET
    addresses: Sequence[Union[str, Tuple[str, int]]]  # AF_UNIX: paths; AF_INET: (host, port)
    try:
        if family == socket.AF_UNIX:
            # libxcb tries Linux's abstract socket first, then the file: an X server
            # that could not create /tmp/.X11-unix (a sandbox, another /tmp) answers
            # on the abstract one only.
            path = f'/tmp/.X11-unix/X{int(number)}'
            addresses = (['\0' + path] if sys.platform.startswith('linux') else []) + [path]
        else:
            addresses = [(host, 6000 + int(number))]
    except ValueError:
        return f'gui needs a display, and DISPLAY={display!r} is not one'
    reason = ''
    for address in addresses:
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.settimeout(1.0)
        try:
            sock.connect(address)
            return None
        except OSError as exc:
            reason = exc.strerror or str(exc)
        finally:
            sock.close()
    return f'gui needs a display, and none answers at DISPLAY={display} ({reason})'


class WorldBuild:
    """
    A physics world built body by body to take the live one's place (:meth:`SimWorld.build`).

    Beside (``beside``): in a PyBullet client of its own, set up as the
    live world's, while the live world goes on stepping; :meth:`SimWorld.take`
    swaps it in at once. A body of the live world loaded into it stays the
    same object: its twin here (``Body.loaded_into``) is adopted at the swap.
    In place (a GUI world: PyBullet opens one window only): the live world is
    emptied first and the bodies are loaded straight into it.
    """

    def __init__(self, client: BulletClient, bodies: Dict[str, Body], beside: bool,
                 free_ray_groups: List[int]) -> None:
        self.client = client
        self.bodies = bodies  # by name, in load order: the live world's dict when in place
        self.beside = beside
        self.twins: List[Tuple[Body, Body]] = []  # (a live body, its twin in this build)
        # The ray groups a robot built into it may take: a group need only be unique
        # within one client (the live world's list when in place).
        self.free_ray_groups = free_ray_groups
        self.taken = False


class SimWorld:
    """
    A PyBullet world: the ground and the bodies loaded into it, stepped at a fixed time step.

    It loads no robot of its own: :meth:`load_robot` places a driven robot
    standing on the ground, :meth:`load` any other description; every body
    is a :class:`~r2d2_sim.physics.body.Body` in :attr:`bodies`, by its unique
    name (in load order), and :meth:`reset` builds the world again with each
    where it started. Raises WorldError (one line) when the time step or the
    GUI cannot be had.
    """

    def __init__(self, *, gui: bool = False, time_step_s: float = 1.0 / 240.0,
                 gravity_m_s2: Vec3 = (0.0, 0.0, -9.8), ground_plane: bool = True,
                 name_rule: Callable[[str], str] = str) -> None:
        if not (math.isfinite(time_step_s) and time_step_s > 0.0):
            raise WorldError(f'time step must be a positive number of seconds, got {time_step_s}')
        self.time_step_s = time_step_s
        self.gui = gui
        self.gravity_m_s2 = gravity_m_s2
        # How a body loaded without a name is named after its URDF (default_name).
        self.name_rule = name_rule
        self.step_count = 0
        self.bodies: Dict[str, Body] = {}
        self.removed_since_built = 0  # bodies removed since the world was last built
        self.builds = 0  # how often the physics world was built (each clear() builds it anew)
        # Threads a large batch of rays is cast on (raycast.cast_rays): the same answers.
        self.ray_threads = 1
        self._free_ray_groups = list(RAY_GROUPS)
        # The bodies a robot built now takes its ray group among (ray_groups_of): None for
        # the live world's.
        self._ray_bodies: Optional[Dict[str, Body]] = None
        # The ray groups whose links no ray tests in the live world (exclude_from_rays).
        self._hidden_ray_groups = 0
        # How many robots with rays a start-up is about to build (expecting_ray_robots).
        self._ray_robots_expected = 0
        # A body's physics blew up and it was put back (put_back): what the blow-up
        # broke around it is still to be put back (repair).
        self.blown_up = False
        self._client: Optional[BulletClient] = None
        self._ground: Optional[Body] = None  # the ground plane this world loaded (plane.urdf)
        problem = display_problem() if gui else None
        if problem is not None:
            raise WorldError(problem)
        # 'argv[0]=' on every connect, on stdout; why a GUI cannot open goes to stderr.
        with silenced_output(stderr=False):
            self._client = BulletClient(
                connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        self._step_simulation = partial(pybullet.stepSimulation,
                                        physicsClientId=self._client._client)
        try:
            self._setup(gravity_m_s2)
            if ground_plane:
                self._ground = self.load('plane.urdf', name=GROUND_PLANE_NAME)
        except Exception:
            self.close()
            raise

    @property
    def _live_client(self) -> BulletClient:
        """Return the physics client; WorldError once the world is closed."""
        client = self._client
        if client is None:
            raise WorldError('the physics world is closed')
        return client

    def _setup(self, gravity: Vec3) -> None:
        self.removed_since_built = 0
        self.builds += 1  # states saved before are gone with the old physics world
        self._set_up(self._live_client, gravity)

    def _set_up(self, client: BulletClient, gravity: Vec3) -> None:
        """Empty ``client``'s physics world and set it up as at start."""
        client.resetSimulation()
        client.setAdditionalSearchPath(pybullet_data.getDataPath())
        client.setTimeStep(self.time_step_s)
        client.setGravity(*gravity)
        # Bullet's cone friction makes skid-steered wheels creep into a turn over
        # seconds (measured: 0.04 -> 0.11 rad/s for a 0.5 rad/s command); the
        # classic pyramid model reaches a steady yaw rate within 0.1 s.
        client.setPhysicsEngineParameter(enableConeFriction=0)
        if self.gui:
            client.configureDebugVisualizer(client.COV_ENABLE_GUI, 0)

    def off_ground(self, x: float, y: float) -> Optional[str]:
        """
        Return why a body standing at (x, y) would fall for ever (a phrase), None if it would not.

        Off the ground plane this world loaded (:data:`GROUND_HALF_WIDTH_M` to each
        side of its centre, where it is now: SetEntityState moves it as any
        static body), while that plane is in the world. None without it:
        another ground (a world's own floor) may be anywhere. Turned or
        tilted, the point of its top face above or below (x, y) is measured.
        """
        ground = self._ground
        if ground is None or self.bodies.get(GROUND_PLANE_NAME) is not ground:
            return None
        self._live_client  # WorldError once closed (a build the world's close ended)
        (px, py, _), rotation = ground.world_pose()
        dx, dy = x - px, y - py
        nx, ny, nz = rotate(rotation, (0.0, 0.0, 1.0))
        dz = -(nx * dx + ny * dy) / nz if abs(nz) > 1e-9 else 0.0  # on the top face's plane
        along, across, _ = rotate_inverse(rotation, (dx, dy, dz))
        edge = GROUND_HALF_WIDTH_M
        if abs(nz) > 1e-9 and max(abs(along), abs(across)) <= edge:
            return None
        if tuple(rotation) == IDENTITY_QUATERNION:
            if px == py:
                return f'off the ground plane (x and y from {px - edge:g} to {px + edge:g} m)'
            return (f'off the ground plane (x from {px - edge:g} to {px + edge:g} m, y from '
                    f'{py - edge:g} to {py + edge:g} m)')
        return (f'off the ground plane (turned, {edge:g} m to each side of its centre at '
                f'x {px:g}, y {py:g})')

    def default_name(self, urdf_name: str, path: str) -> str:
        """
        Return the name a body loaded from ``path`` with no name wants, before made unique.

        Its URDF's ``<robot name>`` (``urdf_name``), else its file's name without
        the suffix, as this world's ``name_rule`` makes it.
        """
        return self.name_rule(urdf_name or os.path.splitext(os.path.basename(path))[0])

    def unique_name(self, wanted: str, usable: Callable[[str], bool] = lambda name: True) -> str:
        """Return ``wanted``, or with the first free (and ``usable``) ``_1``, ``_2``... suffix."""
        return unique_name(self.bodies, wanted, usable)

    def load(self, path: str, position: Vec3 = (0.0, 0.0, 0.0),
             orientation: Quat = IDENTITY_QUATERNION, *, name: Optional[str] = None,
             flags: int = 0, body_yaw_offset_rad: float = 0.0, spawned: bool = False,
             source: Optional[str] = None, into: Optional[WorldBuild] = None,
             made_from: Optional[str] = None, given_as: Optional[str] = None) -> Body:
        """
        Load a URDF file as a new body; return it.

        ``name`` (default: the URDF's ``<robot name>`` as :meth:`default_name`
        gives it, made unique) must not be taken. ``orientation`` is that of
        the URDF base frame. ``into``: a world being built (:meth:`build`)
        instead of the live one.
        ``made_from``: what the user wrote, when ``path`` is a URDF made of it
        (``SDF model door of hinge.sdf``): an error names that, not a
        temporary file, and PyBullet's own messages about the made file
        (names the user never wrote) stay off stdout. ``given_as``: where
        the text of ``path``, a temporary file, was given (``the
        resource_string``): an error names that; PyBullet's messages (the
        user's own names) still show.
        """
        client, bodies = ((into.client, into.bodies) if into is not None
                          else (self._live_client, self.bodies))
        try:
            with silenced_output(stderr=False) if made_from is not None else nullcontext():
                body_id = client.loadURDF(path, basePosition=position,
                                          baseOrientation=orientation, flags=flags)
        except client.error as exc:
            raise WorldError(f'PyBullet cannot load {made_from or given_as or path}: '
                             f'{exc}') from None
        if name is None:
            name = unique_name(bodies, self.default_name(
                records.body_info(client, body_id).name, path))
        elif name in bodies:
            client.removeBody(body_id)
            raise WorldError(f'a body named {name!r} is already in the world')
        # Copied as tuples (a caller may pass lists), as loadURDF took them: 3 and 4 numbers.
        x, y, z = position
        qx, qy, qz, qw = orientation
        body = Body(client, body_id, name, source or path,
                    body_yaw_offset_rad=body_yaw_offset_rad, spawned=spawned,
                    loading=Loading(path, (x, y, z), (qx, qy, qz, qw), flags,
                                    file_stamp(_found(path))))
        bodies[name] = body
        hiding = self._hidden_ray_groups if into is None else self._hidden_in(bodies)
        if hiding and body.sets_own_collision_filters:
            self._show_hidden(bodies)  # a hidden link's contacts with it could differ
        return body

    def load_robot(self, path: str, pose: Tuple[float, float, float],
                   body_yaw_offset_rad: float = 0.0, *, name: Optional[str] = None,
                   spawned: bool = False, source: Optional[str] = None,
                   into: Optional[WorldBuild] = None, given_as: Optional[str] = None) -> Body:
        """
        Load a driven robot at (x, y, yaw), its lowest point just above the ground.

        True cylinders (``URDF_USE_IMPLICIT_CYLINDER``) roll smoothly; the
        default faceted convex hulls make wheels bump along. Inertias come
        from the file. ``given_as`` as :meth:`load` takes it.
        """
        x, y, yaw = pose
        client = into.client if into is not None else self._live_client
        orientation = client.getQuaternionFromEuler((0.0, 0.0, yaw - body_yaw_offset_rad))
        body = self.load(path, (x, y, 0.0), orientation, name=name, spawned=spawned,
                         flags=self.robot_flags, body_yaw_offset_rad=body_yaw_offset_rad,
                         source=source, into=into, given_as=given_as)
        position, _ = client.getBasePositionAndOrientation(body.id)
        body.set_initial_pose((position[0], position[1],
                               position[2] - body.bounding_box().low[2] + SPAWN_CLEARANCE_M),
                              orientation)
        return body

    @property
    def robot_flags(self) -> int:
        """Return the loadURDF flags of a driven robot: inertias from the file, true cylinders."""
        return pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_USE_IMPLICIT_CYLINDER

    @property
    def model_flags(self) -> int:
        """Return the loadURDF flags of a model made from SDF: its inertias, true cylinders."""
        return pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_USE_IMPLICIT_CYLINDER

    def take_ray_group(self) -> int:
        """
        Return a collision group bit of its own for a robot's sensor rays to pass through.

        The first robot gets 4 (``RAY_EXCLUDED_GROUP``), as when a world had one
        robot. WorldError when all 29 are taken: that many robots with a laser.
        """
        if not self._free_ray_groups:
            raise WorldError(f'{len(RAY_GROUPS)} robots with a laser scanner are in the world '
                             'already, as many as Bullet\'s collision groups can tell apart')
        if len(self._free_ray_groups) < len(RAY_GROUPS):
            self._show_hidden()  # another robot's rays must see the one already here
        return self._free_ray_groups.pop(0)

    def exclude_from_rays(self, body: Body, links: Sequence[int], group: int) -> None:
        """
        Make ``body``'s ``links`` invisible to rays of ``group`` (its robot's sensors').

        Hidden from every ray (untested: a third of a scan's time, the same
        ranges; see raycast's Hidden links) while the robot is the only one
        with rays in its world: its ``group`` the only one taken, no other
        robot with rays about to be built (:meth:`expecting_ray_robots`), and
        no body whose URDF sets its own collision filters (whose contacts a
        hidden mask could change). Else excluded as before, tested and
        masked. What would make hiding inexact later (another robot taking a
        ray group, a body setting its own filters loaded, rays cast that
        should see the links) shows them again first (:meth:`_show_hidden`).
        """
        bodies = self._bodies_for_rays()
        hidden = (self._ray_robots_expected <= 1
                  and len(self._free_ray_groups) == len(RAY_GROUPS) - 1
                  and group not in self._free_ray_groups
                  and not any(other.sets_own_collision_filters
                              for other in bodies.values() if other is not body))
        body.exclude_from_rays(links, group, hidden=hidden)
        if hidden and self._ray_bodies is None:
            self._hidden_ray_groups |= group

    @contextmanager
    def expecting_ray_robots(self, count: int) -> Iterator[None]:
        """Meanwhile ``count`` robots with rays are being built: none hides its links."""
        before, self._ray_robots_expected = self._ray_robots_expected, count
        try:
            yield
        finally:
            self._ray_robots_expected = before

    def _bodies_for_rays(self) -> Dict[str, Body]:
        return self.bodies if self._ray_bodies is None else self._ray_bodies

    def _show_hidden(self, bodies: Optional[Dict[str, Body]] = None) -> None:
        """
        Let every ray test the links hidden from them in ``bodies`` (default: ray_groups_of's).

        In the live world, then build it again as it is (:meth:`compact`):
        the links re-inserted into Bullet's broadphase now would be found in
        another order than after a rebuild (a reset), which loads them shown
        with their body; compacted, the run goes on as a rebuilt world's
        would. Its contacts start afresh, as after any compaction.
        """
        if bodies is None:
            bodies = self._bodies_for_rays()
        shown = [body.show_to_rays() for body in bodies.values()]
        if any(shown) and bodies is self.bodies:
            self.compact()
        self._hidden_ray_groups = self._hidden_in(self.bodies)

    @staticmethod
    def _hidden_in(bodies: Dict[str, Body]) -> int:
        """Return the ray groups hidden from every ray among ``bodies`` (bits; 0: none)."""
        hidden = 0
        for body in bodies.values():
            hidden |= body.hidden_ray_groups
        return hidden

    def release_ray_group(self, group: int) -> None:
        """Give a ray group back (its robot left the world)."""
        if group in RAY_GROUPS and group not in self._free_ray_groups:
            self._free_ray_groups.append(group)
            self._free_ray_groups.sort()

    def remove(self, body: Body) -> None:
        """Take ``body`` out of the world (every COMPACT_AFTER_REMOVALS, compacting it)."""
        if self.bodies.get(body.name) is body:
            del self.bodies[body.name]
        if body.alive:
            body.remove()
            self.removed_since_built += 1
            if self.removed_since_built >= COMPACT_AFTER_REMOVALS:
                self.compact()

    def compact(self) -> bool:
        """
        Build the world again, every body as it is now: PyBullet frees what removed ones left.

        Each body is loaded again in its order, with its lasting changes
        (:meth:`Body.reload`), and put back exactly as it was: base pose and
        twist, joints, motors (:meth:`Body.resume`). Contact manifolds start
        afresh, as after a reset: a run goes on a little differently than
        without, and the same way every time, since compaction comes after
        the same removals. Nothing is done (False) when a body's file is
        gone or changed since it was loaded (its size or mtime): it could not
        come back, and memory then grows as without compaction. WorldError
        (one line) if a body fails to load all the same (the others are back).
        """
        bodies = list(self.bodies.values())
        if not all(body.reloadable() for body in bodies):
            return False
        moments = [body.moment() for body in bodies]
        self.clear()
        failed = []
        for body, moment in zip(bodies, moments):
            try:
                self.reload(body)
            except WorldError as exc:  # the others still come back, as in reset()
                failed.append(str(exc))
                continue
            body.resume(moment)
        malloc_trim()  # else the freed shapes stay in the arena of the thread that removed
        if failed:
            raise WorldError('; '.join(failed))
        return True

    @property
    def client(self) -> BulletClient:
        """Return the PyBullet client of this world (for advanced use)."""
        return self._client

    @property
    def sim_time_s(self) -> float:
        """Return the simulated time since start, in seconds."""
        return self.step_count * self.time_step_s

    def step(self, steps: int = 1) -> None:
        """Advance the physics by ``steps`` fixed time steps."""
        step_simulation = self._step_simulation
        for _ in range(steps):
            step_simulation()
        self.step_count += steps

    def clear(self) -> None:
        """
        Empty the physics world and set it up as at start (``resetSimulation``).

        Every body is unloaded (its id gone) but kept, to be loaded again
        with :meth:`reload`; the step counter and the ray groups taken stay.
        """
        for body in self.bodies.values():
            body.unloaded()
        self.bodies = {}
        self._setup(self.gravity_m_s2)

    def reload(self, body: Body, into: Optional[WorldBuild] = None) -> None:
        """
        Load ``body`` again as it was loaded, in its initial state (see Body.reload).

        ``into``: into a world being built (beside: a twin the body adopts at
        :meth:`take`) instead of the live one, emptied before.
        """
        bodies = into.bodies if into is not None else self.bodies
        if body.name in bodies:
            raise WorldError(f'a body named {body.name!r} is already in the world')
        if into is not None and into.beside:
            into.twins.append((body, body.loaded_into(into.client)))
        else:
            body.reload()
        bodies[body.name] = body

    def build(self, beside: bool = True, keep_ray_groups: Sequence[int] = ()) -> WorldBuild:
        """
        Start building the world anew: load into the build, then :meth:`take` it.

        Beside (unless the world has PyBullet's window, which opens once): a
        client of its own, set up as this one, while this world goes on as it
        is. Else in place: the world is emptied now (:meth:`clear`).
        Either way the build starts as this world did (an emptied world is
        the same as a new one, bit for bit). ``keep_ray_groups``: the groups
        of the robots that go on into the build (the others are free there).
        """
        if beside and not self.gui:
            with silenced_output(stderr=False):
                client = BulletClient(connection_mode=pybullet.DIRECT)
            try:
                self._set_up(client, self.gravity_m_s2)
            except BaseException:
                client.disconnect()
                raise
            free = [group for group in RAY_GROUPS if group not in keep_ray_groups]
            return WorldBuild(client, {}, True, free)
        self.clear()
        return WorldBuild(self._live_client, self.bodies, False, self._free_ray_groups)

    @contextmanager
    def ray_groups_of(self, build: Optional[WorldBuild]) -> Iterator[None]:
        """Take and give back ray groups from ``build``'s list meanwhile (robots built into it)."""
        if build is None or not build.beside:
            yield
            return
        live = self._free_ray_groups, self._ray_bodies
        self._free_ray_groups, self._ray_bodies = build.free_ray_groups, build.bodies
        try:
            yield
        finally:
            self._free_ray_groups, self._ray_bodies = live

    def take(self, build: WorldBuild) -> None:
        """
        Make ``build`` the world, at once: its bodies, in their order; the old ones are gone.

        A body of the old world not in the build is unloaded (kept, as by
        :meth:`clear`); one reloaded into it takes its twin's place. The step
        counter and the ray groups taken stay.
        """
        if not build.beside:
            return
        old = self._live_client  # WorldError once closed: a build is not taken then
        for body, twin in build.twins:
            body.adopt(twin)
        kept = {id(body) for body in build.bodies.values()}
        for body in self.bodies.values():
            if id(body) not in kept:
                body.unloaded()
        self._client = build.client
        self._step_simulation = partial(pybullet.stepSimulation,
                                        physicsClientId=build.client._client)
        self.bodies = dict(build.bodies)
        self._free_ray_groups = build.free_ray_groups
        self._hidden_ray_groups = self._hidden_in(self.bodies)
        self.removed_since_built = 0
        self.builds += 1  # states saved before are gone with the old physics world
        build.twins.clear()
        build.taken = True  # its client is the world's now: abandon() leaves it alone
        try:
            old.disconnect()
        except pybullet.error:
            pass  # gone already: nothing of it is used any more
        malloc_trim()

    def abandon(self, build: WorldBuild) -> None:
        """Drop a build that will not be taken (its client disconnected); safe to call twice."""
        if build.beside and not build.taken and build.client.isConnected():
            build.client.disconnect()
        build.twins.clear()

    def reset(self) -> None:
        """
        Build the world again, every body loaded in its order as it was: initial pose, at rest.

        Bullet keeps contact manifolds and the order of its overlapping pairs
        from step to step, and a body put back in place leaves them behind:
        a run after that does not repeat the first one bit for bit. Rebuilt,
        the world is as it was after loading, and the bodies are the same
        objects with new ids. The step counter keeps counting: simulated
        time never goes backwards. WorldError if a body cannot be loaded again
        (it is then left out).
        """
        bodies = list(self.bodies.values())
        self.clear()
        failed = []
        for body in bodies:
            try:
                self.reload(body)
            except WorldError as exc:
                failed.append(str(exc))
        if failed:
            raise WorldError('; '.join(failed))

    def put_back(self, body: Body) -> Optional[str]:
        """
        Put a body whose physics blew up back in its initial state: loaded again, in its place.

        Resetting it in place is not enough: after two steps with a NaN,
        Bullet keeps something inside the multibody that no reset reaches
        (its state reads finite and its contacts are found, yet they do not
        hold it: a robot sinks through the floor), and a NaN contact point
        would stay in its pairs. So it is loaded again, with its lasting
        changes (:meth:`Body.loaded_into`), and takes the old one's place
        in :attr:`bodies` (the same object; a new id, last in Bullet's
        order: a state saved before is refused by :meth:`restore_state`).
        A body whose file is gone or changed (:meth:`Body.reloadable`), or
        that fails to load (the old one is still there then), is put back
        in place instead, its pairs dropped (:meth:`Body.reinsert`) where
        its URDF allows. Returns None, or why it was put back in place only
        (one line). Its motors are those of a loaded body.
        """
        why: Optional[str] = None
        if body.reloadable():
            try:
                twin = body.loaded_into(self._live_client)
            except WorldError as exc:
                why = str(exc)
            else:
                body.remove()
                self.removed_since_built += 1
                body.adopt(twin)
                body.reset()  # exactly the state it started in, to the bit
                return None
        else:
            why = f'{body.source} is gone or changed since {body.name} was loaded from it'
        body.reset()
        try:
            body.reinsert()
        except WorldError:
            pass  # it sets its own collision groups: its pairs stay
        return why

    def repair(self, leave: Collection[Body] = ()) -> List[Tuple[Body, Optional[str]]]:
        """
        After a blow-up (:attr:`blown_up`): put back what it broke; return what was put back.

        A NaN in one body's state spreads in that one step, through its
        contacts, to what it touches: the ground plane too, whose pose and
        bounding box become NaN. Bullet then finds no pair with the ground
        any more, and a robot put back falls through the floor for ever,
        with every other body on it. Each body whose state is not finite,
        but those in ``leave`` (the driven robots, which put themselves
        back, controller and all), is put back (:meth:`put_back`), each
        whatever became of the others: returned with why it was only put
        back in place (None: loaded again).
        """
        self.blown_up = False
        left = {id(body) for body in leave}
        broken = [body for body in self.bodies.values()
                  if id(body) not in left and not body.finite()]
        put = [(body, self.put_back(body)) for body in broken]
        if self.removed_since_built >= COMPACT_AFTER_REMOVALS:
            self.compact()
        return put

    def save_state(self) -> SavedWorld:
        """
        Keep the physics state now in memory, to come back to it with :meth:`restore_state`.

        From the first save on, Bullet handles its overlapping pairs in the
        order of their bodies' links (``deterministicOverlappingPairs``), not
        in the order it found them, which depends on everything that ran
        before. WorldError (one line) for a body whose URDF sets its own
        collision groups (see :meth:`Body.collision_filters`).
        """
        client = self._live_client
        for body in self.bodies.values():
            body.collision_filters()
        client.setPhysicsEngineParameter(deterministicOverlappingPairs=1)
        return SavedWorld(client.saveState(), self._body_ids(), self.builds)

    def restore_state(self, saved: SavedWorld) -> None:
        """
        Put the physics back as :meth:`save_state` kept it: every run from it the same.

        Every body's pose, twist and joints come back (PyBullet's
        ``restoreState``); Bullet's pairs and contact points are dropped
        (each body put into the broadphase again, in load order): kept, they
        would be those of whatever ran since, in the order it met them, and
        the next steps would differ from those of a world that ran nothing
        else. So a run from the state repeats any other run from it, not the
        run that went on from the save. Motors and lasting changes of the
        bodies stay as they are. Only the same bodies can come back
        (``restoreState`` matches them by id, and a body spawned in a deleted
        one's place takes its id and may take its name: the Body objects are
        compared): WorldError (one line) once a body was added, removed or
        loaded again since, or the world built again.
        """
        if saved.built != self.builds or saved.bodies != self._body_ids():
            raise WorldError('the saved state is of other bodies: bodies were added, removed '
                             'or loaded again since it was saved')
        self._live_client.restoreState(stateId=saved.state_id)
        for body in self.bodies.values():
            body.reinsert()

    def forget_state(self, saved: SavedWorld) -> None:
        """Free a state :meth:`save_state` kept; nothing if the world was built again since."""
        if saved.built == self.builds and self._client is not None:
            self._client.removeState(saved.state_id)

    def _body_ids(self) -> Tuple[Tuple[str, int, Body], ...]:
        return tuple((name, body.id, body) for name, body in self.bodies.items())

    def cast_rays(self, starts: numpy.ndarray, ends: numpy.ndarray,
                  mask: int = RAY_MASK) -> numpy.ndarray:
        """
        Cast rays (N x 3 world points) and return hit fractions (1.0: no hit); see raycast.

        ``mask``: the groups the rays can hit; ``ray_mask(group)`` passes
        through the links a robot put in its own ray group.
        """
        if mask & self._hidden_ray_groups:
            self._show_hidden(self.bodies)  # these rays see links hidden from rays
        return cast_rays(self._live_client, starts, ends, mask, threads=self.ray_threads)

    def cast_requests(self, requests: Sequence[RayRequest]) -> List[numpy.ndarray]:
        """Cast several sensors' rays in as few calls as their robots allow (see raycast)."""
        hidden = self._hidden_ray_groups
        if hidden and any(ray_mask(request.group) & hidden for request in requests):
            self._show_hidden(self.bodies)  # these rays see links hidden from rays
        return cast_requests(self._live_client, requests, self.ray_threads)

    def render(self, width_px: int, height_px: int, view: Sequence[float],
               projection: Sequence[float]) -> Tuple[bytes, numpy.ndarray]:
        """
        Render with the CPU renderer: rgb8 rows (top row first) and the raw depth buffer.

        ER_TINY_RENDERER works without a display (DIRECT mode) and gives the
        same pixels in GUI mode, so tests and headless runs see what users see.
        The depth buffer is OpenGL's non-linear d in [0, 1], shaped (height, width).
        """
        rgb, depth, _ = self._render(width_px, height_px, view, projection,
                                     pybullet.ER_NO_SEGMENTATION_MASK)
        return rgb, depth

    def render_seeing(self, body: Body, width_px: int, height_px: int, view: Sequence[float],
                      projection: Sequence[float]) -> Tuple[bytes, numpy.ndarray, numpy.ndarray]:
        """
        Render as :meth:`render` does, and say where ``body`` is seen: a bool per pixel.

        The same pixels as :meth:`render` (the renderer's segmentation mask
        is drawn beside them); the mask is (height, width), True where the
        nearest surface is one of the body's links.
        """
        rgb, depth, segmentation = self._render(width_px, height_px, view, projection, 0)
        # Without ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX each pixel is the body's id, -1 none.
        return rgb, depth, segmentation.reshape(height_px, width_px) == body.id

    def _render(self, width_px: int, height_px: int, view: Sequence[float],
                projection: Sequence[float], flags: int
                ) -> Tuple[bytes, numpy.ndarray, numpy.ndarray]:
        _, _, rgba, depth, segmentation = self._live_client.getCameraImage(
            width_px, height_px, viewMatrix=list(view), projectionMatrix=list(projection),
            renderer=pybullet.ER_TINY_RENDERER, flags=flags)
        rgb = numpy.asarray(rgba, dtype=numpy.uint8).reshape(height_px, width_px, 4)[:, :, :3]
        return (rgb.tobytes(), numpy.asarray(depth, dtype=float).reshape(height_px, width_px),
                numpy.asarray(segmentation))

    def follow_camera(self, body: Body, distance_m: float = 2.0) -> None:
        """Point the GUI camera at a body; no-op without a window."""
        if not self.gui:
            return
        base = body.world_state()
        yaw = math.degrees(yaw_of(base.orientation))
        self._live_client.resetDebugVisualizerCamera(distance_m, yaw - 90.0, -30.0,
                                                     base.position)

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice."""
        client = self._client
        if client is not None:
            try:
                client.disconnect()
            except pybullet.error:
                pass
            self._client = None

    @property
    def connected(self) -> bool:
        """Return True while the physics client is connected."""
        return self._client is not None and self._client.isConnected()

    def __enter__(self) -> 'SimWorld':
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
