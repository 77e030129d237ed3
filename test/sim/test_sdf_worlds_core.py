"""
Gazebo worlds in the core: loaded, scanned, driven in, spawned into, loaded twice the same.

No ROS. The arena (``sdf_files.arena``) is a Gazebo world the tests write
themselves: a concave DAE wall ring around the robot (in centimetres), an STL
pillar, a nested model with an SDF cylinder, an OBJ crate that can move, the
Fuel ground plane and sun, frames as named poses. What the laser measures is
checked against the geometry worked out from the sizes written, within 1 cm;
falls against Bullet's integration of gravity; a second load against the first
bit for bit.
"""

import json
import math
import os
import subprocess
import sys

import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import yaw_of
from r2d2_sim.sim.entities import Category
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.worlds import LoadOptions
from sdf_files import (
    arena, ARENA_HALF_M, box_model, CRATE_SIZE_M, PILLAR, POST, sdf, wall_range)

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'imu_rate': 0.0}
GRAVITY = 9.8
STEP_S = 1.0 / 240.0


@pytest.fixture
def world_dir(tmp_path, monkeypatch):
    """Write the arena; return its directory (meshes cached under it, not in ~/.cache)."""
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    arena(tmp_path)
    return tmp_path


def arena_simulation(make, world_dir, errors=None, **parameters):
    return make(errors=errors, world=str(world_dir / 'arena.sdf'),
                model_paths=[str(world_dir / 'models')], **parameters)


def test_a_gazebo_world_loads_from_the_world_parameter(make, world_dir):
    warnings = []
    simulation = arena_simulation(make, world_dir)
    simulation._warn = warnings.append
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'arena_wall', 'pillar',
                                           'corner']
    world = simulation.worlds.current
    assert (world.name, world.tags) == ('arena', ('sdf',))
    assert [(p.name, p.position) for p in world.named_poses] == [
        ('start', pytest.approx((0.0, 0.0, 0.0))),
        ('goal', pytest.approx((PILLAR[0] - 0.8, PILLAR[1], 0.0)))]
    assert world.start_pose.name == 'start'
    assert world.notes == (
        'not simulated: physics max_step_size 0.001 s (r2d2_sim steps 0.00416667 s: '
        'physics_rate), plugin, light',)
    assert "its ground plane is r2d2_sim's" in world.description
    for name in ('arena_wall', 'pillar', 'corner'):
        assert simulation.entities.category(name) == Category.STATIC_OBJECT
    assert simulation.entities.state('pillar').position == pytest.approx((*PILLAR[:2], 0.0))


def test_the_one_summary_line_is_warned_once_at_start_up(make, world_dir):
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    config, robots = parse_world({'world': str(world_dir / 'arena.sdf'),
                                  'model_paths': [str(world_dir / 'models')]})
    warnings = []
    simulation = Simulation(config, robots, warn=warnings.append)
    try:
        assert warnings == ['world arena: not simulated: physics max_step_size 0.001 s '
                            '(r2d2_sim steps 0.00416667 s: physics_rate), plugin, light']
    finally:
        simulation.close()


def scan_errors(simulation):
    """Return |measured - analytic| for every beam of the robot's laser (grazing ones left out)."""
    robot = simulation.robot
    base = robot.body.world_state()
    x, y = base.position[:2]
    yaw = yaw_of(base.orientation)
    circles = [PILLAR, POST]
    errors = []
    for angle, measured in zip(robot.laser.geometry.angles_rad, robot.laser.scan()):
        expected = wall_range(x, y, angle + yaw, circles)
        if not math.isnan(expected):
            errors.append(abs(float(measured) - expected))
    return errors


