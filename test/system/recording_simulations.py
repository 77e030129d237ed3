"""The two simulations, each recording the followed robot's pose after every playing tick."""

from r2d2_sim.osc import R2D2Simulation, StandardSimulation

# Each side's last run: (time s, position, orientation) after each tick that stepped.
POSES = {'in_process': [], 'over_ros': []}


class RecordingInProcess(R2D2Simulation):
    """R2D2Simulation that records the robot's pose after each period it steps."""

    def start(self, values):
        POSES['in_process'] = []
        super().start(values)

    def step(self):
        super().step()
        if self.simulation is not None and self.playing:
            state = self.simulation.entities.body(self.settings.robot).world_state()
            POSES['in_process'].append(
                (self.time_s, tuple(state.position), tuple(state.orientation)))


class RecordingOverRos(StandardSimulation):
    """StandardSimulation that records the robot's pose (GetEntityState) after each period."""

    def start(self, values):
        POSES['over_ros'] = []
        super().start(values)

    def step(self):
        super().step()
        if self.client is not None and not self.error and self.playing:
            position, orientation = self.pose(self.settings.robot)
            POSES['over_ros'].append((self.time_s, tuple(position), tuple(orientation)))
