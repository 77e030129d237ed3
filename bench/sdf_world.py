#!/usr/bin/env python3
"""
What loading a Gazebo world costs: a warehouse of a few dozen models, cold and warm.

    .venv/bin/python bench/sdf_world.py [--quick] [--screenshot PNG]

Writes a representative SDF world into a temporary directory, as Gazebo users
keep one (models in directories with ``model.config``, included through
``model://``): a concave warehouse wall mesh (COLLADA, in centimetres,
subdivided as exported meshes are), shelves (COLLADA, two materials, in
millimetres), STL pillars, OBJ crates with a ``.mtl`` colour, tables whose
COLLADA mesh is five pieces (one convex hull each), cones of SDF primitives,
doors on revolute hinges, the Fuel ground plane and sun, plugins, a light and
``<physics>`` (the summary line). Then, in the core (``Simulation.load_world``,
no ROS, one robot), times the whole load: cold (an empty mesh cache, a new
one per sample: every mesh read and converted) and warm (the cache filled:
no mesh read). Prints the models, bodies and triangles, a table, and writes
``bench/sdf_world.json``; ``--screenshot`` renders the world with the
simulator's camera renderer (the head camera's) into a PNG. Numbers are
printed, never asserted.
"""

import argparse
import logging
import os
import statistics
import tempfile
import time
import warnings

from common import BENCH_DIR, local_date, machine_info, percentile, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'sdf_world.json')
EMPTY = 'package://r2d2_sim/urdf/empty.world.yaml'
HALF = 6.0  # the warehouse's inner half-size (m)


def _box(size, centre=(0.0, 0.0, 0.0)):
    import trimesh
    mesh = trimesh.creation.box(tuple(size))
    mesh.apply_translation(tuple(centre))
    return mesh


def _dae(path, pieces, unit_m=1.0):
    """Write COLLADA with pycollada: ``pieces`` are (trimesh, rgba), one material each."""
    import collada
    import numpy
    document = collada.Collada()
    document.assetInfo.unitmeter, document.assetInfo.unitname = unit_m, 'unit'
    nodes = []
    for i, (mesh, rgba) in enumerate(pieces):
        effect = collada.material.Effect(f'e{i}', [], 'phong', diffuse=tuple(rgba))
        material = collada.material.Material(f'm{i}', f'm{i}', effect)
        document.effects.append(effect)
        document.materials.append(material)
        source = collada.source.FloatSource(f'v{i}', (numpy.asarray(mesh.vertices) / unit_m)
                                            .reshape(-1), ('X', 'Y', 'Z'))
        geometry = collada.geometry.Geometry(document, f'g{i}', f'g{i}', [source])
        inputs = collada.source.InputList()
        inputs.addInput(0, 'VERTEX', f'#v{i}')
        geometry.primitives.append(geometry.createTriangleSet(
            numpy.asarray(mesh.faces).reshape(-1), inputs, f'm{i}'))
        document.geometries.append(geometry)
        nodes.append(collada.scene.Node(f'n{i}', children=[collada.scene.GeometryNode(
            geometry, [collada.scene.MaterialNode(f'm{i}', material, inputs=[])])]))
    scene = collada.scene.Scene('scene', nodes)
    document.scenes.append(scene)
    document.scene = scene
    document.write(path)


def _model(root, name, body):
    directory = os.path.join(root, name)
    os.makedirs(os.path.join(directory, 'meshes'), exist_ok=True)
    with open(os.path.join(directory, 'model.config'), 'w') as handle:
        handle.write(f'<model><name>{name}</name><sdf version="1.9">model.sdf</sdf></model>')
    with open(os.path.join(directory, 'model.sdf'), 'w') as handle:
        handle.write(f'<?xml version="1.0"?><sdf version="1.9">{body}</sdf>')
    return directory


