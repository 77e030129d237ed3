"""
SDF worlds, models and meshes that tests write for themselves: no ROS, no PyBullet.

Meshes are made with a mesh library (trimesh's shapes, STL and OBJ writers,
pycollada's COLLADA writer, with units and materials), models as Gazebo
keeps them (a directory with ``model.config`` and ``model.sdf``), worlds as
SDF text. Every size is a round number, so the tests can compute what the
laser must measure from the geometry alone.
"""

import logging
import os
from typing import Optional, Sequence
import warnings

import numpy

logging.getLogger('trimesh').setLevel(logging.ERROR)  # no scipy here: trimesh says so


def sdf(body: str, version: str = '1.9') -> str:
    """Return an SDF document of ``body`` (models, a world...)."""
    return f'<?xml version="1.0"?>\n<sdf version="{version}">\n{body}\n</sdf>\n'


def model_dir(root, name: str, body: str, version: str = '1.7') -> str:
    """Write a Gazebo model directory ``root/name`` (model.config, model.sdf); return it."""
    directory = os.path.join(str(root), name)
    os.makedirs(directory, exist_ok=True)
    with open(os.path.join(directory, 'model.config'), 'w') as handle:
        handle.write(f'<?xml version="1.0"?><model><name>{name}</name>'
                     f'<sdf version="{version}">model.sdf</sdf></model>')
    with open(os.path.join(directory, 'model.sdf'), 'w') as handle:
        handle.write(sdf(body, version))
    return directory


def box(size: Sequence[float], centre: Sequence[float] = (0.0, 0.0, 0.0)):
    """Return a trimesh box of ``size`` centred at ``centre``."""
    import trimesh
    mesh = trimesh.creation.box(tuple(size))
    mesh.apply_translation(tuple(centre))
    return mesh


def ring_wall(inner_half_m: float, thickness_m: float, height_m: float):
    """
    Return a square ring of walls around the origin: a concave mesh, the floor at z = 0.

    The inner faces are at x, y = +-``inner_half_m``; four boxes, their
    corners overlapping, as a modeller would leave them.
    """
    import trimesh
    half, t, h = inner_half_m, thickness_m, height_m
    outer = 2.0 * (half + t)
    parts = [box((outer, t, h), (0.0, half + t / 2.0, h / 2.0)),
             box((outer, t, h), (0.0, -half - t / 2.0, h / 2.0)),
             box((t, outer, h), (half + t / 2.0, 0.0, h / 2.0)),
             box((t, outer, h), (-half - t / 2.0, 0.0, h / 2.0))]
    return trimesh.util.concatenate(parts)


def cylinder(radius_m: float, height_m: float, sections: int = 64):
    """Return a cylinder along z, its base at z = 0."""
    import trimesh
    mesh = trimesh.creation.cylinder(radius=radius_m, height=height_m, sections=sections)
    mesh.apply_translation((0.0, 0.0, height_m / 2.0))
    return mesh


def write_stl(path, mesh) -> str:
    """Write a binary STL (trimesh's writer); return the path."""
    from trimesh.exchange.stl import export_stl
    with open(path, 'wb') as handle:
        handle.write(export_stl(mesh))
    return str(path)


def write_obj(path, mesh, rgba: Optional[Sequence[float]] = None) -> str:
    """Write an OBJ (trimesh's writer), with a .mtl of one diffuse colour when given."""
    from trimesh.exchange.obj import export_obj
    text = export_obj(mesh, include_normals=False, include_color=False,
                      include_texture=False)
    if rgba is not None:
        material = os.path.splitext(os.path.basename(str(path)))[0] + '.mtl'
        with open(os.path.join(os.path.dirname(str(path)), material), 'w') as handle:
            handle.write('newmtl paint\nKd {} {} {}\nd {}\n'.format(*rgba))
        text = f'mtllib {material}\nusemtl paint\n' + text
    with open(path, 'w') as handle:
        handle.write(text)
    return str(path)


