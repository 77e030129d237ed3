"""
``contacts``: what a robot touches, as visualization_msgs/MarkerArray, live and recorded.

A robot driven at 0.5 m/s into a fixed wall whose face is at x = 0.9 m: its
gripper (0.515 m ahead of the base link) meets the face, and every marker
stands on it. The markers are the core's contact reading (the RunWatch's).
"""

import pytest
from visualization_msgs.msg import Marker, MarkerArray

from r2d2_sim.testing import box_urdf, read_recording, SimHarness, stamp_ns

WALL_FACE_X = 0.9


def drive_into_the_wall(harness, seconds=4.0):
    """Spawn the wall, listen to contacts, drive into it; return the arrays received."""
    received = []
    harness.create_node('listener', use_sim_time=False).create_subscription(
        MarkerArray, 'contacts', received.append, 10)
    harness.spawn(box_urdf((0.2, 2.0, 1.0)), name='wall', position=(WALL_FACE_X + 0.1, 0.0, 0.5))
    harness.send_cmd_vel(linear=0.5)
    with harness.watch() as watch:
        harness.advance(seconds=seconds)
    return received, watch


def test_a_robot_pushed_into_a_wall_publishes_markers_at_the_contact_point(tmp_path):
    """Nothing until it touches; then a sphere per touched body on the wall's face, recorded."""
    recording = tmp_path / 'contacts.mcap'
    with SimHarness(cmd_vel_timeout=0.0, publish_contacts=True,
                    record=str(recording)) as harness:
        received, watch = drive_into_the_wall(harness)
    assert received, 'no contacts published'
    first = received[0]
    assert stamp_ns(first.markers[0].header.stamp) == watch.contacts[0].start_ns
    assert first.markers[0].action == Marker.DELETEALL  # a viewer drops the last contacts
    spheres = [m for array in received for m in array.markers if m.action == Marker.ADD]
    assert spheres and all(m.type == Marker.SPHERE and m.ns == 'wall' for m in spheres)
    assert all(m.header.frame_id == 'world' for m in spheres)
    for marker in spheres:
        assert marker.pose.position.x == pytest.approx(WALL_FACE_X, abs=0.01)
    assert spheres[0].text == f'{watch.contacts[0].robot_link} -> box'
    position = spheres[0].pose.position
    assert (position.x, position.y, position.z) == watch.contacts[0].position
    # Published at the state rate while touching: once each publication, never before.
    stamps = [stamp_ns(array.markers[0].header.stamp) for array in received]
    assert stamps == sorted(set(stamps)) and stamps[0] >= watch.contacts[0].start_ns
    recorded = read_recording(str(recording), topics=['/contacts'])['/contacts']
    assert [r.message for r in recorded] == received
    assert [r.log_time_ns for r in recorded] == stamps


def test_when_a_contact_ends_one_array_clears_the_markers():
    """It bounces off the wall: at each contact's end a DELETEALL alone, then silence."""
    with SimHarness(cmd_vel_timeout=0.0, publish_contacts=True) as harness:
        received, watch = drive_into_the_wall(harness, seconds=3.0)
        harness.send_cmd_vel(linear=-0.5)
        harness.advance(seconds=1.0)
        ended = [c.end_ns for c in watch.contacts if c.end_ns is not None]
        assert ended, 'the robot never left the wall'
        before = len(received)
        harness.advance(seconds=1.0)  # away from the wall: nothing more
    assert len(received) == before
    clears = [stamp_ns(a.markers[0].header.stamp) for a in received
              if [m.action for m in a.markers] == [Marker.DELETEALL]]
    assert clears == ended
    # Published at every step (the state rate here) from each start to its end, only then.
    stamps = [stamp_ns(a.markers[0].header.stamp) for a in received]
    steps = [round((c.end_ns - c.start_ns) * 240 / 1e9) + 1 for c in watch.contacts]
    assert len(stamps) == sum(steps)
    assert all(any(c.start_ns <= t <= c.end_ns for c in watch.contacts) for t in stamps)


def test_contacts_are_off_by_default():
    """Without publish_contacts there is no contacts publisher at all."""
    with SimHarness(cmd_vel_timeout=0.0) as harness:
        assert 'contacts' not in [p.topic_name.rsplit('/', 1)[-1] for p in harness.sim.publishers]
