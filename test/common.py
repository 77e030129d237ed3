"""
Helpers every tier of this project's tests may use: no ROS, no PyBullet.

The fast tier (``test/model``, ``test/physics``, ``test/sim``) imports from
here, never from ``helpers`` (which loads rclpy and the node). What several
tiers share after a test file was split by tier lives here too, under the
names the tests call it by; the ROS helpers shared that way are in ``helpers``.
Imports of anything heavier than the standard library happen inside the
functions, so importing this module stays cheap (the top conftest does).
"""

import os

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TEST_DIR = os.path.join(REPO, 'test')
RATE_HZ = 240

# Leases taken by helpers.next_domain_id, released by conftest after each test.
leases = []
