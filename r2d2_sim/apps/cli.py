"""
Command-line pieces shared by the ``demo`` and ``drive`` executables and the benchmarks.

argparse types that refuse NaN and infinity, numbers out of range, names that are
no ROS topic or an impossible domain id, the
split between a program's own arguments and ROS's (``--ros-args ...``), and
the exit status after Ctrl-C.
"""

import argparse
import math
import os
import signal
import sys
import threading
from types import FrameType
from typing import Callable, List, Optional, Sequence

# Exit status after Ctrl-C, as a shell reports a process ended by SIGINT.
EXIT_INTERRUPTED = 130
# The largest ROS domain id we accept: Fast DDS refuses 233 and up, and at 232
# its ports run out from the 64th participant on (r2d2_sim.testing.domains).
MAX_DOMAIN_ID = 231


def finite_number(text: str) -> float:
    """Parse a command-line number that must be finite (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}')
    return value


def non_negative_number(text: str) -> float:
    """Parse a finite command-line number >= 0 (an argparse type)."""
    value = finite_number(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f'must be >= 0, got {text!r}')
    return value


def positive_number(text: str) -> float:
    """Parse a finite command-line number > 0 (an argparse type)."""
    value = finite_number(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f'must be > 0, got {text!r}')
    return value


def number_in(low: float, high: float, unit: str = '') -> Callable[[str], float]:
    """
    Return an argparse type for a finite number in [``low``, ``high``] (``unit`` for messages).

    Bounds where a number passes as a float but not through what uses it:
    a ``Duration`` of 1e10 s overflows rcl's nanoseconds, a wait of 1e12 s
    the platform's sleep.
    """
    shown = f' {unit}' if unit else ''

    def number(text: str) -> float:
        value = finite_number(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(
                f'must be in [{low:g}, {high:g}]{shown}, got {text!r}')
        return value
    return number


def topic_name_arg(text: str) -> str:
    """Parse a topic name that rclpy takes for a publisher (an argparse type)."""
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    from rclpy.validate_topic_name import validate_topic_name
    try:
        validate_topic_name(text)
        # Expanded, as a node would: '/a//b' and '~x' pass the check above only.
        validate_full_topic_name(expand_topic_name(text, 'node', '/'))
    except (InvalidTopicNameException, ValueError) as exc:
        # rclpy's text: 'Invalid topic name: WHY:' and lines with a caret; rcl's ValueError
        # "topic name 'X' is invalid: WHY, at FILE:LINE".
        why = str(exc).splitlines()[0].rstrip(':')
        why = why.split(' is invalid: ', 1)[-1].split(', at /', 1)[0]
        why = why.removeprefix('Invalid topic name: ')
        raise argparse.ArgumentTypeError(f'{text!r} is not a ROS topic name: {why}') from None
    return text


def domain_id_arg(text: str) -> int:
    """Parse a ROS domain id, 0-231 (an argparse type)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be an integer, got {text!r}') from None
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise argparse.ArgumentTypeError(f'must be in 0..{MAX_DOMAIN_ID}, got {text!r}')
    return value


def domain_env_problem() -> Optional[str]:
    """
    Return what is wrong with the ``ROS_DOMAIN_ID`` environment variable (None: unset or fine).

    Checked before ROS starts: Fast DDS ends the process itself, with lines of
    its own, at a domain id whose ports do not exist.
    """
    text = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if not text:
        return None
    try:
        value = int(text)
    except ValueError:
        return f'ROS_DOMAIN_ID must be an integer, got {text!r}'
    if not 0 <= value <= MAX_DOMAIN_ID:
        return f'ROS_DOMAIN_ID must be in 0..{MAX_DOMAIN_ID}, got {value}'
    return None


def params_file_problem(argv: Sequence[str]) -> Optional[str]:
    """
    Return what is wrong with a ``--params-file`` among ``argv``'s ROS arguments (None: fine).

    Checked before ROS starts: rcl logs a line of its own, then raises with
    the YAML parser's source locations, for a file that is not there.
    """
    ros = False
    for index, arg in enumerate(argv):
        if arg == '--ros-args':
            ros = True
        elif arg == '--':
            ros = False
        elif ros and arg == '--params-file' and index + 1 < len(argv):
            path = argv[index + 1]
            if not os.path.isfile(path):
                return f'--params-file {path}: no such file'
    return None


