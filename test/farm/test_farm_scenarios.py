"""
Scenarios as data: drawn from a seed, drawn by Hypothesis, written to JSON and read back.

No ROS and no physics: r2d2_sim.farm.scenario and .strategies are plain
Python (numpy, Hypothesis).
"""

import json
import math

from hypothesis import find, given, settings
import pytest

from r2d2_sim.farm.scenario import (
    Box, footprint_distance, Pose, ROOM, Scenario, ScenarioError, ScenarioSpace)
from r2d2_sim.farm.strategies import REPLAY_ENV, scenarios
from r2d2_sim.model.regions import box_region, circle_region

SPACE = ScenarioSpace(world=ROOM, limits=(('max_linear_velocity', (0.2, 0.5)),),
                      scan_noise_std=(0.0, 0.02))
# SPACE.draw(7) as numpy's PCG64 draws it: a change of the drawing (or of numpy's
# stream) shows here, not as a farm whose seeds quietly mean other layouts.
SEVEN = ('{"format": 1, "goal": {"kind": "circle", "values": [3.449, 0.157, 0.3, 0.0]}, '
         '"limits": {"max_linear_velocity": 0.498}, "obstacles": [{"size": [0.32, 0.314, 0.5], '
         '"x": 2.168, "y": -0.825, "yaw": -1.396}, {"size": [0.4, 0.529, 0.5], "x": 2.247, '
         '"y": 1.238, "yaw": -1.554}, {"size": [0.387, 0.527, 0.5], "x": 0.763, "y": 0.892, '
         '"yaw": -1.196}, {"size": [0.488, 0.302, 0.5], "x": 1.106, "y": -0.475, '
         '"yaw": -0.696}], "scan_noise_std": 0.009, "seed": 7, "start": {"x": 0.178, '
         '"y": 0.05, "yaw": 0.111}, "world": "package://r2d2_sim/urdf/room.urdf"}')


def test_a_seed_draws_the_same_scenario_every_time_and_everywhere():
    """draw(seed) is a function of the seed: equal twice, and equal to the pinned text."""
    assert SPACE.draw(7) == SPACE.draw(7)
    assert SPACE.draw(7).to_json() == SEVEN
    assert SPACE.draw(8) != SPACE.draw(7)
    assert [s.seed for s in SPACE.seeds(3, first=5)] == [5, 6, 7]


@pytest.mark.parametrize('seed', range(40))
def test_drawn_scenarios_stay_in_their_space(seed):
    """Counts, areas, sizes, limits and the keep-out around start and goal all hold."""
    scenario = SPACE.draw(seed)
    assert 0 <= len(scenario.obstacles) <= 5
    x_min, y_min, x_max, y_max = SPACE.start_area
    assert x_min <= scenario.start.x <= x_max and y_min <= scenario.start.y <= y_max
    gx, gy = scenario.goal_point
    assert scenario.goal == circle_region(gx, gy, SPACE.goal_tolerance)
    for box in scenario.obstacles:
        assert SPACE.area[0] <= box.x <= SPACE.area[2]
        assert 0.2 <= box.size[0] <= 0.6 and box.size[2] == 0.5
        assert footprint_distance(box, scenario.start.x, scenario.start.y) >= SPACE.keep_out
        assert footprint_distance(box, gx, gy) >= SPACE.keep_out
    assert 0.2 <= dict(scenario.limits)['max_linear_velocity'] <= 0.5
    assert scenario.parameters()['noise_seed'] == seed
    assert scenario.parameters()['max_linear_velocity'] == dict(scenario.limits)[
        'max_linear_velocity']


def test_the_footprint_distance_by_hand():
    """A 2 x 1 box turned 90 degrees at (1, 1): its long side runs along y."""
    box = Box(1.0, 1.0, math.pi / 2, (2.0, 1.0, 0.5))
    assert footprint_distance(box, 1.0, 1.0) == 0.0
    assert footprint_distance(box, 2.5, 1.0) == pytest.approx(1.0)   # 1.5 - half of 1
    assert footprint_distance(box, 1.0, 3.0) == pytest.approx(1.0)   # 2.0 - half of 2
    assert footprint_distance(box, 2.5, 3.0) == pytest.approx(math.sqrt(2.0))
    corners = sorted((round(x, 9), round(y, 9)) for x, y in box.corners())
    assert corners == [(0.5, 0.0), (0.5, 2.0), (1.5, 0.0), (1.5, 2.0)]


