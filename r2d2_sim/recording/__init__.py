"""
The live view (Foxglove WebSocket) and MCAP recording, from already-serialized messages.

:class:`~.sink.FoxgloveSink` takes the bytes every publisher sends, each
publisher through its :class:`~.channels.SinkChannel`; the file goes through
:mod:`.mcap_file` (a full disk ends the recording in one report) and the
server's health is watched by :mod:`.live_guard`; :mod:`.message_definitions`
builds the schemas viewers and rosbag2 readers need from the ROS wheels'
``.msg`` files; :mod:`.reader` reads a recording from anywhere back, within
bounds and cut-off files included, importing message classes only from
installed interface packages. No ROS node, no physics.
"""
