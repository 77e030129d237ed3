"""
Publishing from a second process: the physics thread hands each step's bytes over and goes on.

rclpy's ``publish`` holds the interpreter lock through the whole DDS write
(pybind11, no release), so no thread of the simulator's process can publish
while the physics runs: with every topic of 16 robots taken, the writes cost
about 1.5 ms of each 4.2 ms step at real time (bench/README.md). With
``outputs_process`` the node's publishers are relayed (:class:`RelayedPublisher`):
the outputs build their messages as always (the serialized templates, patched
in place) and a relayed ``publish`` only appends the bytes to the step's
batch; at the end of the step one ``write`` hands the batch to the child
process (:mod:`r2d2_sim.ros.relay_child`), whose own node (``NAME_outputs``, in
the simulator's namespace) owns the real publishers and publishes the bytes in
the order they were made. Subscribers get the same bytes, in the same order,
with the same stamps.

The parts:

- frames on a pipe, parent to child: a header (:data:`FRAME`: payload length,
  sequence number, flags) and records (:data:`RECORD`: publisher index or
  :data:`CREATE`/:data:`DESTROY`, data length, data). A publisher's creation
  and destruction travel in the same stream as the messages, so the child
  always has the publisher a message names. The pipe holds 1 MiB where Linux
  lets it: a child that falls behind by more makes the physics wait, as long
  as it takes something within :data:`WAIT_S` (10 s) of each write that
  found the pipe full. One that takes nothing for that long is given up on
  (see the end).
- acknowledgements on a second pipe, child to parent, only for frames that
  ask (:data:`ACK`): :meth:`OutputRelay.wait` sends an empty frame asking and
  waits for its number. :meth:`SimNode.advance <r2d2_sim.ros.node.SimNode.advance>`
  waits so: a lockstep step (``~/step``, the standard's StepSimulation, a
  harness's ``advance``) returns once its messages are out; the real-time loop
  does not wait.
- matched subscriptions, child to parent, in a shared memory map (an
  anonymous ``memfd``: nothing to clean up): one int32 per publisher, written
  by the child's matched events. The outputs ask it as they ask an rclpy
  publisher (:func:`r2d2_sim.ros.mirror.demand`), and build nothing nobody takes.
- the live view and the recording (``sink``), when asked, live in the child
  too: it opens the :class:`~r2d2_sim.recording.sink.FoxgloveSink`, says on
  the acknowledgements' pipe whether that worked (:data:`REPORT`, before
  anything else), and logs each message it publishes to the sink at the
  simulated time the parent stamped on the stream (:data:`TIME` records, one
  whenever the time moved; :meth:`OutputRelay.set_time` sends one for the
  live view's clock where the node would tell its own sink). The same calls
  in the same order as the node made in its own process: the same MCAP file,
  byte for byte. A second map of the same size says which publishers'
  messages a viewer takes (written when a viewer subscribes or unsubscribes),
  so that with a live view alone nothing nobody watches is built either.

The child ends when the pipe closes (the node is destroyed, or its process
died); a child that died makes the next write fail, and the node logs one
error and publishes nothing more rather than stopping its physics. A child
that is stuck (it took nothing for :data:`WAIT_S`, or did not answer a
lockstep wait) is given up on the same way, and ended too, so that no
publishers of it stay on the graph saying nothing: its pipe closed, SIGTERM
(and SIGCONT, for a stopped one), SIGKILL if that does not end it (as
:meth:`OutputRelay.close` does, on a thread of its own: the physics goes on).
"""

import json
import mmap
import os
import select
import signal
import struct
import subprocess
import sys
import threading
import time
import weakref
from typing import Any, Callable, Dict, List, Optional, Tuple

from rclpy.qos import QoSProfile

from r2d2_sim.ros.cdr import message_bytes, ros_type_name

__all__ = ['OutputRelay', 'RelayedPublisher', 'RelayError', 'FRAME', 'RECORD', 'CREATE',
           'DESTROY', 'TIME', 'TIME_RECORD', 'REPORT', 'ACK', 'MAX_PUBLISHERS',
           'qos_to_dict', 'qos_from_dict']

