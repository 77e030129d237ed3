"""
The runner's shrinking: a drawn scenario written as the Hypothesis strategy's choices.

``choices_of(space, space.draw(seed))`` must replay, through
``scenarios(space)``, as the very scenario drawn, whatever the space's box
count: a list of a fixed size draws no continue flags in Hypothesis's
``st.lists``, and boxes ``draw`` left out must be drawn as boxes the strategy
leaves out too. A scenario the choices cannot express is said so, and nothing
runs. No physics runs here.
"""

import dataclasses

import pytest

from r2d2_sim.farm import shrink
from r2d2_sim.farm.job import FarmJob, Item
from r2d2_sim.farm.scenario import ROOM, ScenarioSpace
from r2d2_sim.farm.shrink import choices_of, replay, shrink_failure

DEFAULT = ScenarioSpace()
# Boxes crowd the start: draw() leaves most of them out, below the space's fewest.
CROWDED = ScenarioSpace(obstacles=(2, 4), area=(0.0, -0.3, 0.6, 0.3))
SPACES = {
    '(0, 5)': DEFAULT, '(3, 3)': dataclasses.replace(DEFAULT, obstacles=(3, 3)),
    '(0, 0)': dataclasses.replace(DEFAULT, obstacles=(0, 0)), '(2, 4) crowded': CROWDED,
    'room, limits, noise': ScenarioSpace(world=ROOM, obstacles=(1, 3),
                                         limits=(('max_linear_velocity', (0.2, 0.5)),),
                                         scan_noise_std=(0.0, 0.02)),
}


@pytest.mark.parametrize('name', list(SPACES))
def test_a_drawn_scenario_replays_from_its_choices_as_drawn(name):
    """Seeds 0..19 of each space: the strategy draws the same scenario from the choices."""
    space = SPACES[name]
    for seed in range(20):
        drawn = space.draw(seed)
        assert replay(space, choices_of(space, drawn)) == drawn, (name, seed)


def test_the_crowded_space_has_scenarios_below_its_fewest_boxes():
    """What the round trip above covers: draw() left boxes out of some of them."""
    assert any(len(CROWDED.draw(seed).obstacles) < 2 for seed in range(20))


def test_a_scenario_the_choices_cannot_express_is_said_so_and_nothing_runs(
        monkeypatch, tmp_path):
    """Choices that replay as another scenario: 'could not express', not the wall clock."""
    ran = []
    job = FarmJob(DEFAULT, lambda harness, scenario: ran.append(scenario), seconds=1.0)
    monkeypatch.setattr(shrink, 'choices_of',
                        lambda space, scenario: choices_of(space, space.draw(scenario.seed + 1)))
    result = shrink_failure(job, Item(4, 4), tmp_path, max_shrinks=2)
    assert result['shrunk'] is None and result['runs'] == 0 and not ran
    assert result['summary'].startswith('seed 4: could not express the scenario as the choices '
                                        'of the Hypothesis strategy'), result['summary']
