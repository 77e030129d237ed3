"""
The farm's promise of determinism: one run recorded twice gives one file, byte for byte.

Before serialize() zeroed CDR's padding, two recordings of one run had the
same messages but different bytes (padding held whatever rclpy's buffer held),
so their hashes differed.
"""

import hashlib

from r2d2_sim.testing import box_urdf, SimHarness


def record(path):
    """Drive into the room and a box, contacts on, everything recorded."""
    with SimHarness(cmd_vel_timeout=0.0, record=str(path), publish_contacts=True,
                    world='package://r2d2_sim/urdf/room.urdf', publish_link_tf=True) as harness:
        harness.spawn(box_urdf((0.3, 0.3, 0.5)), name='box', position=(1.0, 0.0, 0.25))
        harness.send_cmd_vel(linear=0.4, angular=0.1)
        harness.advance(seconds=3.0)
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_one_run_recorded_twice_is_one_file(tmp_path):
    """Two harnesses, the same commands: equal SHA-256 of the MCAP files."""
    assert record(tmp_path / 'a.mcap') == record(tmp_path / 'b.mcap')