def _mesh_link(uri, static, mass=2.0, colour=None):
    geometry = f'<geometry><mesh><uri>{uri}</uri></mesh></geometry>'
    inertial = '' if static else (f'<inertial><mass>{mass}</mass><inertia><ixx>0.1</ixx>'
                                  '<iyy>0.1</iyy><izz>0.1</izz></inertia></inertial>')
    material = '' if colour is None else f'<material><diffuse>{colour}</diffuse></material>'
    return (f'<link name="link">{inertial}<collision name="c">{geometry}</collision>'
            f'<visual name="v">{geometry}{material}</visual></link>')


def write_models(root):
    """Write the warehouse's models into ``root`` (a model path)."""
    import trimesh
    from trimesh.exchange.stl import export_stl
    walls = []
    long_side = 2 * HALF + 0.4
    for x, y, sx, sy in ((0, HALF + 0.1, long_side, 0.2), (0, -HALF - 0.1, long_side, 0.2),
                         (HALF + 0.1, 0, 0.2, 2 * HALF), (-HALF - 0.1, 0, 0.2, 2 * HALF),
                         (-2.0, 3.0, 0.2, 6.0), (2.0, -3.0, 0.2, 6.0)):
        walls.append(_box((sx, sy, 1.5), (x, y, 0.75)))
    wall = trimesh.util.concatenate(walls)
    vertices, faces = wall.vertices, wall.faces
    for _ in range(5):  # exported walls are finely tessellated
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    wall = trimesh.Trimesh(vertices, faces, process=False)
    directory = _model(root, 'warehouse_walls', '<model name="warehouse_walls"><static>true'
                       '</static>' + _mesh_link('meshes/walls.dae', True, colour='0.7 0.7 0.75 1')
                       + '</model>')
    _dae(os.path.join(directory, 'meshes', 'walls.dae'), [(wall, (0.7, 0.7, 0.75, 1))], 0.01)
    frame = trimesh.util.concatenate([_box((0.05, 0.4, 1.6), (x, 0, 0.8)) for x in (-0.5, 0.5)])
    boards = trimesh.util.concatenate([_box((1.0, 0.4, 0.03), (0, 0, z))
                                       for z in (0.1, 0.6, 1.1, 1.55)])
    directory = _model(root, 'shelf', '<model name="shelf"><static>true</static>'
                       + _mesh_link('meshes/shelf.dae', True) + '</model>')
    _dae(os.path.join(directory, 'meshes', 'shelf.dae'),
         [(frame, (0.2, 0.3, 0.7, 1)), (boards, (0.8, 0.6, 0.3, 1))], 0.001)
    directory = _model(root, 'pillar', '<model name="pillar"><static>true</static>'
                       + _mesh_link('meshes/pillar.stl', True, colour='0.8 0.8 0.2 1')
                       + '</model>')
    pillar = trimesh.creation.cylinder(radius=0.2, height=1.5, sections=64)
    pillar.apply_translation((0, 0, 0.75))
    with open(os.path.join(directory, 'meshes', 'pillar.stl'), 'wb') as handle:
        handle.write(export_stl(pillar))
    directory = _model(root, 'crate', '<model name="crate">'
                       + _mesh_link('meshes/crate.obj', False) + '</model>')
    from trimesh.exchange.obj import export_obj
    with open(os.path.join(directory, 'meshes', 'crate.mtl'), 'w') as handle:
        handle.write('newmtl wood\nKd 0.7 0.45 0.2\n')
    with open(os.path.join(directory, 'meshes', 'crate.obj'), 'w') as handle:
        handle.write('mtllib crate.mtl\nusemtl wood\n' + export_obj(
            _box((0.4, 0.4, 0.4), (0, 0, 0.2)), include_normals=False, include_color=False,
            include_texture=False))
    legs = [_box((0.05, 0.05, 0.7), (x, y, 0.35)) for x in (-0.5, 0.5) for y in (-0.3, 0.3)]
    table = trimesh.util.concatenate(legs + [_box((1.2, 0.8, 0.04), (0, 0, 0.72))])
    directory = _model(root, 'table', '<model name="table">'
                       + _mesh_link('meshes/table.dae', False, 10.0) + '</model>')
    _dae(os.path.join(directory, 'meshes', 'table.dae'), [(table, (0.5, 0.35, 0.2, 1))])
    _model(root, 'cone', '''<model name="cone"><link name="link">
      <inertial><mass>0.5</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>
      </inertia></inertial>
      <collision name="base"><pose>0 0 0.15 0 0 0</pose><geometry><cylinder><radius>0.12
      </radius><length>0.3</length></cylinder></geometry></collision>
      <visual name="base"><pose>0 0 0.15 0 0 0</pose><geometry><cylinder><radius>0.12</radius>
      <length>0.3</length></cylinder></geometry><material><diffuse>1 0.4 0 1</diffuse>
      </material></visual>
      <visual name="top"><pose>0 0 0.33 0 0 0</pose><geometry><sphere><radius>0.06</radius>
      </sphere></geometry><material><diffuse>1 1 1 1</diffuse></material></visual>
      </link></model>''')
    _model(root, 'door', '''<model name="door">
      <link name="frame"><collision name="c"><pose>0 0 1.1 0 0 0</pose><geometry><box><size>
      0.1 0.1 2.2</size></box></geometry></collision><visual name="v"><pose>0 0 1.1 0 0 0</pose>
      <geometry><box><size>0.1 0.1 2.2</size></box></geometry></visual></link>
      <joint name="fixed" type="fixed"><parent>world</parent><child>frame</child></joint>
      <link name="panel"><pose>0.45 0 1.0 0 0 0</pose><inertial><mass>8</mass><inertia><ixx>2.7
      </ixx><iyy>3.2</iyy><izz>0.6</izz></inertia></inertial>
      <collision name="c"><geometry><box><size>0.8 0.04 1.9</size></box></geometry></collision>
      <visual name="v"><geometry><box><size>0.8 0.04 1.9</size></box></geometry><material>
      <diffuse>0.3 0.5 0.3 1</diffuse></material></visual></link>
      <joint name="hinge" type="revolute"><pose relative_to="frame">0 0 1 0 0 0</pose>
      <parent>frame</parent><child>panel</child><axis><xyz>0 0 1</xyz><limit><lower>-1.6</lower>
      <upper>1.6</upper></limit><dynamics><friction>0.5</friction></dynamics></axis></joint>
      </model>''')


