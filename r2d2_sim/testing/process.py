"""
Child processes: start one with its output in a file, watch it, stop it (SIGINT, then SIGKILL).

One layer for everyone who runs ``sim_node`` or a helper in a process of its
own: :class:`~r2d2_sim.testing.sim_process.SimProcess`, the ``demo``, the
benchmarks and this project's tests. Output goes to a file, never a pipe:
nobody reads while the child runs, and a full pipe would block it. A child
is told this process's id (``R2D2_SIM_PARENT_PID``): ``sim_node`` ends by
itself when this process dies without stopping it (SIGKILL by a CI timeout).
"""

import os
import signal
import subprocess
import sys
import tempfile
from typing import Any, IO, List, Mapping, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.client import PARENT_PID_ENV, ros_arg

__all__ = ['ProcessResult', 'stop_process', 'ChildProcess', 'sim_node_command',
           'RosArgs', 'parse_ros_args']


class ProcessResult(NamedTuple):
    """How a process ended: its exit status and everything it wrote."""

    returncode: int
    stdout: str
    stderr: str


def stop_process(process: subprocess.Popen, sig: int = signal.SIGINT,
                 timeout_s: float = 10.0) -> ProcessResult:
    """
    Send ``sig``, wait up to ``timeout_s`` for the exit, kill as a last resort.

    Returns the exit status and the output read from pipes ('' for output
    that went elsewhere). A KeyboardInterrupt while waiting (a second Ctrl-C)
    kills the process at once.
    """
    if process.poll() is None:
        process.send_signal(sig)
    try:
        out, err = process.communicate(timeout=timeout_s)
    except (subprocess.TimeoutExpired, KeyboardInterrupt):
        process.kill()
        out, err = process.communicate()
    return ProcessResult(process.returncode, out or '', err or '')