FRAME = struct.Struct('<IQB')   # payload bytes after this header, sequence number, flags
RECORD = struct.Struct('<iI')   # publisher index (or CREATE / DESTROY), data bytes
ACK_RECORD = struct.Struct('<Q')
REPORT = struct.Struct('<I')     # the child's start report: JSON bytes after this length
TIME_RECORD = struct.Struct('<q')
CREATE = -1                      # data: the publisher as JSON (index, topic, type, QoS)
DESTROY = -2                     # data: the index as JSON
TIME = -3                        # data: the simulated time (ns) of the messages after it
ACK = 1                          # flag: the child writes the frame's number back once published
MAX_PUBLISHERS = 4096            # the shared counts' slots (indices of destroyed ones are reused)
PIPE_BYTES = 1 << 20             # Linux's default /proc/sys/fs/pipe-max-size
F_SETPIPE_SZ = 1031
WAIT_S = 10.0                    # the longest wait for the child to take or answer anything
START_S = 60.0                   # the longest wait for a child opening a sink to report
CLOSE_S = 5.0                    # the longest wait for the child to end


class RelayError(RuntimeError):
    """The outputs process could not start, or did not answer in time."""


def qos_to_dict(qos: QoSProfile) -> Dict[str, int]:
    """Return every field of a QoS as numbers (durations in ns), for the child to rebuild."""
    return {'history': int(qos.history), 'depth': int(qos.depth),
            'reliability': int(qos.reliability), 'durability': int(qos.durability),
            'liveliness': int(qos.liveliness),
            'deadline': qos.deadline.nanoseconds, 'lifespan': qos.lifespan.nanoseconds,
            'liveliness_lease_duration': qos.liveliness_lease_duration.nanoseconds,
            'avoid_ros_namespace_conventions': int(qos.avoid_ros_namespace_conventions)}


def qos_from_dict(fields: Dict[str, int]) -> QoSProfile:
    """Return the QoSProfile :func:`qos_to_dict` described (the same offered QoS)."""
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, ReliabilityPolicy
    return QoSProfile(
        history=HistoryPolicy(fields['history']), depth=fields['depth'],
        reliability=ReliabilityPolicy(fields['reliability']),
        durability=DurabilityPolicy(fields['durability']),
        liveliness=LivelinessPolicy(fields['liveliness']),
        deadline=Duration(nanoseconds=fields['deadline']),
        lifespan=Duration(nanoseconds=fields['lifespan']),
        liveliness_lease_duration=Duration(nanoseconds=fields['liveliness_lease_duration']),
        avoid_ros_namespace_conventions=bool(fields['avoid_ros_namespace_conventions']))


def _ready(fd: int, event: int, timeout_s: float) -> bool:
    """Return True once ``fd`` is ready for ``event`` (POLLIN, POLLOUT) within ``timeout_s``."""
    poller = select.poll()  # not select(): a test process may hold fds above 1023
    poller.register(fd, event)
    return bool(poller.poll(max(0.0, timeout_s) * 1000.0))


def _close_fds(fds: Tuple[int, ...]) -> None:
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass


class RelayedPublisher:
    """A publisher whose messages the outputs process publishes; rclpy's interface, in part."""

    def __init__(self, relay: 'OutputRelay', index: int, msg_type: type, topic_name: str,
                 qos_profile: QoSProfile) -> None:
        self.relay = relay
        self.index = index
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.qos_profile = qos_profile
        self.destroyed = False

    def publish(self, msg: Any) -> None:
        """Hand ``msg`` (a message or its serialized bytes) to the outputs process."""
        if self.destroyed:  # as rclpy's InvalidHandle says it
            raise RelayError(f'the publisher of {self.topic_name} was destroyed')
        self.relay.publish(self.index, message_bytes(msg, self.msg_type))

    def get_subscription_count(self) -> int:
        """Return the subscriptions the child's publisher matched (its latest matched event)."""
        return self.relay.subscription_count(self.index)

    def subscription_counter(self) -> Callable[[], int]:
        """
        Return the cheapest way to ask whether anyone takes this (the outputs' demand).

        The child's matched subscriptions, and with a live view in the child
        whether a viewer takes the topic; with a recording, always.
        """
        relay, index = self.relay, self.index
        counts, taken = relay.counts, relay.sink_taken
        if relay.sink_record_path is not None:
            return _one
        if relay.sink_live:
            return lambda: counts[index] or taken[index]
        return lambda: counts[index]

    def destroy(self) -> None:
        """Take the child's publisher down (once)."""
        if not self.destroyed:
            self.destroyed = True
            self.relay.destroy(self.index)


def _one() -> int:
    return 1


