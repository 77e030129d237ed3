"""
The ``~/get_joint_info`` reply: every joint of a robot and its child link, as JSON.

The tutorial's joint and link analysis, as a service answers it: the 17
attributes of PyBullet's ``getJointInfo`` (with the type as a word beside its
code), then the link's mass and lateral friction (``getDynamicsInfo``) and
its world pose now (``getLinkState``). Only shaping here: the numbers come
from the body's named records.
"""

from dataclasses import asdict
import json
from typing import Any, Dict, List

from r2d2_sim.physics.body import Body

__all__ = ['joint_info', 'joint_info_json']

# getJointInfo's order; 'type' (the word) goes after 'name'.
JOINT_FIELDS = ('index', 'name', 'type', 'type_code', 'q_index', 'u_index', 'flags', 'damping',
                'friction', 'lower_limit', 'upper_limit', 'max_force', 'max_velocity',
                'link_name', 'axis', 'parent_frame_position', 'parent_frame_orientation',
                'parent_index')


def joint_info(body: Body) -> List[Dict[str, Any]]:
    """Describe every joint of ``body`` (its 17 attributes) and its child link."""
    result = []
    for joint in body.joints.values():
        record = dict(asdict(joint), type=joint.type_name)
        entry = {field: list(value) if isinstance(value, tuple) else value
                 for field, value in ((f, record[f]) for f in JOINT_FIELDS)}
        dynamics = body.dynamics(joint.index)
        state = body.link_state(joint.index)
        entry['link'] = {
            'name': joint.link_name,
            'mass': dynamics.mass_kg,
            'lateral_friction': dynamics.lateral_friction,
            'world_position': list(state.frame_position),
            'world_orientation': list(state.frame_orientation),
        }
        result.append(entry)
    return result


def joint_info_json(body: Body, source: str) -> str:
    """Return the service's JSON: ``robot`` (its base link), ``urdf`` (where from), ``joints``."""
    return json.dumps({'robot': body.base_link_name, 'urdf': source,
                       'joints': joint_info(body)})