def write_dae(path, mesh, rgba: Sequence[float] = (0.6, 0.6, 0.6, 1.0),
              unit_m: Optional[float] = None, node_offset=(0.0, 0.0, 0.0)) -> str:
    """
    Write a COLLADA file with pycollada: one material, ``<unit meter>`` when given.

    The vertices are divided by ``unit_m`` (a file in centimetres has them
    100 times larger) and the node is moved by ``node_offset`` (file units),
    so the mesh read back is ``mesh`` only if both are applied.
    """
    import collada
    document = collada.Collada()
    if unit_m is not None:
        document.assetInfo.unitmeter = unit_m
        document.assetInfo.unitname = 'unit'
    effect = collada.material.Effect('effect', [], 'phong', diffuse=tuple(rgba))
    material = collada.material.Material('material', 'paint', effect)
    document.effects.append(effect)
    document.materials.append(material)
    scale = 1.0 / unit_m if unit_m else 1.0
    vertices = numpy.asarray(mesh.vertices, dtype=float) * scale - numpy.asarray(node_offset)
    source = collada.source.FloatSource('vertices', vertices.reshape(-1), ('X', 'Y', 'Z'))
    geometry = collada.geometry.Geometry(document, 'geometry', 'mesh', [source])
    inputs = collada.source.InputList()
    inputs.addInput(0, 'VERTEX', '#vertices')
    geometry.primitives.append(geometry.createTriangleSet(
        numpy.asarray(mesh.faces, dtype=numpy.int64).reshape(-1), inputs, 'paint'))
    document.geometries.append(geometry)
    node = collada.scene.Node('node', children=[collada.scene.GeometryNode(
        geometry, [collada.scene.MaterialNode('paint', material, inputs=[])])],
        transforms=[collada.scene.TranslateTransform(*node_offset)])
    scene = collada.scene.Scene('scene', [node])
    document.scenes.append(scene)
    document.scene = scene
    with warnings.catch_warnings():  # pycollada still uses numpy.matrix
        warnings.simplefilter('ignore', PendingDeprecationWarning)
        document.write(str(path))
    return str(path)


def mesh_model(name: str, uri: str, *, static: bool = True, pose: str = '0 0 0 0 0 0',
               rgba: Optional[Sequence[float]] = None, mass: float = 1.0,
               scale: str = '1 1 1', link_pose: str = '0 0 0 0 0 0') -> str:
    """Return a <model> of one link whose collision and visual are the mesh at ``uri``."""
    colour = '' if rgba is None else (
        f'<material><diffuse>{" ".join(str(c) for c in rgba)}</diffuse></material>')
    geometry = f'<geometry><mesh><uri>{uri}</uri><scale>{scale}</scale></mesh></geometry>'
    inertial = '' if static else (
        f'<inertial><mass>{mass}</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy><izz>0.1</izz>'
        '</inertia></inertial>')
    return (f'<model name="{name}"><static>{str(static).lower()}</static><pose>{pose}</pose>'
            f'<link name="link"><pose>{link_pose}</pose>{inertial}<collision name="collision">'
            f'{geometry}</collision><visual name="visual">{geometry}{colour}</visual></link>'
            '</model>')


def box_model(name: str, size=(0.4, 0.4, 0.4), *, static: bool = False, mass: float = 2.0,
              pose: str = '0 0 0 0 0 0', rgba=(0.8, 0.3, 0.1, 1.0), extra: str = '') -> str:
    """Return a <model> of one box link (its inertia a solid box's), ``extra`` inside it."""
    x, y, z = size
    m = mass / 12.0
    inertial = '' if static else (
        f'<inertial><mass>{mass}</mass><inertia><ixx>{m * (y * y + z * z)}</ixx>'
        f'<iyy>{m * (x * x + z * z)}</iyy><izz>{m * (x * x + y * y)}</izz></inertia>'
        '</inertial>')
    geometry = f'<geometry><box><size>{x} {y} {z}</size></box></geometry>'
    colour = ' '.join(str(c) for c in rgba)
    return (f'<model name="{name}"><static>{str(static).lower()}</static><pose>{pose}</pose>'
            f'<link name="link">{inertial}<collision name="collision">{geometry}</collision>'
            f'<visual name="visual">{geometry}<material><diffuse>{colour}</diffuse></material>'
            f'</visual></link>{extra}</model>')


# -- the arena: a Gazebo world of this project's tests ----------------------------------------

ARENA_HALF_M = 2.0        # the wall mesh's inner faces: x, y = +-2 m
ARENA_WALL_M = 0.2
PILLAR = (1.2, 1.2, 0.25)   # x, y, radius (m): an STL mesh, static
POST = (-1.2, 1.2, 0.2)     # x, y, radius: an SDF cylinder, static, in a nested model
CRATE_SIZE_M = 0.4          # the OBJ crate, a moving model on the model path


