"""
One driven robot in the world, by concept.

No ROS. :mod:`.robot` holds :class:`~.robot.Robot` (its body, controller, sensors and
their rates, measured each step); :mod:`.drive_train` finds which joints drive it;
:mod:`.sensors` holds its sensors and where they sit on it (head camera, laser,
3D lidar, IMU).
"""
