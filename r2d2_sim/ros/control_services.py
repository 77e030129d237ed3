"""
The simulator's own control services: ``~/pause``, ``~/step``, ``~/reset``, ``~/get_status``.

std_srvs types, so any ROS tool can call them; each replies with the
simulation's state as JSON in ``message`` (:meth:`ControlServices.status`),
for programs to parse. The operations are the node's (pause landing on a
publication, a step of one control period, a reset of the robots' state);
this module only answers, under the node's lock.
"""

import json

from std_srvs.srv import SetBool, Trigger

__all__ = ['ControlServices']


class ControlServices:
    """The control services of ``node`` (a :class:`~r2d2_sim.ros.node.SimNode`), on that node."""

    def __init__(self, node) -> None:
        self._node = node
        node.create_service(SetBool, '~/pause', self._on_pause)
        node.create_service(Trigger, '~/step', self._on_step)
        node.create_service(Trigger, '~/reset', self._on_reset)
        node.create_service(Trigger, '~/get_status', self._on_get_status)

    def status(self, **facts) -> str:
        """
        Return the simulation's state as the JSON text the control services reply with.

        Keys: ``paused``, ``step`` (physics steps since start), ``sim_time_ns``
        and ``sim_time`` (s) of the last step, ``commands_received`` (cmd_vel
        messages taken so far by all robots, so a client can confirm its
        command arrived), ``robots`` (each robot's ``namespace``, ``tf`` topic
        and ``commands_received``, by name), plus the service's own ``facts``
        (``steps`` advanced, an ``error``).
        """
        node = self._node
        ns = node.sim_time_ns
        state = {'paused': node.paused, 'step': node.step_count, 'sim_time_ns': ns,
                 'sim_time': ns / 1e9, 'commands_received': node.commands_received,
                 'robots': {i.name: {'namespace': i.namespace, 'tf': i.tf_topics[0],
                                     'commands_received': i.cmd_vel.received}
                            for i in node.robots}}
        state.update(facts)
        return json.dumps(state)

    def _on_pause(self, request, response):
        with self._node.lock:  # the reply's time is the state the pause landed on
            self._node.set_paused(request.data)
            response.message = self.status()
        response.success = True
        return response

    def _on_step(self, request, response):
        node = self._node
        with node.lock:
            if not node.paused:
                response.success = False
                response.message = self.status(
                    steps=0, error='the simulation is running: pause it (~/pause true) to step')
                return response
            steps = node.advance_to_next_publish()
            response.message = self.status(steps=steps)
        response.success = True
        return response

    def _on_get_status(self, request, response):
        with self._node.lock:
            response.message = self.status()
        response.success = True
        return response

    def _on_reset(self, request, response):
        with self._node.lock:
            self._node.reset_simulation()  # the robots; time goes on, spawned entities stay
            response.message = self.status()
        response.success = True
        return response
