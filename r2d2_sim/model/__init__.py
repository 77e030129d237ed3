"""
Pure math, numpy at most: no PyBullet, no ROS (a test imports them all and checks).

Differential-drive kinematics and odometry (:mod:`.kinematics`), the drive
controller from command to wheel targets (:mod:`.drive_controller`), rigid
transforms, a URDF's link tree and a tf2-style buffer of them (:mod:`.transforms`,
:mod:`.link_tree`, :mod:`.tf_buffer`), sensor models (:mod:`.sensors`, :mod:`.camera`),
Gazebo's sensor noise (:mod:`.noise`), wheel encoders that err (:mod:`.encoders`), a
battery (:mod:`.battery`), regions on the ground (:mod:`.regions`), physics health
checks (:mod:`.health`) and step timing (:mod:`.timing`).
"""
