"""
battery_state on the wire, as Nav2's docking server reads it with use_battery_status.

opennav_docking's SimpleChargingDock subscribes ``battery_state`` (relative,
so in the robot's namespace) and calls the robot charging when
``current > charging_threshold`` (0.5 A by default). A robot resting on its
dock must publish that; one driving away a negative current. Both a default
and a sensor-data (best effort) subscriber receive the messages.
"""

import math

import pytest
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import BatteryState

from helpers import make_sim
from r2d2_sim.testing import wait_for

NAV2_CHARGING_THRESHOLD_A = 0.5


def listen(ros):
    node = ros.create_node('battery_listener', use_sim_time=False)
    reliable, best_effort = [], []
    node.create_subscription(BatteryState, 'battery_state', reliable.append, 10)
    node.create_subscription(BatteryState, 'battery_state', best_effort.append,
                             qos_profile_sensor_data)
    return reliable, best_effort


def test_a_robot_on_its_dock_reports_charging_as_nav2_docking_reads_it(ros):
    sim = make_sim(ros, battery_rate=10.0, battery_initial_charge=0.5,
                   battery_dock_pose=[0.5, 0.25, 0.3], initial_pose=[0.5, 0.25, 0.3])
    reliable, best_effort = listen(ros)
    sim.advance(48)
    assert wait_for(lambda: len(reliable) >= 2 and best_effort)
    state = reliable[-1]
    assert state.current > NAV2_CHARGING_THRESHOLD_A
    assert state.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    assert state.header.frame_id == 'base_link'
    assert (state.header.stamp.sec, state.header.stamp.nanosec) == (0, 200_000_000)
    assert state.capacity == state.design_capacity == 2.0
    assert state.percentage == pytest.approx(0.5, abs=1e-3)
    assert state.voltage == pytest.approx(12.8 + 4.0 * state.percentage, abs=1e-4)
    assert state.present and math.isnan(state.temperature)


def test_a_robot_away_from_its_dock_discharges(ros):
    sim = make_sim(ros, battery_rate=10.0, battery_dock_pose=[3.0, 0.0, 0.0],
                   cmd_vel_timeout=0.0)
    reliable, _ = listen(ros)
    sim.simulation.robot.command(0.3, 0.0)
    sim.advance(240)
    assert wait_for(lambda: len(reliable) >= 10)
    state = reliable[-1]
    assert state.current < -NAV2_CHARGING_THRESHOLD_A
    assert state.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert state.percentage < 1.0


def test_no_battery_topic_unless_asked(sim):
    topics = [name for name, _ in sim.get_topic_names_and_types()]
    assert '/battery_state' not in topics


def test_an_empty_dock_pose_is_no_dock_as_ros_hands_it_over(ros):
    """``battery_dock_pose:=[]`` (ROS gives an empty array as None): no dock, no traceback."""
    sim = make_sim(ros, battery_rate=10.0, battery_dock_pose=None)
    assert list(sim.get_parameter('battery_dock_pose').value or []) == []
    reliable, _ = listen(ros)
    sim.advance(48)
    assert wait_for(lambda: len(reliable) >= 2)
    assert reliable[-1].power_supply_status != BatteryState.POWER_SUPPLY_STATUS_CHARGING