def ros_start_problem(argv: Sequence[str]) -> Optional[str]:
    """Return what ROS would refuse to start with, in its own lines (None: nothing found)."""
    return domain_env_problem() or params_file_problem(argv)


def init_ros(argv: Sequence[str], prog: str) -> bool:
    """
    Initialise rclpy for a tool without rclpy's signal handlers; False after one error line.

    The tools take Ctrl-C themselves (``sim_node.stop_on_signals``): rclpy's
    handler would raise inside its own message handling.
    """
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    problem = ros_start_problem(argv)
    if problem is not None:
        print(f'{prog}: error: {problem}', file=sys.stderr)
        return False
    try:
        rclpy.init(args=list(argv), signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an invalid ROS_DOMAIN_ID; rclpy raises assorted types
        print(f'{prog}: error: cannot initialise ROS: {exc}', file=sys.stderr)
        return False
    return True


def non_ros_args(argv: Sequence[str], prog: str) -> List[str]:
    """
    Return the arguments after the program name that are not for ROS.

    Malformed ``--ros-args`` end the program like an argparse error: one line
    on stderr and exit status 2.
    """
    from rclpy.utilities import remove_ros_args
    try:
        return remove_ros_args(list(argv))[1:]
    except Exception as exc:  # rcl's parse errors come as assorted exception types
        print(f'{prog}: error: bad ROS arguments: {exc}', file=sys.stderr)
        raise SystemExit(2)


class SignalledEvent(threading.Event):
    """
    An event a signal handler sets without a lock: :meth:`is_set` is true from the signal on.

    :func:`stop_on_signals` sets :attr:`signalled` (a plain attribute) in
    the handler, and the event itself from a thread a moment later: a check
    made right after the signal (the demo's, as it stops spinning) sees it.
    """

    def __init__(self) -> None:
        super().__init__()
        self.signalled = False

    def is_set(self) -> bool:
        """Return True once a signal came or the event was set."""
        return self.signalled or super().is_set()


def stop_on_signals(stop: Optional[threading.Event] = None) -> threading.Event:
    """
    Return an event (``stop``, or a new one) that SIGINT, SIGTERM and SIGHUP set from now on.

    SIGHUP (the terminal closed, the SSH session dropped) killed the process
    before it could finish its recording; it stops it as SIGTERM does, unless
    the process was started ignoring it (``nohup``), which is kept.

    The handler takes no lock: Python runs it in the main thread between two
    bytecodes, which may be inside ``stop.wait()`` or ``stop.set()`` with the
    event's lock held (``sim_node``'s loop waits on it hundreds of times a
    second while paused); setting the event there waited for that lock
    forever, and the process ignored SIGTERM and SIGINT (seen once). It
    writes a byte down a pipe, and a thread of its own sets the event; a
    :class:`SignalledEvent` (the default) reads as set at once.
    """
    stop = SignalledEvent() if stop is None else stop

    def handler(signum: int, frame: Optional[FrameType]) -> None:
        if isinstance(stop, SignalledEvent):
            stop.signalled = True
        wake()
    wake = _set_from_a_thread(stop)
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    hangup = getattr(signal, 'SIGHUP', None)  # not on Windows
    if hangup is not None and signal.getsignal(hangup) is not signal.SIG_IGN:
        signal.signal(hangup, handler)
    return stop


def _set_from_a_thread(stop: threading.Event) -> Callable[[], None]:
    """Return ``wake()``, which takes no lock, and a thread that sets ``stop`` at the first."""
    read_end, write_end = os.pipe()  # neither inherited by a child
    os.set_blocking(write_end, False)

    def relay() -> None:
        try:
            os.read(read_end, 1)
        finally:
            stop.set()
    threading.Thread(target=relay, name='stop_on_signals', daemon=True).start()

    def wake() -> None:
        try:
            os.write(write_end, b'\0')
        except OSError:  # the pipe is full: the thread has a byte to wake to already
            pass
    return wake


def raise_if_stopped(stop: threading.Event) -> None:
    """
    Raise ``KeyboardInterrupt`` if ``stop`` is set: Ctrl-C, taken where the caller chooses.

    For the client executables (``demo``, ``drive``), called between spins.
    rclpy's own SIGINT handler raises wherever the main thread happens to be;
    inside ``take_message`` pybind11 turns that into a ``RuntimeError``
    traceback, and the context is already shut down, too late to publish a stop.
    """
    if stop.is_set():
        raise KeyboardInterrupt