def test_the_scan_inside_a_concave_wall_mesh_matches_the_geometry_within_a_centimetre(
        make, world_dir):
    """A convex hull of the wall would put the robot inside a solid block: ranges of 0."""
    simulation = arena_simulation(make, world_dir)
    for _ in range(24):
        simulation.step()
    errors = scan_errors(simulation)
    assert len(errors) > 300
    assert max(errors) < 0.01
    # And away from the middle, turned: the walls are where the geometry says from anywhere.
    simulation.set_entity_state('r2d2', '', (-0.5, -0.8, 0.47), (0.0, 0.0, 0.38268, 0.92388),
                                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    for _ in range(24):
        simulation.step()
    assert max(scan_errors(simulation)) < 0.01


def test_the_robot_drives_inside_the_concave_wall_without_touching_it(make, world_dir):
    simulation = arena_simulation(make, world_dir)
    robot, world = simulation.robot, simulation.world
    robot.command(0.4, 0.0)
    touched = 0
    for step in range(240 * 3):
        simulation.step()
        if step % 24 == 0:
            wall = world.bodies['arena_wall'].id
            touched += sum(1 for point in robot.body.contacts() if point.body_b == wall)
    position = robot.body.world_state().position
    assert position[0] > 0.8  # about 1.1 m at 0.4 m/s after the ramp
    assert abs(position[1]) < 0.1 and max(abs(position[0]), abs(position[1])) < ARENA_HALF_M
    assert touched == 0
    assert min(scan_errors(simulation)) < 0.01 and max(scan_errors(simulation)) < 0.01


def fall(simulation, name, steps):
    for _ in range(steps):
        simulation.step()
    return simulation.entities.state(name).position[2]


def test_a_spawned_sdf_model_falls_as_gravity_says_and_rests_on_the_ground(make, world_dir):
    """Bullet integrates v += -g dt, z += v dt: after n steps z0 - g dt^2 n (n + 1) / 2."""
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    text = sdf(box_model('falling', size=(0.4, 0.4, 0.6)))
    name = simulation.spawn(SpawnRequest(resource_string=text, position=(-1.0, -1.0, 2.0)))
    assert name == 'falling'
    n = 60
    assert fall(simulation, name, n) == pytest.approx(
        2.0 - GRAVITY * STEP_S ** 2 * n * (n + 1) / 2.0, abs=1e-5)
    assert fall(simulation, name, 480) == pytest.approx(0.3, abs=2e-3)  # half its height
    assert simulation.entities.category(name) == Category.DYNAMIC_OBJECT


def test_a_spawned_mesh_model_from_the_model_path_rests_on_its_hull(make, world_dir):
    """The crate's link is 0.2 m above its model frame: it rests with the frame on the ground."""
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    name = simulation.spawn(SpawnRequest(uri='model://crate', position=(1.0, -1.0, 1.0)))
    assert simulation.entities.state(name).position[2] == pytest.approx(1.2)  # its link
    assert fall(simulation, name, 480) == pytest.approx(CRATE_SIZE_M / 2.0, abs=2e-3)


def test_a_model_directory_spawns_as_sdf_by_path_and_file_uri(make, world_dir):
    """Spawn a directory as docs/sdf-worlds.md says (it was NOT_FOUND "URDF file not found")."""
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    directory = str(world_dir / 'models' / 'crate')
    for name, uri in (('by_path', directory), ('by_uri', 'file://' + directory)):
        assert simulation.spawn(SpawnRequest(uri=uri, name=name,
                                             position=(1.0, -1.0, 1.0))) == name
        assert simulation.entities.state(name).position[2] == pytest.approx(1.2)  # its link


@pytest.mark.parametrize('static, expected', [(False, (1.0, 5.0, 0.5)),   # its link
                                              (True, (0.0, 5.0, 0.0))])   # the model frame
def test_a_spawned_models_state_is_its_canonical_links_or_a_static_ones_model_frame(
        make, static, expected):
    """A box 1 m along x and 0.5 m up from its model frame, spawned at (0, 5, 0)."""
    simulation = make()
    link = '<link name="link"><pose>1 0 0.5 0 0 0</pose>'
    text = sdf(box_model('box', static=static).replace('<link name="link">', link, 1))
    name = simulation.spawn(SpawnRequest(resource_string=text, position=(0.0, 5.0, 0.0)))
    assert simulation.entities.state(name).position == pytest.approx(expected, abs=1e-9)


def states(simulation):
    return [(name, tuple(body.world_state())) for name, body in
            simulation.world.bodies.items()]


def run_arena(make, world_dir, cache):
    os.environ['R2D2_SIM_CACHE_DIR'] = str(world_dir / cache)
    simulation = arena_simulation(make, world_dir, noise_seed=3, scan_noise_std=0.01)
    simulation.spawn(SpawnRequest(uri='model://crate', position=(0.8, 0.0, 0.6)))
    simulation.spawn(SpawnRequest(resource_string=sdf(box_model('lid')),
                                  position=(0.8, 0.0, 1.5)))
    simulation.robot.command(0.3, 0.2)
    scans = []
    for _ in range(480):
        result = simulation.step()
        if result is not None and result.measurements[0].scan is not None:
            scans.append(result.measurements[0].scan.tobytes())
    return states(simulation), scans


def test_loading_the_same_world_twice_gives_bit_identical_physics(make, world_dir):
    """Cold (meshes converted) and warm (from the cache): the same run, bit for bit."""
    first = run_arena(make, world_dir, 'cache_a')
    assert os.listdir(world_dir / 'cache_a' / 'meshes')
    second = run_arena(make, world_dir, 'cache_a')
    third = run_arena(make, world_dir, 'cache_b')
    assert first == second == third
    assert first[0][-1][1][0][2] > 0.3  # the lid came to rest on the crate


JOINTS = sdf('''<model name="rig"><static>false</static>
  <link name="base"><inertial><mass>0</mass></inertial>
    <collision name="c"><geometry><box><size>0.1 0.1 0.1</size></box></geometry></collision>
  </link>
  <joint name="anchor" type="fixed"><parent>world</parent><child>base</child></joint>
  <link name="arm"><pose>0.5 0 0 0 0 0</pose>
    <inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia>
    </inertial></link>
  <joint name="hinge" type="revolute"><pose>-0.5 0 0 0 0 0</pose><parent>base</parent>
    <child>arm</child><axis><xyz>0 1 0</xyz></axis></joint>
  <link name="stiff"><pose>0 0.5 0 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01</ixx>
    <iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
  <joint name="rusty" type="revolute"><pose>0 -0.5 0 0 0 0</pose><parent>base</parent>
    <child>stiff</child><axis><xyz>1 0 0</xyz><dynamics><friction>100</friction></dynamics>
    </axis></joint>
  <link name="bob"><pose>0 0 -0.5 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01</ixx>
    <iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
  <joint name="ball" type="ball"><parent>base</parent><child>bob</child></joint>
  <link name="cardan"><pose>0 0 0.5 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01</ixx>
    <iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
  <joint name="cross" type="universal"><parent>base</parent><child>cardan</child>
    <axis><xyz>1 0 0</xyz></axis><axis2><xyz>0 1 0</xyz></axis2></joint>
</model>''')


def test_joints_are_free_but_for_their_friction_and_each_type_has_its_bullet_joint(make):
    simulation = make(scan_rate=0.0)
    name = simulation.spawn(SpawnRequest(resource_string=JOINTS, position=(3.0, 3.0, 2.0)))
    body = simulation.world.bodies[name]
    kinds = {joint.name: joint.type_name for joint in body.joints.values()}
    # A universal joint is two revolute joints through a small link between them.
    assert kinds == {'hinge': 'revolute', 'rusty': 'revolute', 'ball': 'spherical',
                     'cross__first': 'revolute', 'cross': 'revolute'}
    assert body.static  # fixed to the world by its base
    hinge, rusty = body.joints['hinge'].index, body.joints['rusty'].index
    for _ in range(120):
        simulation.step()
    angles = body.joint_states([hinge, rusty]).positions
    # The arm (1 m from the hinge, horizontal) swings down under gravity; the rusty joint's
    # friction (100 N m) holds its 0.5 m arm (4.9 N m) still.
    assert abs(angles[0]) > 0.5
    assert abs(angles[1]) < 1e-3


def arm(name: str, y: float) -> str:
    """Return a 1 kg link hanging nothing yet: level with its hinge, ``y`` m from it."""
    return (f'<link name="{name}"><pose>0 {y} 2 0 0 0</pose><inertial><mass>1</mass>'
            '</inertial><collision name="c"><geometry><sphere><radius>0.05</radius></sphere>'
            '</geometry></collision></link>')


def hinge(name: str, child: str, y: float, kind: str = 'revolute') -> str:
    """Return a joint about x from the hub to ``child``, at the hub (``y`` m from the child)."""
    axes = '<axis><xyz>1 0 0</xyz></axis>' + ('<axis2><xyz>0 0 1</xyz></axis2>'
                                              if kind == 'universal' else '')
    return (f'<joint name="{name}" type="{kind}"><parent>hub</parent><child>{child}</child>'
            f'<pose>0 {-y} 0 0 0 0</pose>{axes}</joint>')


def test_joints_whose_names_meet_once_made_urdf_safe_are_each_a_joint(tmp_path):
    """
    ``j k`` and ``j_k`` are both ``j_k`` in a URDF: PyBullet killed the node (SIGSEGV).

    So did a joint named ``u__first`` beside a universal joint ``u`` (written
    as ``u__first`` and ``u``). Loaded in a process of its own, as a crash
    would take the test runner with it; every arm must swing on its own joint.
    """
    world = tmp_path / 'arms.sdf'
    world.write_text(sdf(
        '<world name="w"><model name="arms"><link name="hub"><pose>0 0 2 0 0 0</pose>'
        '<inertial><mass>1</mass></inertial></link><joint name="base" type="fixed">'
        '<parent>world</parent><child>hub</child></joint>' +
        arm('b', 0.5) + arm('c', -0.5) + arm('d', 0.7) + arm('e', -0.7) +
        hinge('j k', 'b', 0.5) + hinge('j_k', 'c', -0.5) + hinge('u', 'd', 0.7, 'universal') +
        hinge('u__first', 'e', -0.7) + '</model></world>'))
    code = '\n'.join([
        'import json',
        'from r2d2_sim.sim.settings.robots import parse_world',
        'from r2d2_sim.sim.simulation import Simulation',
        f"config, robots = parse_world({{'world': {str(world)!r}, 'scan_rate': 0.0,",
        "                                'imu_rate': 0.0, 'cmd_vel_timeout': 0.0})",
        'simulation = Simulation(config, robots)',
        "body = simulation.world.bodies['arms']",
        "joints = {j.name: j.index for j in body.joints.values() if j.type_name != 'fixed'}",
        'for _ in range(120):',
        '    simulation.step()',
        'angles = body.joint_states(list(joints.values())).positions',
        'print(json.dumps(dict(zip(joints, angles))))',
        'simulation.close()',
    ])
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    angles = json.loads(result.stdout.splitlines()[-1])
    assert sorted(angles) == ['j_k', 'j_k_1', 'u', 'u__first', 'u__first_1']
    # After 0.5 s each level arm has swung down about x on its own joint, mirrored pairs
    # alike; the universal joint's second axis (z) stays still.
    assert angles['j_k'] < -0.3 and angles['j_k_1'] == pytest.approx(-angles['j_k'])
    assert angles['u__first'] < -0.3
    assert angles['u__first_1'] == pytest.approx(-angles['u__first'], abs=1e-6)
    assert angles['u'] == pytest.approx(0.0, abs=1e-6)


def test_links_no_joint_joins_are_bodies_of_their_own_and_cannot_be_one_spawn(make, tmp_path):
    apart = sdf('<world name="w"><model name="pair">'
                '<link name="a"><collision name="c"><geometry><sphere><radius>0.1</radius>'
                '</sphere></geometry></collision></link>'
                '<link name="b"><pose>1 0 0 0 0 0</pose></link></model></world>')
    path = tmp_path / 'pair.sdf'
    path.write_text(apart)
    simulation = make(world=str(path), scan_rate=0.0)
    assert simulation.entities.names()[-2:] == ['pair', 'pair__b']
    model = apart.replace('<world name="w">', '').replace('</world>', '')
    with pytest.raises(RefusedError) as raised:
        simulation.spawn(SpawnRequest(resource_string=model))
    assert raised.value.code == 'UNSUPPORTED_ASSETS'
    assert 'make 2 bodies that no joint joins' in raised.value.message


def tilted_box(name: str, inertia: str, static: bool = False) -> str:
    return (f'<model name="{name}"><static>{str(static).lower()}</static>'
            '<pose>0 3 0.5 0.3 0 0</pose><link name="l">'
            f'<inertial><mass>1</mass><inertia>{inertia}</inertia></inertial>'
            '<collision name="c"><geometry><box><size>0.2 0.2 0.2</size></box></geometry>'
            '</collision></link></model>')


@pytest.mark.parametrize('inertia', [
    '<ixx>0</ixx><iyy>0</iyy><izz>0</izz>',
    '<ixx>0.001</ixx><iyy>0.001</iyy><izz>1</izz>',                 # no triangle
    '<ixx>0.01</ixx><ixy>0.02</ixy><iyy>0.01</iyy><izz>0.01</izz>',  # not positive definite
])
def test_a_moving_link_with_an_inertia_no_body_has_is_refused_in_one_line(make, inertia):
    """Refuse what PyBullet zeroed silently, so the box never rotated (LINK_INERTIA_INVALID)."""
    simulation = make(scan_rate=0.0)
    with pytest.raises(RefusedError) as raised:
        simulation.spawn(SpawnRequest(resource_string=sdf(tilted_box('box', inertia))))
    assert raised.value.code == 'RESOURCE_PARSE_ERROR'
    assert 'link l moves, so its inertia must be positive definite' in raised.value.message
    assert '\n' not in raised.value.message
    # A static model's links never move: its inertia is not used, nor checked.
    simulation.spawn(SpawnRequest(resource_string=sdf(tilted_box('still', inertia, True))))
    simulation.spawn(SpawnRequest(resource_string=sdf(
        tilted_box('fine', '<ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>'))))


def test_the_camera_sees_the_colours_of_the_world(make, world_dir):
    """The post is red, the pillar yellow, the wall grey: render toward each from the middle."""
    from r2d2_sim.model.camera import projection_matrix, view_matrix
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    projection = projection_matrix(64, 64, 30.0, 0.05, 20.0)

    def centre(target):
        view = view_matrix((0.0, 0.0, 0.6), (target[0], target[1], 0.0), (0.0, 0.0, 1.0))
        rgb, _ = simulation.world.render(64, 64, view, projection)
        offset = (32 * 64 + 32) * 3
        return tuple(rgb[offset:offset + 3])
    red, yellow, grey = centre(POST), centre(PILLAR), centre((0.0, -ARENA_HALF_M))
    assert red[0] > 100 and red[0] > 3 * max(red[1], red[2])
    assert min(yellow[:2]) > 100 and yellow[2] < 0.5 * min(yellow[:2])
    assert max(grey) - min(grey) < 30 and 60 < grey[0] < 220


def test_load_world_takes_an_sdf_world_and_a_full_reset_builds_it_again(make, world_dir):
    simulation = make(scan_rate=0.0, model_paths=[str(world_dir / 'models')],
                      world_paths=[str(world_dir)])
    world = simulation.load_world(str(world_dir / 'arena.sdf'))
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'arena_wall', 'pillar',
                                           'corner']
    assert world.notes and world.notes[0].startswith('not simulated:')
    simulation.delete_entity('pillar')
    simulation.reset(time=True, state=True, spawned=True)
    assert 'pillar' in simulation.entities.names()
    with pytest.raises(RefusedError) as raised:
        simulation.load_world(str(world_dir / 'arena.sdf'),
                              options=LoadOptions(fail_on_unsupported_element=True))
    assert raised.value.code == 'UNSUPPORTED_ELEMENTS'
    assert simulation.worlds.current is world  # refused: the world as it was


