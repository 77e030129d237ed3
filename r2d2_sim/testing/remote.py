"""
A ROS node in a context of its own, spun in the caller's thread: :class:`RemoteProbe`.

For talking to a simulator in another process: its subscriptions, publishers
and service clients are the caller's, and every wait has a deadline.
"""

import os
import time
from typing import Any, Callable, Optional, Sequence, Type

import rclpy
from rclpy.client import Client
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from r2d2_sim.client import spin_until
from r2d2_sim.testing.executor import HarnessError

__all__ = ['RemoteProbe', 'send_request', 'ask_until', 'Wait']

# How a caller waits: spin until condition() holds (True) or timeout_s passes (False).
Wait = Callable[[Callable[[], bool], float], bool]


def send_request(client: Client, request: Any, wait: Wait, timeout_s: float,
                 resend_after_s: Optional[float] = None,
                 abort: Optional[Callable[[], bool]] = None) -> Any:
    """
    Send ``request`` through ``client``; return the reply (None: the deadline, or ``abort()``).

    ``wait`` spins the client's executor (``RemoteProbe.spin_until``).
    ``resend_after_s``, for idempotent requests only: send the request
    again if no reply came in that long. A reply can be lost for good:
    rmw_fastrtps drops it when, 100 ms after the request came in, the
    server has still not discovered the client's reply reader, which a
    busy machine does (seen once with one core kept busy beside the test
    suite). A late reply to an earlier send is dropped.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        future = client.call_async(request)
        wait_s = deadline - time.monotonic()
        if resend_after_s is not None:
            wait_s = min(wait_s, resend_after_s)
        wait(lambda: future.done() or (abort is not None and abort()), max(wait_s, 0.0))
        if future.done():
            return future.result()
        client.remove_pending_request(future)
        if (abort is not None and abort()) or time.monotonic() >= deadline:
            return None


def ask_until(answered: Callable[[], bool], wait: Wait, timeout_s: float,
              pause_s: float = 0.002) -> bool:
    """
    Ask ``answered()`` until it holds; False once ``timeout_s`` has passed.

    For a question the simulator answers through a service (its counts of
    commands or readers): ``answered`` calls it, so it cannot be a condition
    ``wait`` checks while it spins. Between questions ``wait`` spins the
    caller's executor for ``pause_s``.
    """
    deadline = time.monotonic() + timeout_s
    while not answered():
        if time.monotonic() > deadline:
            return False
        wait(lambda: False, pause_s)
    return True


class RemoteProbe:
    """
    A node in a context of its own on ``domain_id``, spun in the caller's thread.

    For talking to a simulator in another process: create subscriptions,
    publishers and clients on :attr:`node`, then :meth:`spin_until` a
    condition holds. ``ros_args`` (e.g. ``['-r', '/clock:=/a/clock']``) remap
    this side's names too. Close it when done (or use it as a context manager).
    """

    def __init__(self, domain_id: int, name: str = 'remote_probe', *,
                 namespace: Optional[str] = None, ros_args: Sequence[str] = ()) -> None:
        os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.domain_id = domain_id
        self.context = Context()
        # ros_args (remap rules) apply to every node of this context.
        args = ['--ros-args', *ros_args] if ros_args else None
        rclpy.init(args=args, context=self.context, domain_id=domain_id)
        try:
            self.node = Node(name, context=self.context, namespace=namespace)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        except BaseException:
            rclpy.try_shutdown(context=self.context)
            raise

    def spin_until(self, condition: Callable[[], bool], timeout_s: float) -> bool:
        """Spin until ``condition()`` holds (True) or the deadline passes (False)."""
        return spin_until(self.executor, condition, timeout_s)

    def call(self, srv_type: Type, name: str, request: Any, timeout_s: float = 10.0,
             resend_after_s: Optional[float] = None) -> Any:
        """
        Call service ``name`` and return its response; HarnessError at the deadline.

        ``resend_after_s``: see :meth:`call_client` (idempotent services only).
        """
        client = self.node.create_client(srv_type, name)
        try:
            if not self.spin_until(client.service_is_ready, timeout_s):
                raise HarnessError(f'service {name} is not available')
            response = self.call_client(client, request, timeout_s, resend_after_s)
            if response is None:
                raise HarnessError(f'{name} did not answer within {timeout_s:g} s')
            return response
        finally:
            self.node.destroy_client(client)

    def call_client(self, client: Client, request: Any, timeout_s: float,
                    resend_after_s: Optional[float] = None,
                    abort: Optional[Callable[[], bool]] = None) -> Any:
        """Send ``request`` through ``client`` and spin for the reply: :func:`send_request`."""
        return send_request(client, request, self.spin_until, timeout_s, resend_after_s, abort)

    def close(self) -> None:
        """Shut the executor down, destroy the node, shut the context down; safe twice."""
        if self.context.ok():
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
            rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> 'RemoteProbe':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()