def write_world(root):
    """Write the world and its models under ``root``; return the world's path."""
    models = os.path.join(root, 'models')
    write_models(models)
    includes = []

    def include(model, name, x, y, yaw=0.0):
        includes.append(f'<include><uri>model://{model}</uri><name>{name}</name>'
                        f'<pose>{x} {y} 0 0 0 {yaw}</pose></include>')
    for i in range(6):
        include('shelf', f'shelf_{i}', -5.0 + 2.0 * (i % 3), 5.3 if i < 3 else -5.3)
    for i in range(8):
        include('pillar', f'pillar_{i}', -4.0 + 8.0 * (i % 2), -4.0 + (i // 2) * 2.6)
    for i in range(8):
        include('crate', f'crate_{i}', 3.0 + 0.5 * (i % 2), 1.0 + 0.5 * (i // 2))
    for i in range(4):
        include('table', f'table_{i}', -4.0 + 2.0 * (i % 2), -1.0 - 2.0 * (i // 2), 0.3 * i)
    for i in range(4):
        include('cone', f'cone_{i}', 1.0 + 0.6 * i, -1.5)
    for i in range(2):
        include('door', f'door_{i}', -2.0 - 0.4 * i, 0.2 - 5.8 * i)
    world = f'''<?xml version="1.0"?>
<sdf version="1.9"><world name="warehouse">
  <physics name="1ms" type="ignored"><max_step_size>0.001</max_step_size>
    <real_time_factor>1.0</real_time_factor></physics>
  <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>
  <plugin filename="gz-sim-sensors-system" name="gz::sim::systems::Sensors"/>
  <scene><ambient>0.4 0.4 0.4 1</ambient></scene>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane</uri></include>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Sun</uri></include>
  <include><uri>model://warehouse_walls</uri></include>
  {"".join(includes)}
  <light type="point" name="lamp"><pose>0 0 3 0 0 0</pose></light>
  <frame name="start"><pose>0 0 0 0 0 0</pose></frame>
  <frame name="goal"><pose relative_to="table_0">0 1.2 0 0 0 0</pose></frame>
</world></sdf>'''
    path = os.path.join(root, 'warehouse.sdf')
    with open(path, 'w') as handle:
        handle.write(world)
    return path


def summary(times):
    """Return the median and 90th percentile of ``times``."""
    return {'median_ms': statistics.median(times), 'p90_ms': percentile(times, 90),
            'samples_ms': times}


def time_load(simulation, path, cache):
    """Return the wall ms of one LoadWorld of ``path`` with the mesh cache in ``cache``."""
    os.environ['R2D2_SIM_CACHE_DIR'] = cache
    simulation.load_world(EMPTY)
    start = time.perf_counter()
    simulation.load_world(path)
    return (time.perf_counter() - start) * 1e3


def screenshot(simulation, path, width=960, height=540):
    """Render the world from above a corner with the simulator's renderer into a PNG."""
    from matplotlib.image import imsave
    import numpy
    from r2d2_sim.model.camera import projection_matrix, view_matrix
    eye, target = (7.5, -8.5, 6.5), (-0.5, 0.5, 0.0)
    view = view_matrix(eye, [t - e for t, e in zip(target, eye)], (0.0, 0.0, 1.0))
    rgb, _ = simulation.world.render(width, height, view,
                                     projection_matrix(width, height, 50.0, 0.1, 60.0))
    imsave(path, numpy.frombuffer(rgb, numpy.uint8).reshape(height, width, 3), format='png')


def main():
    """Write the world, time its loads cold and warm; print; write bench/sdf_world.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--quick', action='store_true', help='fewer samples (~20 s)')
    parser.add_argument('--screenshot', metavar='PNG', help='also render the world into PNG')
    args = parser.parse_args()
    cold_samples, warm_samples = (2, 4) if args.quick else (5, 10)
    logging.getLogger('trimesh').setLevel(logging.ERROR)
    warnings.simplefilter('ignore', PendingDeprecationWarning)
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    with tempfile.TemporaryDirectory() as root:
        path = write_world(root)
        simulation = Simulation(*parse_world({'world_paths': [root], 'scan_rate': 0.0,
                                              'model_paths': [os.path.join(root, 'models')]}))
        try:
            cold = [time_load(simulation, path, os.path.join(root, f'cold_{i}'))
                    for i in range(cold_samples)]
            time_load(simulation, path, os.path.join(root, 'warm'))  # fills the cache
            warm = [time_load(simulation, path, os.path.join(root, 'warm'))
                    for _ in range(warm_samples)]
            world = simulation.worlds.current
            bodies = len(world.models)
            triangles = int(world.description.split(' mesh triangles')[0].split()[-1])
            models = 1 + path_count(path)
            if args.screenshot:
                screenshot(simulation, args.screenshot)
        finally:
            simulation.close()
    results = {'models': models, 'bodies': bodies, 'mesh_triangles': triangles,
               'notes': list(world.notes), 'cold': summary(cold), 'warm': summary(warm)}
    print(f'warehouse.sdf: {models} models (with the ground plane and the sun), {bodies} '
          f'bodies loaded, {triangles} mesh triangles')
    print(f'{"ms per LoadWorld":22} {"median":>8} {"p90":>8} samples')
    for label, times in (('cold (empty cache)', cold), ('warm (cache filled)', warm)):
        print(f'{label:22} {statistics.median(times):8.0f} {percentile(times, 90):8.0f} '
              f'{len(times)}')
    write_json(RESULTS_PATH, {'date': local_date(), 'machine': machine_info(),
                              'results': results})


def path_count(path):
    """Return how many models the world file names: its includes (the sun is a light)."""
    with open(path) as handle:
        return handle.read().count('<include>') - 1


if __name__ == '__main__':
    main()