def test_strict_worlds_refuses_at_start_up_in_one_line(make, world_dir):
    from r2d2_sim.errors import WorldError
    with pytest.raises(WorldError, match=r'^world .*arena\.sdf: not simulated: physics '):
        arena_simulation(make, world_dir, strict_worlds=True)


def test_without_r2d2_sims_ground_plane_the_worlds_own_is_loaded(make, world_dir):
    simulation = arena_simulation(make, world_dir, ground_plane=False, scan_rate=0.0)
    assert simulation.entities.names()[:2] == ['r2d2', 'ground_plane']
    name = simulation.spawn(SpawnRequest(resource_string=sdf(box_model('b')),
                                         position=(-1.0, 1.0, 0.5)))
    assert fall(simulation, name, 480) == pytest.approx(0.2, abs=2e-3)  # on the SDF's plane


def test_a_model_of_hundreds_of_shapes_loads(make, tmp_path):
    """
    Load a static model of 300 shapes: each of its URDF elements on a line of its own.

    PyBullet reads a URDF in lines of 8 kB, so one long line broke in an
    attribute (turtlebot3_house, a static model of 214 shapes, did so).
    """
    shapes = ''.join(f'<collision name="c{i}"><pose>{i * 0.1} 0 0.05 0 0 0</pose><geometry><box>'
                     '<size>0.05 0.05 0.1</size></box></geometry></collision>'
                     for i in range(300))
    path = tmp_path / 'fence.sdf'
    path.write_text(sdf(f'<world name="w"><model name="fence"><static>true</static><pose>0 2 0 '
                        f'0 0 0</pose><link name="l">{shapes}</link></model></world>'))
    simulation = make(world=str(path), scan_rate=0.0)
    fence = simulation.world.bodies['fence']
    assert len(fence.collision_shapes(-1)) == 300


