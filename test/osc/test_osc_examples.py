"""
The scenarios of docs/scenarios.md, run as written: ``scenario_execution --simulation ...``.

Each example is a file of ``test/examples/osc/``, shown byte for byte on the page, and
run here by the scenario_execution command itself (pip only: in process, no ROS),
whose JUnit file gives the verdict. The command finds osc.r2d2 through its entry
points (a shim for this source tree, ``common.osc_env``).
"""

from pathlib import Path
import re

import pytest

from common import OSC_EXAMPLES, osc_env, REPO, scenario_execution

PAGE = Path(REPO) / 'docs' / 'scenarios.md'
IN_PROCESS = 'r2d2_sim.osc:R2D2Simulation'


def test_the_page_shows_the_example_files_byte_for_byte():
    """Every text and yaml block of docs/scenarios.md naming a file is that file."""
    text = PAGE.read_text(encoding='utf-8')
    shown = re.findall(r'^```(?:text|yaml)\n# (\S+)\n(.*?)^```$', text, re.S | re.M)
    assert {name for name, _ in shown} == {p.name for p in OSC_EXAMPLES.iterdir()}
    for name, body in shown:
        assert f'# {name}\n{body}' == (OSC_EXAMPLES / name).read_text(encoding='utf-8'), name


@pytest.mark.parametrize('example', ['go_to_goal.osc', 'obstacle_stop.osc', 'crossing.osc'])
def test_each_example_passes(tmp_path, example):
    """The example's one scenario passes, and the command says so (exit status 0)."""
    status, output, cases = scenario_execution(
        ['--simulation', IN_PROCESS, OSC_EXAMPLES / example], osc_env(tmp_path / 'shim'),
        tmp_path)
    assert cases == {example[:-4]: None}, output[-3000:]
    assert status == 0 and 'Traceback' not in output


def test_the_crossing_variations_give_one_verdict_each(tmp_path):
    """Its parameter file, two documents: r2 at 0.25 m/s passes, at 0.6 m/s comes too near."""
    status, output, cases = scenario_execution(
        ['--simulation', IN_PROCESS, '--scenario-parameter-file',
         OSC_EXAMPLES / 'crossing_speeds.yaml', OSC_EXAMPLES / 'crossing.osc'],
        osc_env(tmp_path / 'shim'), tmp_path)
    assert list(cases) == ['crossing-0', 'crossing-1'], output[-3000:]
    assert cases['crossing-0'] is None and cases['crossing-1'] == 'execution failed.'
    assert 'r2d2 came within 0.3 m of r2' in output and status == 1
