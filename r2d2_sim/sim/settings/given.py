"""
Parameters as a program gives them: names the simulator reads, values as ROS holds them.

No ROS. The node reads its parameters from ROS, which already holds plain
values and warns of a name nobody declared; everything else that starts a
simulator from Python (the test harnesses, the farm's jobs, the learning
environments' ``sim_parameters``) is handed a dict, perhaps of numpy's
numbers or paths, and checks it here before anything starts:

- :func:`plain_value`: numpy's scalars and arrays, paths and an ``IntEnum``'s
  members as the bools, ints, floats, strings and lists ROS holds;
- :func:`is_ros_value`: whether a value is one of those (a scalar, or a
  list of scalars);
- :func:`unknown_parameters`: a line for each name the simulator does not
  read, with the nearest it does;
- :func:`checked_parameters`: all three, as the harnesses and the farm's
  jobs ask before anything starts.
"""

import difflib
import os
from typing import Any, Callable, Dict, Iterable, List, Mapping, Sequence

from r2d2_sim.sim.settings.table import PARAMETERS, PARAMETERS_BY_NAME

__all__ = ['ROS_OWN_PARAMETERS', 'NO_QOS_OVERRIDES', 'plain_value', 'is_ros_value',
           'unknown_parameters', 'checked_parameters']

# rclpy's own parameters, which every node declares.
ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')
# rclpy declares qos_overrides.TOPIC.publisher.POLICY only for a publisher created with
# QoSOverridingOptions, in Node.create_publisher. The node's publishers are not: with
# outputs_process they live in another process, made through the relay, where rclpy would
# never apply them; a robot's are made on its own node, some only when it is spawned, so a
# typo in a topic could not be told at start-up from a topic still to come; and rclpy
# changes the QoSProfile it is given in place (ours are shared constants). Their QoS is
# fixed and documented instead (docs/node.md), and each override is named as not taken.
QOS_OVERRIDES = 'qos_overrides.'
NO_QOS_OVERRIDES = ("r2d2_sim's publishers take no QoS overrides (docs/node.md gives each "
                    "topic's QoS)")
SCALARS = (bool, int, float, str)


def plain_value(value: Any) -> Any:
    """
    Return ``value`` as ROS would hold it where it can be, else as it is.

    numpy's scalars (``numpy.int64(3)``, ``numpy.float32``, ``numpy.bool_``)
    become Python's int, float and bool, numpy's arrays and tuples lists (item
    by item), a path its string, a subclass of a scalar (an ``IntEnum``) its
    plain value. Anything else (None, a dict, an object) comes back unchanged,
    for the caller to refuse or to leave to the simulator.
    """
    if type(value) in SCALARS:
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if type(value).__module__ == 'numpy':
        if hasattr(value, 'tolist') and getattr(value, 'ndim', 0) > 0:  # an array
            return [plain_value(v) for v in value.tolist()]
        if hasattr(value, 'item'):  # a scalar
            return value.item()
    if isinstance(value, (list, tuple)):
        return [plain_value(v) for v in value]
    if isinstance(value, SCALARS):  # a subclass: bool before int, which it is too
        for plain in SCALARS:
            if isinstance(value, plain):
                return plain(value)
    return value


def is_ros_value(value: Any) -> bool:
    """Return True for what a ROS parameter holds: a scalar, or a list of scalars."""
    if isinstance(value, SCALARS):
        return True
    return isinstance(value, (list, tuple)) and all(isinstance(v, SCALARS) for v in value)


def unknown_parameters(names: Iterable[str], robots: Sequence[str]) -> List[str]:
    """
    Return 'unknown parameter NAME (did you mean ...?)' for each name the simulator reads not.

    Ours, ``ROBOT.parameter`` of a robot ``robots`` lists and rclpy's own are
    read. ROS ignores overrides nobody declares, so a typo would run on the
    default: the node warns of each; the harnesses and the farm refuse them
    before anything starts. rclpy's ``qos_overrides.`` are named too, as not
    taken (see :data:`NO_QOS_OVERRIDES`).
    """
    known = [spec.name for spec in PARAMETERS]
    problems = []
    for name in sorted(names):
        robot, dot, parameter = name.partition('.')
        if (name in PARAMETERS_BY_NAME or name in ROS_OWN_PARAMETERS
                or (dot and robot in robots
                    and (parameter in PARAMETERS_BY_NAME or parameter == 'namespace'))):
            continue
        if name.startswith(QOS_OVERRIDES):
            problems.append(f'{name}: {NO_QOS_OVERRIDES}')
            continue
        if dot and robot not in robots:  # NAME.parameter of a robot robots does not list
            close = difflib.get_close_matches(robot, robots, n=1)
            hint = (f' (did you mean {close[0]}.{parameter}?)' if close else
                    f' (robots lists {", ".join(robots) or "none"})')
        else:
            close = difflib.get_close_matches(parameter if dot else name, known, n=1)
            hint = f' (did you mean {robot + "." if dot else ""}{close[0]}?)' if close else ''
        problems.append(f'unknown parameter {name}{hint}')
    return problems


def checked_parameters(given: Mapping[Any, Any],
                       refused: Callable[[str], Exception]) -> Dict[str, Any]:
    """
    Return ``given`` as the simulator's parameters, plain (:func:`plain_value`).

    Raises ``refused(line)`` for a value no ROS parameter holds (None, a
    dict, an object) and for names the simulator does not read (the node's
    own words, with its did-you-mean; ``ROBOT.parameter`` of a robot that
    ``robots`` lists is read).
    """
    parameters = {str(name): plain_value(value) for name, value in given.items()}
    for name, value in parameters.items():
        if not is_ros_value(value):
            raise refused(f'parameter {name}: a {type(value).__name__} is no ROS parameter '
                          'value (a bool, number, string or list of one of those)')
    robots = parameters.get('robots')
    unknown = unknown_parameters(parameters, [str(r) for r in robots]
                                 if isinstance(robots, list) else [])
    if unknown:
        raise refused('; '.join(unknown))
    return parameters