def test_json_gives_back_the_same_scenario_bit_for_bit():
    """Floats of any precision survive the round trip, and so do box goals and limits."""
    scenario = Scenario(obstacles=(Box(0.1 + 0.2, 1 / 3, -math.pi / 7, (0.3, 1e-3, 2.0)),),
                        start=Pose(-0.1, 2.0 / 3.0, 1e-17), goal=box_region(1, -1, 2, 1),
                        seed=2**31 - 1, world=ROOM, limits=(('max_angular_velocity', 0.7),),
                        scan_noise_std=0.01)
    again = Scenario.from_json(scenario.to_json())
    assert again == scenario
    assert again.obstacles[0].x == 0.1 + 0.2 and again.start.yaw == 1e-17
    assert json.loads(scenario.to_json())['goal'] == {'kind': 'box', 'values': [1, -1, 2, 1]}


@pytest.mark.parametrize('text, message', [
    ('not json', 'not JSON'),
    ('[1, 2]', 'a JSON object expected'),
    ('{"format": 2}', 'scenario format 2'),
    ('{"format": 1, "seed": 1}', "not a scenario: KeyError 'goal'"),
])
def test_a_bad_scenario_text_is_one_line(text, message):
    """from_json refuses what is not a scenario with a ScenarioError of one line."""
    with pytest.raises(ScenarioError, match=message) as raised:
        Scenario.from_json(text)
    assert '\n' not in str(raised.value)


@pytest.mark.parametrize('change, message', [
    ({'seed': -1}, 'seed must be'), ({'seed': 2**31}, 'seed must be'),
    ({'limits': (('max_speed', 1.0),)}, 'limits: max_speed'),
    ({'goal': 'there'}, 'goal must be'),
])
def test_an_impossible_scenario_is_refused(change, message):
    """Seeds outside the noise seed's range, unknown limits, a goal that is no region."""
    with pytest.raises(ScenarioError, match=message):
        Scenario(**change)


NAN, INF = float('nan'), float('inf')


@pytest.mark.parametrize('change, message', [
    ({'obstacles': (3, 1)}, 'obstacles must be'), ({'area': (1, 0, 0, 1)}, 'area must be'),
    ({'box_size': (0.5, 0.2)}, 'box_size must be'), ({'goal_tolerance': 0.0}, 'must be > 0'),
    ({'box_size': (0.2, NAN)}, 'box_size must be finite'),
    ({'box_height': NAN}, 'box_height must be a finite number, got nan'),
    ({'box_height': INF}, 'box_height must be a finite number, got inf'),
    ({'keep_out': NAN}, 'keep_out must be a finite number, got nan'),
    ({'keep_out': -1.0}, r'keep_out must be >= 0, got -1\.0'),
    ({'goal_tolerance': NAN}, 'goal_tolerance must be a finite number, got nan'),
    ({'goal_tolerance': INF}, 'goal_tolerance must be a finite number, got inf'),
    ({'scan_noise_std': (-0.1, 0.0)}, r'scan_noise_std must be \(lowest, highest\) within 0 '
                                      'and 10 m'),
    ({'scan_noise_std': (0.0, 10.5)}, 'scan_noise_std must be'),
    ({'limits': {'max_linear_velocity': (0.1, 1.0)}}, r'limits must be \(name, \(low, high\)\) '
                                                      'pairs, got dict'),
    ({'limits': (('max_linear_velocity', 0.5),)},
     r"limits: \('max_linear_velocity', 0.5\) is not \(name, \(low, high\)\)"),
    ({'limits': (('max_linear_velocity', (NAN, 1.0)),)}, 'limits: .*max_linear_velocity'),
    ({'limits': (('top_speed', (0.1, 1.0)),)}, "limits: .*'top_speed'.* is not"),
    ({'obstacles': 5}, 'obstacles must be .*got 5'),
    ({'obstacles': (0.0, 2.0)}, 'obstacles must be'),
    ({'obstacles': (0, 10 ** 7)}, r'obstacles must be \(fewest, most\), 0 <= fewest <= most <= '
                                  r'1000, got \(0, 10000000\)'),
])
def test_an_impossible_space_is_refused(change, message):
    """A space whose ranges are empty, or not numbers, or not ranges, says which in one line."""
    with pytest.raises(ScenarioError, match=message) as raised:
        ScenarioSpace(**change)
    assert '\n' not in str(raised.value)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(scenario=scenarios(SPACE))
def test_hypothesis_draws_from_the_same_space(scenario):
    """The strategy's scenarios obey the space as draw's do, and survive JSON."""
    assert len(scenario.obstacles) <= 5
    for box in scenario.obstacles:
        assert SPACE.clear(box, scenario.start, scenario.goal_point)
        assert box.x == round(box.x * 1000) / 1000  # whole millimetres
    assert Scenario.from_json(scenario.to_json()) == scenario