def test_a_state_reset_repeats_a_run_among_sdf_bodies_bit_for_bit(make, world_dir):
    """Free joints and flags are part of a body's loading: a rebuilt world has them again."""
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    simulation.spawn(SpawnRequest(resource_string=JOINTS, position=(-1.0, -1.0, 2.0)))
    simulation.spawn(SpawnRequest(uri='model://crate', position=(0.9, 0.0, 0.8)))

    def run():
        simulation.robot.command(0.3, 0.0)
        for _ in range(240):
            simulation.step()
        return states(simulation), simulation.world.bodies['rig'].joint_states(
            simulation.world.bodies['rig'].movable_indices).positions
    first = run()
    simulation.reset(state=True)
    assert run() == first
    assert abs(first[1][0]) > 0.5  # the hinge swung: its motor was freed again after the reset


def test_the_bounds_services_see_sdf_bodies(make, world_dir):
    from r2d2_sim.sim.bounds import Region
    simulation = arena_simulation(make, world_dir, scan_rate=0.0)
    low, high = sorted(simulation.entities.bounds('pillar').points, key=sum)
    radius = PILLAR[2]
    assert low == pytest.approx((-radius, -radius, 0.0), abs=0.01)
    assert high == pytest.approx((radius, radius, 1.0), abs=0.01)
    x, y = POST[:2]
    near_post = Region.box((x - 0.3, y - 0.3, 0.2), (x + 0.3, y + 0.3, 0.4))
    # A static concave mesh counts as its bounding box (docs/limits.md): the wall's holds all.
    assert simulation.entities.overlapping(near_post) == ['arena_wall', 'corner']
    beside_post = Region.box((x + 0.3, y - 0.1, 0.2), (x + 0.5, y, 0.4))
    assert simulation.entities.overlapping(beside_post) == ['arena_wall']


