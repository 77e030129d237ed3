"""
PyBullet, and nothing of ROS: the world, its bodies and what is read from them.

:class:`~.world.SimWorld` owns its physics client; every body in it is a
:class:`~.body.Body` that owns its id; PyBullet's tuples are named once in
:mod:`.records`; ray casts in :mod:`.raycast`; robot descriptions (URDF files,
packages, text) are found in :mod:`.description`.
"""