class ChildProcess:
    """
    A child process whose stdout and stderr go to files (temporary unless ``log_path``).

    ``merge_output`` sends stderr to the stdout file, in the order written.
    :meth:`start` runs it, :meth:`exited` and :meth:`log_tail` watch it,
    :meth:`stop` ends it and returns a :class:`ProcessResult` (the same one on
    later calls). Use it as a context manager to stop it on the way out.

    ``env`` (default: this process's) gets ``R2D2_SIM_PARENT_PID``, this
    process's id: ``sim_node`` ends when this process does, however it dies.
    ``pass_fds`` are descriptors the child inherits (only those): a domain
    lease's :attr:`~r2d2_sim.testing.domains.DomainLease.fds` keep the
    domain leased for as long as the child runs.
    """

    def __init__(self, command: Sequence[str], env: Optional[Mapping[str, str]] = None, *,
                 cwd: Optional[str] = None, log_path: Optional[str] = None,
                 merge_output: bool = False, pass_fds: Sequence[int] = ()) -> None:
        self.command = list(command)
        self.env = None if env is None else dict(env)
        self.cwd = cwd
        self.log_path = log_path
        self.merge_output = merge_output or log_path is not None
        self.pass_fds = tuple(pass_fds)
        self.process: Optional[subprocess.Popen] = None
        self.result: Optional[ProcessResult] = None
        self._files: Tuple[Optional[IO[str]], Optional[IO[str]]] = (None, None)  # from start()

    def start(self) -> 'ChildProcess':
        """Start the process; return self."""
        if self.log_path is not None:
            out = open(self.log_path, 'w+', encoding='utf-8', errors='replace')
        else:
            out = tempfile.TemporaryFile('w+', encoding='utf-8', errors='replace')
        err = None if self.merge_output else tempfile.TemporaryFile(
            'w+', encoding='utf-8', errors='replace')
        self._files = (out, err)
        env = dict(os.environ if self.env is None else self.env)
        env[PARENT_PID_ENV] = str(os.getpid())
        self.process = subprocess.Popen(
            self.command, env=env, cwd=self.cwd, stdin=subprocess.DEVNULL, stdout=out,
            stderr=subprocess.STDOUT if err is None else err, pass_fds=self.pass_fds)
        return self

    @property
    def pid(self) -> Optional[int]:
        """Return the process id (None before start)."""
        return None if self.process is None else self.process.pid

    @property
    def returncode(self) -> Optional[int]:
        """Return the exit status once it has exited, else None."""
        return None if self.process is None else self.process.poll()

    def poll(self) -> Optional[int]:
        """Return the exit status once it has exited, else None (as ``Popen.poll``)."""
        return self.returncode

    def send_signal(self, sig: int) -> None:
        """Send ``sig`` to the process if it still runs."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(sig)

    def exited(self) -> bool:
        """Return True once the process has ended."""
        return self.process is not None and self.process.poll() is not None

    def output(self) -> Tuple[str, str]:
        """Return (stdout, stderr) written so far (stderr '' when merged into stdout)."""
        if self.result is not None:
            return self.result.stdout, self.result.stderr
        texts = []
        for handle in self._files:
            if handle is None or handle.closed:
                texts.append('')
                continue
            # Read at an offset (pread), never moving the file's: the child writes through
            # the same open file, so a seek here put its next lines over earlier ones
            # (a log polled while the child wrote lost lines; 5 of 5 runs in a test).
            fd = handle.fileno()
            data = os.pread(fd, os.fstat(fd).st_size, 0)
            texts.append(data.decode('utf-8', errors='replace'))
        return texts[0], texts[1]

    def log_tail(self, lines: int = 10) -> List[str]:
        """Return the last non-empty lines the process wrote (stderr after stdout)."""
        stdout, stderr = self.output()
        text = stdout + ('\n' + stderr if stderr else '')
        return [line for line in text.splitlines() if line.strip()][-lines:]

    def failure_message(self, what: str, lines: int = 10) -> str:
        """Return a readable error: ``what``, the exit status if any, and the output tail."""
        code = self.returncode
        if code is not None:
            what += f' (it exited with status {code})'
        tail = self.log_tail(lines)
        if tail:
            name = self.command[2] if self.command[1:2] == ['-m'] else self.command[0]
            what += ':\n' + '\n'.join(f'  {name}: {line}' for line in tail)
        return what

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 10.0) -> ProcessResult:
        """Send ``sig``, wait up to ``timeout_s``, kill as a last resort; return how it ended."""
        if self.result is not None:
            return self.result
        code = -1
        if self.process is not None:
            code = stop_process(self.process, sig, timeout_s).returncode
        stdout, stderr = self.output()
        for handle in self._files:
            if handle is not None:
                handle.close()
        self.result = ProcessResult(code, stdout, stderr)
        return self.result

    def __enter__(self) -> 'ChildProcess':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.stop()


def sim_node_command(parameters: Optional[Mapping[str, Any]] = None,
                     ros_args: Sequence[str] = (),
                     command: Optional[Sequence[str]] = None) -> List[str]:
    """
    Return the command line that runs the simulator with these parameters.

    ``command`` defaults to this interpreter's ``-m r2d2_sim`` (the same code
    as ``sim_node``). Values are written with :func:`r2d2_sim.client.ros_arg`:
    strings stay strings, lists stay lists. A value of None is left out: the
    node keeps its default (written, YAML's ``null`` reached the node as the
    text "null": ``record=None`` recorded into a file named null).
    """
    args = list(command or [sys.executable, '-m', 'r2d2_sim'])
    ros = []
    for name, value in (parameters or {}).items():
        if value is not None:
            ros += ['-p', f'{name}:={ros_arg(value)}']
    ros += list(ros_args)
    return args + (['--ros-args'] + ros if ros else [])


class RosArgs(NamedTuple):
    """What a ``--ros-args`` list says about a node's name, namespace and topic remaps."""

    node_name: Optional[str]      # from -r __node:=name
    namespace: Optional[str]      # from -r __ns:=/ns
    remaps: Tuple[str, ...]       # the other remap rules, as 'from:=to'


def parse_ros_args(ros_args: Sequence[str], node_name: str) -> RosArgs:
    """
    Read the remap rules (``-r``/``--remap``) of ``ros_args`` that apply to node ``node_name``.

    Rules prefixed with another node's name (``other:from:=to``) are left
    out; a prefix of ``node_name`` is dropped. A client that talks to the
    node (:class:`~r2d2_sim.testing.sim_process.SimProcess`) applies the
    topic remaps to itself, so a ``/clock:=/a/clock`` reaches both sides.
    """
    name = namespace = None
    remaps = []
    args = list(ros_args)
    for i, arg in enumerate(args[:-1]):
        if arg not in ('-r', '--remap'):
            continue
        rule = args[i + 1]
        target, _, rest = rule.partition(':')
        if rest and not rest.startswith('=') and ':=' in rest:
            if target not in (node_name, name):
                continue
            rule = rest
        source, _, value = rule.partition(':=')
        if source == '__node':
            name = value
        elif source == '__ns':
            namespace = value
        elif not source.startswith('__'):
            remaps.append(rule)
    return RosArgs(name, namespace, tuple(remaps))