def test_a_world_manifest_lists_an_sdf_model_at_its_pose_with_its_name_and_tags(make, world_dir):
    (world_dir / 'shop.world.yaml').write_text(
        'r2d2_sim_world: 1\nname: shop\nstart_pose: door\nmodels:\n'
        '  - {uri: models/crate/model.sdf, name: stock, position: [1.5, 0.5, 0.0], yaw: 0.5,\n'
        '     description: A crate of stock., tags: [goods]}\n'
        '  - {uri: arena.sdf, tags: [arena]}\n'
        'named_poses:\n  - {name: door, position: [-1.0, 0.0, 0.0], tags: [entry]}\n')
    simulation = arena_simulation(make, world_dir, scan_rate=0.0, world_paths=[str(world_dir)])
    simulation.load_world(str(world_dir / 'shop.world.yaml'))
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'stock', 'arena_wall',
                                           'pillar', 'corner']
    info = simulation.entities.info('stock')
    assert (info.description, info.tags) == ('A crate of stock.', ('goods',))
    assert simulation.entities.info('pillar').tags == ('arena',)
    # The crate's link is 0.2 m above its model frame, which stands at the entry's pose.
    assert simulation.entities.state('stock').position == pytest.approx((1.5, 0.5, 0.2))
    assert simulation.worlds.current.start_pose.name == 'door'
    (world_dir / 'twice.world.yaml').write_text(  # one model file twice: two crates
        'r2d2_sim_world: 1\nmodels:\n  - {uri: models/crate/model.sdf}\n'
        '  - {uri: models/crate/model.sdf, position: [1.0, 0.0, 0.0]}\n')
    simulation.load_world(str(world_dir / 'twice.world.yaml'))
    assert simulation.entities.names()[2:] == ['crate', 'crate_1']
    (world_dir / 'named.world.yaml').write_text(
        'r2d2_sim_world: 1\nmodels:\n  - {uri: arena.sdf, name: everything}\n')
    with pytest.raises(RefusedError, match='holds several models: the entry cannot give them'):
        simulation.load_world(str(world_dir / 'named.world.yaml'))


def test_strict_worlds_refuses_an_sdf_spawn_with_anything_not_simulated(make):
    simulation = make(scan_rate=0.0, strict_worlds=True)
    plain = sdf(box_model('plain'))
    with_plugin = sdf(box_model('busy', extra='<plugin name="p" filename="f"/>'))
    with pytest.raises(RefusedError) as raised:
        simulation.spawn(SpawnRequest(resource_string=with_plugin))
    assert raised.value.code == 'UNSUPPORTED_ASSETS'
    assert raised.value.message == 'the resource_string: not simulated: plugin (strict_worlds)'
    assert simulation.spawn(SpawnRequest(resource_string=plain)) == 'plain'
    warned = []
    relaxed = make(scan_rate=0.0)
    relaxed._warn = warned.append
    # Clear of the robot, which a spawn at the origin would overlap (another warning).
    assert relaxed.spawn(SpawnRequest(resource_string=with_plugin,
                                      position=(2.0, 0.0, 0.2))) == 'busy'
    assert warned == ['busy: not simulated: plugin']
