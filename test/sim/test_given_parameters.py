"""Parameters as programs give them: one conversion and one name check for every caller."""

import enum
from pathlib import Path

import numpy

from r2d2_sim.sim.settings.given import is_ros_value, plain_value, unknown_parameters


class Rate(enum.IntEnum):
    FAST = 50


def test_numpy_paths_and_enums_become_the_values_ros_holds():
    cases = [(numpy.int64(3), 3, int), (numpy.float32(0.5), 0.5, float),
             (numpy.bool_(True), True, bool), (numpy.str_('room'), 'room', str),
             (numpy.array([1.0, 2.0]), [1.0, 2.0], list), (numpy.float64(2.0), 2.0, float),
             (Path('/tmp/w.sdf'), '/tmp/w.sdf', str), (Rate.FAST, 50, int),
             ((numpy.int32(1), Path('a')), [1, 'a'], list), (numpy.array(7), 7, int)]
    for given, plain, kind in cases:
        value = plain_value(given)
        assert value == plain and type(value) is kind, given
        assert is_ros_value(value), given
    for kept in (None, {'a': 1}, object()):
        assert plain_value(kept) is kept
        assert not is_ros_value(kept)
    assert not is_ros_value([1, [2]])


def test_unknown_names_get_the_nearest_known_one():
    assert unknown_parameters(['scan_rate', 'use_sim_time'], []) == []
    assert unknown_parameters(['qos_overrides./odmo.publisher.depth'], []) == [
        "qos_overrides./odmo.publisher.depth: r2d2_sim's publishers take no QoS overrides "
        "(docs/node.md gives each topic's QoS)"]
    assert unknown_parameters(['scan_rat'], []) == [
        'unknown parameter scan_rat (did you mean scan_rate?)']
    assert unknown_parameters(['b.scan_rate', 'a.scan_rat', 'a.namespace'], ['a']) == [
        'unknown parameter a.scan_rat (did you mean a.scan_rate?)',
        'unknown parameter b.scan_rate (robots lists a)']