def test_hypothesis_shrinks_toward_fewer_boxes_and_round_numbers():
    """The simplest scenario with a box is one box at the ranges' simplest values."""
    space = ScenarioSpace(area=(1.0, 1.0, 2.0, 2.0))  # every box keeps out of start and goal
    simplest = find(scenarios(space), lambda s: len(s.obstacles) >= 1,
                    settings=settings(database=None, derandomize=True))
    assert len(simplest.obstacles) == 1 and simplest.seed == 0
    assert simplest.obstacles[0] == Box(1.0, 1.0, 0.0, (0.2, 0.2, 0.5))
    assert simplest.start == Pose(0.0, 0.0, 0.0) and simplest.goal_point == (3.0, 0.0)


def test_a_replayed_scenario_is_all_the_strategy_draws(tmp_path, monkeypatch):
    """R2D2_FARM_REPLAY makes scenarios() draw just the file's scenario."""
    path = tmp_path / 'case.json'
    path.write_text(SEVEN)
    monkeypatch.setenv(REPLAY_ENV, str(path))
    drawn = find(scenarios(ScenarioSpace()), lambda s: True,
                 settings=settings(database=None, derandomize=True))
    assert drawn.to_json() == SEVEN
    monkeypatch.setenv(REPLAY_ENV, str(tmp_path / 'missing.json'))
    with pytest.raises(ScenarioError, match='No such file'):
        scenarios(ScenarioSpace())


ROOM_WORLD = 'package://r2d2_sim/urdf/room.world.yaml'  # its named poses: start, goal, dock...


def test_start_and_goal_by_name_are_the_world_poses_numbers():
    """room.world.yaml: start (0, 0, 0), dock (1.4, 0, 0); the names kept beside the numbers."""
    scenario = Scenario.named(ROOM_WORLD, start='dock', goal='goal', goal_tolerance=0.25, seed=4)
    assert scenario.start == Pose(1.4, 0.0, 0.0)
    assert scenario.goal == circle_region(-2.0, 1.5, 0.25)
    assert (scenario.start_name, scenario.goal_name) == ('dock', 'goal')
    assert Scenario.from_json(scenario.to_json()) == scenario
    # The world's start pose is the origin here: initial_pose is the start itself.
    assert scenario.parameters()['initial_pose'] == [1.4, 0.0, 0.0]
    with pytest.raises(ScenarioError, match=r"no named pose 'kitchen' in .*: it has|"
                                            r"no named pose 'kitchen' .* it has: corner_ne"):
        Scenario.named(ROOM_WORLD, goal='kitchen')


def test_a_space_with_named_ends_draws_them_and_keeps_boxes_out_of_them():
    """Every draw starts at 'start' and heads for 'goal'; no box within keep_out of either."""
    space = ScenarioSpace(world=ROOM_WORLD, start_pose='start', goal_pose='goal',
                          area=(-2.8, -2.3, 1.8, 2.3), obstacles=(3, 6), keep_out=0.7)
    for scenario in space.seeds(20):
        assert scenario.start == Pose(0.0, 0.0, 0.0) and scenario.goal_point == (-2.0, 1.5)
        assert (scenario.start_name, scenario.goal_name) == ('start', 'goal')
        for box in scenario.obstacles:
            assert footprint_distance(box, 0.0, 0.0) >= 0.7
            assert footprint_distance(box, -2.0, 1.5) >= 0.7
    assert space.draw(3) == space.draw(3)
    with pytest.raises(ScenarioError, match="no named pose 'nowhere'"):
        ScenarioSpace(world=ROOM_WORLD, goal_pose='nowhere')
    with pytest.raises(ScenarioError, match="no named pose 'start' in no world"):
        ScenarioSpace(start_pose='start')


def test_the_hypothesis_strategy_keeps_the_named_ends():
    """scenarios(space) of a space with names: every example at the named start and goal."""
    space = ScenarioSpace(world=ROOM_WORLD, start_pose='corner_sw', goal_pose='corner_ne',
                          area=(-2.8, -2.3, 1.8, 2.3))

    @settings(max_examples=15, derandomize=True, database=None)
    @given(scenarios(space))
    def check(scenario):
        # The yaw comes back from the pose's quaternion: the same to the last bit or two.
        assert scenario.start.yaw == pytest.approx(math.pi / 4, abs=1e-15)
        assert (scenario.start.x, scenario.start.y) == (-2.5, -2.0)
        assert scenario.goal_point == (1.5, 2.0)
    check()


def test_a_space_over_a_missing_world_fails_when_made_in_one_line(tmp_path):
    """Not in every run: ScenarioSpace reads its world once; the message names the file once."""
    missing = str(tmp_path / 'arena.sdf')
    with pytest.raises(ScenarioError) as raised:
        ScenarioSpace(world=missing)
    message = str(raised.value)
    assert message.count(missing) == 1 and 'no such world file' in message
    assert '\n' not in message
