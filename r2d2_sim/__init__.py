"""
r2d2_sim: a ROS 2 node that runs a PyBullet simulation of R2D2.

The package is split so that each layer can be tested alone:
``drive`` (differential-drive math, no ROS, no PyBullet), ``world``
(the PyBullet world, no ROS) and ``node`` (the rclpy plumbing).
"""
