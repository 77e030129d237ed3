"""
Gazebo's noise model (r2d2_sim.model.noise), each parameter checked by its statistics.

Every check draws at least 10,000 values from a seeded generator, so each is
deterministic, and the tolerances (2 % for means and spreads) are several
standard errors wide: mean and sigma within 2 %, the constant bias's sign
both ways over seeds (and its size from its own draws), rounding exact, the
dynamic bias's correlation time from its autocorrelation and its settled
spread from the formula.
"""

import math

import numpy
import pytest

from r2d2_sim.model.noise import (
    noise_generator, NoiseConfigError, NoiseModel, NoiseSpec, quantize)

SAMPLES = 40_000


def rng(seed=0):
    return numpy.random.default_rng(seed)


def test_white_noise_mean_and_sigma_within_two_percent():
    model = NoiseModel(NoiseSpec(mean=0.5, stddev=0.1), rng(1))
    values = model.apply(numpy.full(SAMPLES, 3.0)) - 3.0
    assert values.mean() == pytest.approx(0.5, rel=0.02)
    assert values.std() == pytest.approx(0.1, rel=0.02)


def test_a_mean_alone_is_added_exactly_without_a_draw():
    generator = rng(2)
    state = generator.bit_generator.state
    values = NoiseModel(NoiseSpec(mean=0.25), generator).apply(numpy.zeros(SAMPLES))
    assert numpy.all(values == 0.25)
    assert generator.bit_generator.state == state