class OutputRelay:
    """
    The outputs process of one simulator, and the pipe to it (see the module).

    ``domain_id`` is the simulator's context's; the child's node is
    ``node_name`` in ``namespace``. ``log_error`` says, once, that the child
    is gone. ``sink``: the live view and recording to open in the child
    (:class:`~r2d2_sim.recording.sink.FoxgloveSink`'s ``port``, ``host``,
    ``record_path`` and ``name``; None: none), whose messages are logged at
    ``time_ns()`` when they are handed over. Raises :class:`RelayError` when
    the process cannot start, or its sink cannot (the sink's own line).
    """

    def __init__(self, domain_id: int, node_name: str, namespace: str,
                 log_error: Callable[[str], None] = print, *,
                 sink: Optional[Dict[str, Any]] = None,
                 time_ns: Optional[Callable[[], int]] = None) -> None:
        self._log_error = log_error
        if sink is not None and time_ns is None:
            raise ValueError('a sink in the outputs process needs time_ns')
        try:
            counts_fd = os.memfd_create('r2d2_sim_outputs_counts')
        except (AttributeError, OSError) as exc:  # memfd_create is Linux's
            raise RelayError(f'outputs_process needs memfd_create (Linux): {exc}') from exc
        os.ftruncate(counts_fd, 8 * MAX_PUBLISHERS)
        self._map = mmap.mmap(counts_fd, 8 * MAX_PUBLISHERS)
        shared = memoryview(self._map).cast('i')
        self.counts = shared[:MAX_PUBLISHERS]       # matched subscriptions, by index
        self.sink_taken = shared[MAX_PUBLISHERS:]   # 1 while a viewer takes the topic
        self._time_ns = time_ns if sink is not None else None
        self._sent_time: Optional[int] = None
        spec = sink or {}
        self.sink_live = spec.get('port') is not None
        self.sink_record_path: Optional[str] = spec.get('record_path')
        self.sink_url: Optional[str] = None  # the live view's address, once the child said
        frames_read, self._frames = os.pipe()
        self._acks, acks_write = os.pipe()
        try:
            import fcntl
            fcntl.fcntl(self._frames, F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:  # a lower pipe-max-size: the default 64 KiB
            pass
        command = [sys.executable, '-m', 'r2d2_sim.ros.relay_child',
                   '--frames', str(frames_read), '--acks', str(acks_write),
                   '--counts', str(counts_fd), '--domain', str(domain_id),
                   '--node', node_name, '--namespace', namespace]
        if sink is not None:
            command += ['--sink', json.dumps(sink)]
        try:
            # A session of its own: a Ctrl-C in the terminal reaches the simulator only
            # (the child, still importing rclpy, printed a KeyboardInterrupt traceback);
            # the simulator's end closes the pipe, and that ends the child.
            self.process: Optional[subprocess.Popen] = subprocess.Popen(
                command, pass_fds=(frames_read, acks_write, counts_fd), stdin=subprocess.DEVNULL,
                start_new_session=True)
        except OSError as exc:
            for fd in (self._frames, self._acks):
                os.close(fd)
            raise RelayError(f'cannot start the outputs process: {exc}') from exc
        finally:
            for fd in (frames_read, acks_write, counts_fd):
                os.close(fd)
        os.set_blocking(self._frames, False)  # a stuck child: a deadline, not a hang
        # A node never destroyed: its pipe closes at exit or collection, and the child ends.
        self._finalizer = weakref.finalize(self, _close_fds, (self._frames, self._acks))
        self._lock = threading.RLock()  # one frame at a time, whichever thread publishes
        self._broke_lock = threading.Lock()
        self._acks_left = b''  # a partial acknowledgement read (never split in practice)
        self._pending: List[bytes] = []
        self._batching = 0
        self._sequence = 0
        self._acknowledged = 0
        self._next_index = 0
        self._free: List[int] = []
        self.broken = False
        self.frames_sent = 0
        self._ending: Optional[threading.Thread] = None  # ends a child given up on (_broke)
        if sink is not None:
            try:
                self._await_report()
            except BaseException:  # a refusal, or a Ctrl-C meanwhile: no child left behind
                self.close(1.0)
                raise

    def _await_report(self) -> None:
        """Read the child's start report: its sink's address, or why it could not open."""
        deadline, data = time.monotonic() + START_S, b''
        while True:
            if len(data) >= REPORT.size:
                (length,) = REPORT.unpack_from(data)
                if len(data) >= REPORT.size + length:
                    break
            left = deadline - time.monotonic()
            chunk = (os.read(self._acks, 4096)
                     if left > 0.0 and _ready(self._acks, select.POLLIN, left) else None)
            if not chunk:
                status = self.close(1.0)
                why = (f'it did not answer within {START_S:g} s' if chunk is None
                       else f'it ended with status {status}')
                raise RelayError(f'the outputs process could not start: {why}')
            data += chunk
        report = json.loads(data[REPORT.size:REPORT.size + length])
        self._acks_left = data[REPORT.size + length:]
        if 'error' in report:
            self.close(1.0)
            raise RelayError(report['error'])
        self.sink_url = report.get('url')

    # -- publishers ---------------------------------------------------------------------

    def create_publisher(self, msg_type: type, topic_name: str,
                         qos_profile: QoSProfile) -> RelayedPublisher:
        """Have the child make a publisher of ``msg_type`` on the resolved ``topic_name``."""
        with self._lock:
            return self._create_publisher(msg_type, topic_name, qos_profile)

    def _create_publisher(self, msg_type: type, topic_name: str,
                          qos_profile: QoSProfile) -> RelayedPublisher:
        if self._free:
            index = self._free.pop()
        elif self._next_index < MAX_PUBLISHERS:
            index, self._next_index = self._next_index, self._next_index + 1
        else:
            raise RelayError(f'the outputs process holds {MAX_PUBLISHERS} publishers at most')
        self.counts[index] = self.sink_taken[index] = 0
        self._record(CREATE, json.dumps({
            'index': index, 'topic': topic_name, 'type': ros_type_name(msg_type),
            'qos': qos_to_dict(qos_profile)}).encode())
        return RelayedPublisher(self, index, msg_type, topic_name, qos_profile)

    def destroy(self, index: int) -> None:
        """Have the child destroy the publisher ``index``; the index is free again after."""
        with self._lock:
            self._record(DESTROY, json.dumps({'index': index}).encode())
            self.counts[index] = self.sink_taken[index] = 0
            self._free.append(index)

    def subscription_count(self, index: int) -> int:
        """Return what the child last said about publisher ``index``'s matched subscriptions."""
        return self.counts[index]

    # -- messages -----------------------------------------------------------------------

    def publish(self, index: int, data: bytes) -> None:
        """Queue ``data`` for publisher ``index``: at once, or at the end of the batch."""
        self._record(index, data)

    def set_time(self, time_ns: int) -> None:
        """Tell the child's live view the simulated time, as the node tells its own sink."""
        if self.sink_live:
            with self._lock:
                self._stamp(time_ns)
                if not self._batching:
                    self._send(0)

    def _stamp(self, time_ns: int) -> None:
        """Queue a TIME record if the time moved since the last one (the lock held)."""
        if time_ns != self._sent_time:
            self._sent_time = time_ns
            self._pending.append(RECORD.pack(TIME, TIME_RECORD.size))
            self._pending.append(TIME_RECORD.pack(time_ns))

    def _record(self, index: int, data: bytes) -> None:
        with self._lock:
            if self._time_ns is not None and index >= 0:
                self._stamp(self._time_ns())  # what the sink logs it at, as a mirror would
            self._pending.append(RECORD.pack(index, len(data)))
            self._pending.append(data)
            if not self._batching:
                self._send(0)

    def begin(self) -> None:
        """Start a batch (a step): what is published until :meth:`end` goes in one frame."""
        self._lock.acquire()  # held through the batch: another thread's records wait
        self._batching += 1

    def end(self) -> None:
        """End a batch; the outermost one sends its frame."""
        try:
            self._batching -= 1
            if not self._batching and self._pending:
                self._send(0)
        finally:
            self._lock.release()

    def _send(self, flags: int) -> int:
        """Write the pending records as one frame; return its sequence number (0: not sent)."""
        if self.broken:
            self._pending = []
            return 0
        payload = b''.join(self._pending)
        self._pending = []
        self._sequence += 1
        frame = FRAME.pack(len(payload), self._sequence, flags) + payload
        view, deadline = memoryview(frame), None
        try:
            while view:
                try:
                    view = view[os.write(self._frames, view):]
                    deadline = None  # it took some: a child behind, not a stuck one
                except BlockingIOError:  # the pipe is full: the child is behind
                    now = time.monotonic()
                    deadline = deadline or now + WAIT_S
                    if now >= deadline or not _ready(self._frames, select.POLLOUT,
                                                     deadline - now):
                        self._broke(f'it took nothing for {WAIT_S:g} s')
                        return 0
        except OSError as exc:  # BrokenPipeError: the child is gone
            self._broke(f'{exc.strerror or exc}')
            return 0
        self.frames_sent += 1
        return self._sequence

    def wait(self, timeout_s: Optional[float] = None) -> bool:
        """
        Return once the child has published everything handed over so far (True).

        False when the child is gone or did not answer within ``timeout_s``
        (default :data:`WAIT_S`; said once in the node's log, and the child
        ended).
        """
        with self._lock:
            if self._batching:
                raise RuntimeError('wait() inside a batch: its frame is not sent yet')
            target = self._send(ACK)
            if not target:
                return False
            timeout_s = WAIT_S if timeout_s is None else timeout_s
            deadline = time.monotonic() + timeout_s
            while self._acknowledged < target:
                left = deadline - time.monotonic()
                if left <= 0.0 or not _ready(self._acks, select.POLLIN, left):
                    self._broke(f'no answer within {timeout_s:g} s')
                    return False
                data = self._acks_left + os.read(self._acks, 4096)
                if data == self._acks_left:
                    self._broke('it closed its pipe')
                    return False
                usable = len(data) - len(data) % ACK_RECORD.size  # whole numbers only
                self._acks_left = data[usable:]
                for (number,) in ACK_RECORD.iter_unpack(data[:usable]):
                    self._acknowledged = max(self._acknowledged, number)
            return True

    def _broke(self, why: str) -> None:
        with self._broke_lock:  # the physics thread and a status request may both find it
            if self.broken:
                return
            self.broken = True
        process = self.process
        status = process.poll() if process is not None else None
        ended = '' if status is None else f' (it ended with status {status})'
        lost = ('nothing more is published or recorded' if self.sink_record_path is not None
                else 'nothing more is published')
        if process is not None and status is None:
            lost = f'ending it (its publishers leave the graph): {lost}'
        self._log_error(f'the outputs process failed{ended}: {why}; {lost}')
        if process is not None and status is None:
            self._end(process)

    def _end(self, process: subprocess.Popen) -> None:
        """
        End a child given up on but still there: no publishers of it stay on the graph.

        Its pipes closed, SIGTERM now (SIGCONT: a stopped child takes it
        too), then, on a thread of its own, what :meth:`close` does to a
        child that does not end: the physics thread does not wait for it.
        """
        with self._lock:  # no write on the pipes while they close (a status request's thread)
            self._pending = []
            self._finalizer()
        process.terminate()
        process.send_signal(signal.SIGCONT)
        self._ending = threading.Thread(target=self._finish, args=(process, CLOSE_S),
                                        name='ending the outputs process', daemon=True)
        self._ending.start()

    # -- the process --------------------------------------------------------------------

    def close(self, timeout_s: float = CLOSE_S) -> Optional[int]:
        """
        Close the pipe (the child publishes what it has, then ends); return its status.

        A child that does not end within ``timeout_s`` gets SIGTERM, then
        SIGKILL after as long again. A child that records waits as long as
        its file grows (a slow disk still taking the queue: the recording is
        what the user asked for); SIGTERM then drops what is left and still
        finishes the file. A child given up on (see the module) is being
        ended already: this waits for that. The counts' map stays until the
        last publisher asking it is gone.
        """
        with self._lock:
            process, self.process = self.process, None
            if process is None:
                return None
            self._pending = []
            self.broken = True  # quietly: what is published after this goes nowhere
            self._finalizer()  # closes the pipes: the child publishes what it has, then ends
        if self._ending is not None:  # given up on, and being ended already
            self._ending.join()
            return process.wait()
        return self._finish(process, timeout_s)

    def _finish(self, process: subprocess.Popen, timeout_s: float) -> int:
        """Wait for ``process`` to end, its pipes closed; SIGTERM, then SIGKILL if stuck."""
        size = self._recorded_bytes()
        while True:
            try:
                return process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                grown = self._recorded_bytes()
                if grown is None or grown <= (size or 0):
                    break
                size = grown  # the disk is still taking the recording: wait on
        process.terminate()  # stuck: SIGTERM is a clean exit (the file finished), SIGKILL not
        try:
            return process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            return process.wait()

    def _recorded_bytes(self) -> Optional[int]:
        """Return the size of the child's recording now (None: no recording, or no file)."""
        if self.sink_record_path is None:
            return None
        try:
            return os.stat(self.sink_record_path).st_size
        except OSError:
            return None

    @property
    def running(self) -> bool:
        """Return True while the child is alive and takes frames (a dead one is said once)."""
        process = self.process
        if process is not None and not self.broken and process.poll() is not None:
            self._broke('it ended')  # found by asking, before the next write would
        return process is not None and not self.broken

    def describe(self) -> Tuple[int, int]:
        """Return (frames sent, publishers held): for status and tests."""
        return self.frames_sent, self._next_index - len(self._free)
