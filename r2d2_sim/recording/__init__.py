"""
The live view (Foxglove WebSocket) and MCAP recording, from already-serialized messages.

:class:`~.sink.FoxgloveSink` takes the bytes every publisher sends;
:mod:`.message_definitions` builds the schemas viewers and rosbag2 readers
need from the ROS wheels' ``.msg`` files. No ROS node, no physics.
"""
