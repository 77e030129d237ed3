"""
The same noise_seed gives the same noisy readings, bit for bit, in another process.

Python salts ``hash`` per process, and a seed derived from it would repeat
only within one: the noise streams are seeded from the seed, the robot's name
(CRC-32) and the sensor. Two robots run one second with every sensor's noise
on (laser, IMU, wheel encoders, depth) in two fresh interpreters and in this
one; the digests of everything they read must be equal, and another seed
must give another digest.
"""

import os
import subprocess
import sys

from common import REPO

READINGS = '''
import hashlib, sys
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation

NOISE = {
    'robots': ['a', 'b'], 'b.initial_pose': [0.0, 1.0, 0.0],
    'world': 'package://r2d2_sim/urdf/room.urdf',
    'scan_noise_std': 0.01, 'scan_noise_bias_std': 0.01, 'scan_noise_precision': 0.001,
    'scan_noise_dynamic_bias_std': 0.01, 'scan_noise_dynamic_bias_correlation_time': 10.0,
    'imu_angular_velocity_noise_std': 0.01, 'imu_angular_velocity_noise_bias_std': 0.01,
    'imu_linear_acceleration_noise_std': 0.1, 'imu_orientation_noise_std': 0.01,
    'encoder_noise_std': 0.02, 'encoder_noise_bias_std': 0.01, 'encoder_noise_precision': 0.002,
    'encoder_noise_dynamic_bias_std': 0.01, 'encoder_noise_dynamic_bias_correlation_time': 60.0,
    'camera_rate': 24.0, 'camera_depth': True, 'camera_width': 16, 'camera_height': 12,
    'depth_noise_std': 0.01, 'depth_noise_bias_std': 0.01, 'cmd_vel_timeout': 0.0,
}


def digest(seed):
    config, robots = parse_world(dict(NOISE, noise_seed=seed))
    simulation = Simulation(config, robots)
    try:
        for robot in simulation.robots:
            robot.command(0.3, 0.4)
        sha = hashlib.sha256()
        for _ in range(240):
            result = simulation.step()
            if result is None:
                continue
            for m in result.measurements:
                if m.scan is not None:
                    sha.update(m.scan.tobytes())
                if m.image is not None:
                    sha.update(m.image.depth.tobytes())
                sha.update(repr((m.imu, None if m.frame is None else m.frame.odometry)).encode())
        return sha.hexdigest()
    finally:
        simulation.close()


if __name__ == '__main__':
    print(digest(int(sys.argv[1])))
'''


def digest_in_a_new_process(tmp_path, seed):
    script = tmp_path / 'readings.py'
    script.write_text(READINGS)
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get('PYTHONPATH', ''))
    result = subprocess.run([sys.executable, str(script), str(seed)], capture_output=True,
                            text=True, env=env, cwd=tmp_path, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout.strip()


def test_the_same_seed_repeats_every_noisy_reading_across_processes(tmp_path):
    namespace = {'__name__': 'readings'}
    exec(compile(READINGS, 'readings.py', 'exec'), namespace)
    here = namespace['digest'](11)
    first, second = (digest_in_a_new_process(tmp_path, 11) for _ in range(2))
    assert first == second == here
    assert digest_in_a_new_process(tmp_path, 12) != here
