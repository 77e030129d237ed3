"""
Farm runs pinned to the bit: verdicts, measures and recordings of fixed seeds against a reference.

The reference (``data/fingerprints.json``) was written by the tree before the
farm's per-core speed work (issue 36), so that any change that makes a run
faster must keep every verdict, every measure and every recorded byte: a
faster farm that judged differently would be a different farm. Each case
runs twice: as a farm runs it (nothing recorded; a failure recorded by its
rerun) and recording every output, and both give the same measures.

``R2D2_FARM_FINGERPRINTS=write`` writes the reference again instead of
checking it: only for a change that is meant to change what runs do.
"""

import hashlib
import importlib.util
import json
import os
from pathlib import Path

import pytest

from common import EXAMPLES
from r2d2_sim.farm.run import run_scenario, safe
from r2d2_sim.farm.scenario import Scenario

REFERENCE = Path(__file__).resolve().parent / 'data' / 'fingerprints.json'
WRITE_ENV = 'R2D2_FARM_FINGERPRINTS'
# docs/farm.md's example farm: seeds that reach the goal and seeds that stop before a box.
SEEDS = [0, 1, 2, 3, 4]
# A stopper that stops too late, 2 cm beside a box straight ahead (docs/farm.md's shrunk
# scenario): it touches the box, so the farm records its rerun.
LATE = ('{"format": 1, "goal": {"kind": "circle", "values": [2.5, 0.0, 0.3, 0.0]}, '
        '"limits": {}, "obstacles": [{"size": [0.3, 0.3, 0.5], "x": 0.9, "y": -0.02, '
        '"yaw": 0.0}], "scan_noise_std": 0.0, "seed": 0, "start": {"x": 0.0, "y": 0.0, '
        '"yaw": 0.0}, "world": ""}')


def example():
    """Return docs/farm.md's example module (not a test module of this suite)."""
    spec = importlib.util.spec_from_file_location(
        'stopper_farm_example', EXAMPLES / 'farm' / 'test_stopper_farm.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def sha256(data: bytes) -> str:
    """Return the SHA-256 of ``data`` in hex."""
    return hashlib.sha256(data).hexdigest()


def fingerprint(outcome) -> dict:
    """Return what must not change of a run: its verdict and a hash of its measures."""
    measures = json.dumps(outcome.measures(), sort_keys=True).encode()
    return {'passed': outcome.passed, 'reason': outcome.reason, 'steps': outcome.steps,
            'time_to_goal_s': outcome.time_to_goal_s, 'clearance_m': outcome.clearance_m,
            'measures_sha256': sha256(measures)}


def cases():
    """Return (name, scenario, controller) of every pinned case."""
    farm = example()

    def late_stopper(harness, scenario):
        harness.add_node(farm.GoalStopper(scenario.goal_point, stop_m=0.3,
                                          context=harness.context))
    pinned = [(f'stopper-{seed}', farm.SPACE.draw(seed), farm.goal_stopper) for seed in SEEDS]
    pinned.append(('late-stopper', Scenario.from_json(LATE), late_stopper))
    return farm.PARAMETERS, pinned


def measure(tmp_path) -> dict:
    """Run every case as the farm does and recording everything; return their fingerprints."""
    parameters, pinned = cases()
    found = {}
    for name, scenario, controller in pinned:
        farmed = run_scenario(scenario, controller, seconds=20.0, verdict=safe,
                              parameters=parameters,
                              record_failure=str(tmp_path / f'{name}-failure.mcap'))
        recording = tmp_path / f'{name}.mcap'
        recorded = run_scenario(scenario, controller, seconds=20.0, verdict=safe,
                                parameters=parameters, record=str(recording))
        entry = fingerprint(farmed)
        entry['recorded_measures_sha256'] = fingerprint(recorded)['measures_sha256']
        entry['recording_sha256'] = sha256(recording.read_bytes())
        if farmed.recording is not None:
            entry['failure_recording_sha256'] = sha256(Path(farmed.recording).read_bytes())
        found[name] = entry
    return found


def test_every_pinned_run_is_the_reference_to_the_bit(tmp_path):
    """Verdicts, measures (as farmed and as recorded) and recording hashes: the reference's."""
    found = measure(tmp_path)
    if os.environ.get(WRITE_ENV) == 'write':
        REFERENCE.write_text(json.dumps(found, indent=1, sort_keys=True) + '\n',
                             encoding='utf-8')
        pytest.skip(f'{REFERENCE.name} written')
    reference = json.loads(REFERENCE.read_text(encoding='utf-8'))
    assert sorted(found) == sorted(reference)
    for name, entry in found.items():
        assert entry == reference[name], name
    late = found['late-stopper']
    assert not late['passed'] and late['failure_recording_sha256'] == late['recording_sha256']
    assert any(e['passed'] and e['time_to_goal_s'] is None for e in found.values())
    assert any(e['time_to_goal_s'] is not None for e in found.values())