def arena(root) -> str:
    """
    Write the arena world and its models under ``root``; return the world file's path.

    ``root/models`` holds ``arena_wall`` (a concave DAE ring, in centimetres, around
    the origin), ``pillar`` (an STL cylinder) and ``crate`` (a moving OBJ box with a
    blue .mtl); the world includes them through ``model://`` (``root/models`` must
    be on the model path), with the Fuel ground plane and sun, a nested model
    holding the post, a frame ``start`` at the origin facing +x and a frame
    ``goal`` relative to the pillar, a plugin and a light (not simulated).
    """
    models = os.path.join(str(root), 'models')
    wall = model_dir(models, 'arena_wall', mesh_model(
        'arena_wall', 'model://arena_wall/meshes/wall.dae', rgba=(0.6, 0.6, 0.65, 1.0)))
    os.makedirs(os.path.join(wall, 'meshes'))
    write_dae(os.path.join(wall, 'meshes', 'wall.dae'), ring_wall(ARENA_HALF_M, ARENA_WALL_M, 1.0),
              unit_m=0.01)
    pillar = model_dir(models, 'pillar', mesh_model('pillar', 'meshes/pillar.stl',
                                                    rgba=(0.9, 0.9, 0.2, 1.0)))
    os.makedirs(os.path.join(pillar, 'meshes'))
    write_stl(os.path.join(pillar, 'meshes', 'pillar.stl'), cylinder(PILLAR[2], 1.0, 128))
    crate = model_dir(models, 'crate', mesh_model('crate', 'meshes/crate.obj', static=False,
                                                  mass=2.0, link_pose='0 0 0.2 0 0 0'))
    os.makedirs(os.path.join(crate, 'meshes'))
    write_obj(os.path.join(crate, 'meshes', 'crate.obj'), box((CRATE_SIZE_M,) * 3),
              rgba=(0.1, 0.2, 0.9, 1.0))
    x, y, radius = POST
    world = sdf(f'''<world name="arena">
  <physics type="ode"><max_step_size>0.001</max_step_size></physics>
  <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane</uri></include>
  <include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Sun</uri></include>
  <include><uri>model://arena_wall</uri></include>
  <include><uri>model://pillar</uri><pose>{PILLAR[0]} {PILLAR[1]} 0 0 0 0</pose></include>
  <model name="corner">
    <static>true</static><pose>{x} {y} 0 0 0 0</pose>
    <model name="post"><link name="link"><pose>0 0 0.5 0 0 0</pose>
      <collision name="c"><geometry><cylinder><radius>{radius}</radius><length>1</length>
      </cylinder></geometry></collision>
      <visual name="v"><geometry><cylinder><radius>{radius}</radius><length>1</length>
      </cylinder></geometry><material><diffuse>0.9 0.1 0.1 1</diffuse></material></visual>
    </link></model>
  </model>
  <frame name="start"><pose>0 0 0 0 0 0</pose></frame>
  <frame name="goal"><pose relative_to="pillar">-0.8 0 0 0 0 3.141592653589793</pose></frame>
</world>''')
    path = os.path.join(str(root), 'arena.sdf')
    with open(path, 'w') as handle:
        handle.write(world)
    return path


def wall_range(x: float, y: float, angle: float, circles=()) -> float:
    """
    Return the range from (x, y) along ``angle`` to the arena's wall or a circle (x, y, r).

    NaN when the beam grazes a circle within 1 cm of its edge (a faceted mesh and
    the true circle can disagree there by more than the tolerance).
    """
    import math
    dx, dy = math.cos(angle), math.sin(angle)
    best = math.inf
    for direction, start in ((dx, x), (dy, y)):
        if abs(direction) > 1e-12:
            for wall in (ARENA_HALF_M, -ARENA_HALF_M):
                t = (wall - start) / direction
                if t > 0.0:
                    best = min(best, t)
    for cx, cy, r in circles:
        fx, fy = x - cx, y - cy
        if abs(abs(fx * dy - fy * dx) - r) < 0.01:
            return math.nan
        b, c = fx * dx + fy * dy, fx * fx + fy * fy - r * r
        if b * b - c >= 0.0 and -b - math.sqrt(b * b - c) > 0.0:
            best = min(best, -b - math.sqrt(b * b - c))
    return best
