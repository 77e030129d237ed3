"""
The simulator's own control services: ``~/pause``, ``~/step``, ``~/reset``, ``~/get_status``.

And ``~/get_readers``: how many readers each of its writers matched.

std_srvs types, so any ROS tool can call them; each replies with the
simulation's state as JSON in ``message`` (:meth:`ControlServices.status`),
for programs to parse. The operations are the node's (pause landing on a
publication, a step of one control period, a reset of the robots' state);
this module only answers, under the node's lock.
"""

import json
from typing import Any, Dict, Optional

from std_srvs.srv import SetBool, Trigger

from r2d2_sim.errors import RefusedError
from r2d2_sim.ros.fleet import Fleet
from r2d2_sim.ros.mirror import MirroringNode
from r2d2_sim.ros.seams import SimulatorControl

__all__ = ['ControlServices']


class ControlServices:
    """
    The control services of ``simulator`` on ``server`` (the simulator's own node).

    ``fleet`` gives each robot's ``cmd_vel`` counts and where its topics are,
    for the status.
    """

    def __init__(self, simulator: SimulatorControl, server: MirroringNode,
                 fleet: Fleet) -> None:
        self._simulator = simulator
        self._fleet = fleet
        self._server = server
        server.create_service(SetBool, '~/pause', self._on_pause)
        server.create_service(Trigger, '~/step', self._on_step)
        server.create_service(Trigger, '~/reset', self._on_reset)
        server.create_service(Trigger, '~/get_status', self._on_get_status)
        server.create_service(Trigger, '~/get_readers', self._on_get_readers)

    def status(self, **facts: Any) -> str:
        """
        Return the simulation's state as the JSON text the control services reply with.

        Keys: ``paused``, ``step`` (physics steps since start), ``sim_time_ns``
        and ``sim_time`` (s) of the last step, ``published_ns`` (the stamp of
        the latest state publication), ``commands_received`` (cmd_vel
        messages taken so far by all robots, so a client can confirm its
        command arrived), ``robots`` (each robot's ``namespace``, ``tf`` topic
        and ``commands_received``, by name), with ``outputs_process`` its
        ``outputs`` (``running``: the child alive and taking frames, ``frames``
        sent, ``publishers`` held), with a live view or a recording
        ``live_view`` (its address) and ``recording`` (the file), plus the
        service's own ``facts`` (``steps`` advanced, an ``error``).
        """
        simulator, fleet = self._simulator, self._fleet
        ns = simulator.sim_time_ns
        state = {'paused': simulator.paused, 'step': simulator.step_count, 'sim_time_ns': ns,
                 'sim_time': ns / 1e9, 'published_ns': simulator.last_publication_ns,
                 'commands_received': fleet.received,
                 'robots': {i.name: {'namespace': i.namespace, 'tf': i.tf_topics[0],
                                     'commands_received': i.cmd_vel.received}
                            for i in fleet}}
        relay = self._server.relay
        if relay is not None:
            frames, publishers = relay.describe()
            state['outputs'] = {'running': relay.running, 'frames': frames,
                                'publishers': publishers}
        state.update(self._server.sink_status())
        state.update(facts)
        return json.dumps(state)

    def readers(self) -> Dict[str, int]:
        """
        Return, for each topic the simulator publishes, the readers its writers there match.

        The fewest any of its writers of that topic (one per robot on a shared
        ``/tf``) has matched. A client that just subscribed waits until this
        counts its reader: a message published before the writer matched it
        never reaches it, and with outputs built on demand a writer that counts
        no reader builds nothing. 0.2 us a writer.
        """
        nodes = {id(node): node for node in [self._server] + [i.node for i in self._fleet]}
        counts: Dict[str, int] = {}
        for node in nodes.values():
            for publisher in node.all_publishers():  # relayed ones too (outputs_process)
                count = publisher.get_subscription_count()
                topic = publisher.topic_name
                counts[topic] = min(counts.get(topic, count), count)
        return counts

    def _on_pause(self, request: SetBool.Request,
                  response: SetBool.Response) -> SetBool.Response:
        with self._simulator.lock:  # the reply's time is the state the pause landed on
            try:
                self._simulator.set_paused(request.data)
            except RefusedError as exc:  # resuming with no world loaded
                response.success = False
                response.message = self.status(error=exc.message)
                return response
            response.message = self.status()
        response.success = True
        return response

    def _no_world(self, response: Trigger.Response,
                  **facts: Any) -> Optional[Trigger.Response]:
        """Answer a request that needs a world while none is loaded; None when one is."""
        if self._simulator.world_is_loaded:
            return None
        response.success = False
        response.message = self.status(error='no world is loaded (UnloadWorld): load one '
                                             '(LoadWorld) first', **facts)
        return response

    def _on_step(self, request: Trigger.Request,
                 response: Trigger.Response) -> Trigger.Response:
        simulator = self._simulator
        with simulator.lock:
            if self._no_world(response, steps=0) is not None:
                return response
            if not simulator.paused:
                response.success = False
                response.message = self.status(
                    steps=0, error='the simulation is running: pause it (~/pause true) to step')
                return response
            steps = simulator.advance_to_next_publish()
            response.message = self.status(steps=steps)
        response.success = True
        return response

    def _on_get_status(self, request: Trigger.Request,
                       response: Trigger.Response) -> Trigger.Response:
        with self._simulator.lock:
            response.message = self.status()
        response.success = True
        return response

    def _on_get_readers(self, request: Trigger.Request,
                        response: Trigger.Response) -> Trigger.Response:
        with self._simulator.lock:  # the robots' nodes come and go under it
            response.message = json.dumps(self.readers())
        response.success = True
        return response

    def _on_reset(self, request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        with self._simulator.lock:
            if self._no_world(response) is not None:
                return response
            self._simulator.reset_simulation()  # the robots; time goes on, spawned entities stay
            response.message = self.status()
        response.success = True
        return response
