"""
The live view (Foxglove WebSocket) and MCAP recording, from already-serialized messages.

:class:`~.sink.FoxgloveSink` takes the bytes every publisher sends;
:mod:`.message_definitions` builds the schemas viewers and rosbag2 readers
need from the ROS wheels' ``.msg`` files; :mod:`.reader` reads a recording
from anywhere back, within bounds and cut-off files included, importing
message classes only from installed interface packages. No ROS node, no physics.
"""