@pytest.mark.slow
def test_the_constant_bias_takes_both_signs_over_seeds_and_keeps_its_size():
    """|bias| ~ |N(bias_mean, bias_std)|; its sign is flipped with probability 0.5."""
    spec = NoiseSpec(bias_mean=1.0, bias_stddev=0.05)
    biases = numpy.array([NoiseModel(spec, rng(seed)).bias[0] for seed in range(SAMPLES // 4)])
    positive = numpy.mean(biases > 0.0)
    assert 0.48 < positive < 0.52  # 10,000 seeds: 1.6 standard errors of 0.5 each side
    assert numpy.abs(biases).mean() == pytest.approx(1.0, rel=0.02)
    assert numpy.abs(biases).std() == pytest.approx(0.05, rel=0.02)


def test_the_constant_bias_is_drawn_once_and_added_to_every_value():
    model = NoiseModel(NoiseSpec(bias_mean=0.3, stddev=0.01), rng(5))
    first = model.apply(numpy.zeros(SAMPLES))
    second = model.apply(numpy.zeros(SAMPLES))
    for values in (first, second):
        assert values.mean() == pytest.approx(model.bias[0], rel=0.02)
        assert values.std() == pytest.approx(0.01, rel=0.02)
    assert abs(model.bias[0]) == pytest.approx(0.3)


def test_each_channel_draws_its_own_bias():
    model = NoiseModel(NoiseSpec(bias_mean=1.0), rng(7), channels=3)
    signs = {tuple(numpy.sign(NoiseModel(NoiseSpec(bias_mean=1.0), rng(seed), channels=3).bias))
             for seed in range(40)}
    assert len(signs) > 4  # axes flip independently
    values = model.apply(numpy.zeros((SAMPLES, 3)))
    assert numpy.array_equal(values[0], model.bias)


def test_rounding_is_exact_to_the_precision():
    """Each value is the multiple of the precision nearest to the unrounded one."""
    inputs = numpy.linspace(-5.0, 5.0, SAMPLES)
    rounded = NoiseModel(NoiseSpec(stddev=0.3, precision=0.05), rng(3)).apply(inputs)
    unrounded = NoiseModel(NoiseSpec(stddev=0.3), rng(3)).apply(inputs)
    multiples = numpy.round(unrounded / 0.05)
    assert numpy.array_equal(rounded, multiples * 0.05)
    assert numpy.all(numpy.abs(rounded - unrounded) <= 0.025 + 1e-12)
    assert len(numpy.unique(rounded)) > 100


def test_rounding_goes_half_away_from_zero_as_std_round():
    assert list(quantize(numpy.array([0.25, -0.25, 0.75, 0.2, -0.2]), 0.5)) == \
        [0.5, -0.5, 1.0, 0.0, -0.0]
    assert quantize(1.234, 0.0) == 1.234


def gauss_markov(sigma, tau_s, dt_s, samples, seed):
    model = NoiseModel(NoiseSpec(dynamic_bias_stddev=sigma,
                                 dynamic_bias_correlation_time_s=tau_s), rng(seed), period_s=dt_s)
    values = numpy.empty(samples)
    for i in range(samples):
        model.step_dynamic_bias(dt_s)
        values[i] = model.dynamic_bias[0]
    return values


def autocorrelation(values, lags):
    centred = values - values.mean()
    variance = numpy.dot(centred, centred) / len(values)
    return numpy.array([numpy.dot(centred[:-lag], centred[lag:]) / len(values) / variance
                        for lag in lags])


@pytest.mark.slow
def test_the_dynamic_bias_has_its_correlation_time_and_settled_spread():
    """rho(lag) = exp(-lag dt / tau): tau fitted over lags up to tau, and sigma sqrt(tau/2)."""
    sigma, tau_s, dt_s = 0.2, 0.5, 0.01
    values = gauss_markov(sigma, tau_s, dt_s, 400_000, seed=11)
    lags = numpy.arange(1, 51)
    rho = autocorrelation(values, lags)
    slope = numpy.polyfit(lags * dt_s, numpy.log(rho), 1)[0]
    assert -1.0 / slope == pytest.approx(tau_s, rel=0.05)
    assert values.std() == pytest.approx(sigma * math.sqrt(tau_s / 2.0), rel=0.03)
    assert NoiseSpec(dynamic_bias_stddev=sigma, dynamic_bias_correlation_time_s=tau_s) \
        .dynamic_bias_steady_stddev == pytest.approx(sigma * math.sqrt(tau_s / 2.0))


@pytest.mark.slow
def test_the_dynamic_bias_walks_as_sigma_sqrt_t_while_t_is_short_of_tau():
    """From 0, over t << tau the bias spreads as a random walk of density sigma."""
    sigma, tau_s, dt_s, steps = 0.1, 3600.0, 0.01, 100
    ends = numpy.array([gauss_markov(sigma, tau_s, dt_s, steps, seed)[-1]
                        for seed in range(10_000)])
    assert ends.std() == pytest.approx(sigma * math.sqrt(steps * dt_s), rel=0.03)
    assert abs(ends.mean()) < 3 * sigma / 100


def test_the_dynamic_bias_steps_once_per_application_by_the_period():
    spec = NoiseSpec(dynamic_bias_stddev=0.1, dynamic_bias_correlation_time_s=1.0)
    model = NoiseModel(spec, rng(4), period_s=0.1)
    again = NoiseModel(spec, rng(4), period_s=0.1)
    model.apply(numpy.zeros(5))
    again.step_dynamic_bias(0.1)
    assert model.dynamic_bias[0] == again.dynamic_bias[0] != 0.0


def test_an_exact_spec_changes_and_draws_nothing():
    generator = rng(9)
    state = generator.bit_generator.state
    values = numpy.arange(5.0)
    assert NoiseModel(NoiseSpec(), generator).apply(values) is values
    assert generator.bit_generator.state == state
    assert NoiseModel(NoiseSpec(), None).exact


def test_the_variance_is_the_mean_square_error_of_all_parts():
    spec = NoiseSpec(mean=0.1, stddev=0.2, bias_mean=0.3, bias_stddev=0.05,
                     dynamic_bias_stddev=0.01, dynamic_bias_correlation_time_s=100.0,
                     precision=0.06)
    assert spec.variance == pytest.approx(0.01 + 0.04 + 0.09 + 0.0025 + 0.01 ** 2 * 50.0
                                          + 0.06 ** 2 / 12.0)
    # Over seeds, a model without drift errs by that much on average (the bias over seeds).
    spec = NoiseSpec(mean=0.1, stddev=0.2, bias_mean=0.3, bias_stddev=0.05)
    errors = numpy.concatenate([NoiseModel(spec, rng(seed)).apply(numpy.zeros(4))
                                for seed in range(SAMPLES // 4)])
    assert numpy.mean(errors ** 2) == pytest.approx(spec.variance, rel=0.03)


@pytest.mark.parametrize('field, value, message', [
    ('stddev', -0.1, 'stddev must be >= 0'),
    ('bias_stddev', float('nan'), 'bias_stddev must be a finite number'),
    ('precision', -1.0, 'precision must be >= 0'),
    ('mean', True, 'mean must be a finite number'),
    ('dynamic_bias_correlation_time_s', float('inf'), 'must be a finite number'),
])
def test_bad_specs_are_refused_in_one_line(field, value, message):
    with pytest.raises(NoiseConfigError, match=message) as info:
        NoiseSpec(**{field: value})
    assert '\n' not in str(info.value)


def test_a_dynamic_bias_needs_its_correlation_time():
    with pytest.raises(NoiseConfigError, match='dynamic_bias_correlation_time_s'):
        NoiseSpec(dynamic_bias_stddev=0.1)


def test_noise_without_a_generator_is_refused():
    with pytest.raises(NoiseConfigError, match='rng'):
        NoiseModel(NoiseSpec(stddev=0.1), None)


def test_streams_differ_by_seed_robot_and_sensor_and_repeat():
    def first(*key):
        return noise_generator(*key).normal(size=4).tolist()
    assert first(1, 'r2d2', 'scan') == first(1, 'r2d2', 'scan')
    others = [first(2, 'r2d2', 'scan'), first(1, 'r2d2_1', 'scan'), first(1, 'r2d2', 'imu')]
    assert all(other != first(1, 'r2d2', 'scan') for other in others)
