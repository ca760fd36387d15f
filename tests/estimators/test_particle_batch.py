"""The particle cloud over a batch of runs (a host whose every input is a port, so that one batch
holds runs of every branch): a batch is its runs alone, bit for bit; a run's draws are its own
(statistics per run, independence between runs); a NaN run leaves the others' bits alone."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.estimators.particle_cloud import bytes_per_run
from drake_uuv.models.measurement import DROPPED
from drake_uuv.testing import after_update, assert_batch_equals_runs
from tests.estimators.cloud_host import (
    PORTS,
    CloudHost,
    read_states,
    run_inputs,
    run_states,
    set_states,
    state_parts,
)

COUNT = 300


def branches(B: int) -> tuple[dict[str, np.ndarray], list[np.ndarray]]:
    """B runs cycling through the branches: reweighed by both sonars (resampling: the cloud is
    wide against the ranges), by one sonar, without a range (no resampling), drawn, drawn and
    weighed, not moving, not live, with navigation noise, without regularisation's spread."""
    inputs, states = run_inputs(B), run_states(B, COUNT)
    Q = np.zeros((6, 6))
    Q[:3, :3] = np.diag([1e-4, 2e-4, 5e-5])
    for i in range(B):
        case = i % 8
        if case == 1:
            inputs["used"][i, 1] = 0.0
        elif case == 2:
            inputs["used"][i] = 0.0
            inputs["status"][i] = DROPPED
        elif case == 3:
            inputs["drawn"][i] = 1.0
        elif case == 4:
            inputs["drawn"][i] = 1.0
            inputs["weigh_draw"][i] = 1.0
        elif case == 5:
            inputs["moving"][i] = 0.0
        elif case == 6:
            states[4][i] = 0.0  # not live: no posterior
            inputs["moving"][i] = 0.0
        elif case == 7:
            inputs["Q_nav"][i] = Q.ravel()
    return inputs, states


@pytest.mark.parametrize("B", [1, 2, 8, 9])
def test_a_batch_step_is_each_run_alone(B):
    inputs, states = branches(B)
    groups, arrays = state_parts(CloudHost(COUNT, batch_size=B), states)
    assert_batch_equals_runs(
        lambda b: CloudHost(COUNT, batch_size=b), inputs, groups, arrays=arrays
    )


def step(B: int, inputs: dict, states: list) -> tuple[dict[str, np.ndarray], list[np.ndarray]]:
    """The outputs and the next state of a batch."""
    system = CloudHost(COUNT, batch_size=B)
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, np.asarray(value, dtype=float).ravel())
    set_states(system, context, states)
    outputs = {
        name: system.GetOutputPort(name).Eval(context).reshape(B, -1).copy()
        for name in ("x_hat", "P_hat", "nis")
    }
    return outputs, read_states(system, after_update(system, context))


def test_the_steps_of_every_branch_are_what_they_should_be():
    inputs, states = branches(8)
    outputs, after = step(8, inputs, states)
    nis = outputs["nis"][:, 0]
    assert np.all(np.isfinite(nis[[0, 1, 3, 4, 5, 7]])) and np.isnan(nis[[2, 6]]).all()
    assert np.isnan(outputs["x_hat"][6]).all()  # not live: no posterior
    live = after[4][:, 0]
    assert live.tolist() == [1, 1, 1, 1, 1, 0, 0, 1]
    # A run not moving keeps its particles and weights, and the host's prediction.
    for run in (5, 6):
        for group in (0, 1, 2, 3):
            assert_array_equal(after[group][run], states[group][run])
    # Without a range the weights stand; reweighed runs resampled (equal weights after).
    assert_array_equal(after[3][2], states[3][2])
    assert np.ptp(after[3][0]) == 0.0 and after[3][0][0] == -math.log(COUNT)
    # The prediction written is the new cloud's weighted moments.
    particles = after[2].reshape(8, COUNT, 6)
    weights = np.exp(after[3] - after[3].max(axis=1, keepdims=True))
    weights /= weights.sum(axis=1, keepdims=True)
    mean = np.einsum("bn,bnk->bk", weights, particles)
    assert_allclose(after[0][[0, 1, 2, 3, 4, 7]], mean[[0, 1, 2, 3, 4, 7]], rtol=1e-12)


def test_a_run_is_a_function_of_its_own_seed():
    inputs, states = run_inputs(4), run_states(4, COUNT)
    for name in PORTS:  # four copies of run 0
        inputs[name][:] = inputs[name][0]
    for group in states:
        group[:] = group[0]
    inputs["particle_seed"] = np.array([[0.3], [0.7], [0.3], [0.7]])
    _, after = step(4, inputs, states)
    assert_array_equal(after[2][0], after[2][2])
    assert_array_equal(after[2][1], after[2][3])
    assert not np.array_equal(after[2][0], after[2][1])


def test_a_nan_run_leaves_the_other_runs_bits_alone():
    inputs, states = branches(8)
    clean_outputs, clean = step(8, inputs, states)
    for run, how in ((0, "particles"), (3, "draw"), (7, "weights")):
        if how == "particles":
            states[2][run, 7] = np.nan
        elif how == "draw":
            inputs["draw_P"][run, 0] = np.nan
        else:
            states[3][run] = -np.inf
    with np.errstate(all="raise"):  # nothing of numpy's may even warn
        outputs, after = step(8, inputs, states)
    others = [1, 2, 4, 5, 6]
    for name, value in outputs.items():
        assert_array_equal(value[others], clean_outputs[name][others], err_msg=name)
    for group, value in enumerate(after):
        assert_array_equal(value[others], clean[group][others], err_msg=str(group))
    assert np.isnan(after[2][0]).any() and np.isnan(after[2][3]).all()
    assert np.isnan(after[0][[0, 3, 7]]).any(axis=1).all()


def test_each_run_draws_its_own_target_acceleration_noise():
    """A cloud at one point with equal weights, no range: each run's predicted cloud is
    ``N(A x + B a, B W Bᵀ)`` from its own draws (its sample moments within their standard
    errors), and the runs' draws are independent (particle by particle, uncorrelated)."""
    B, count = 40, 2000
    system = CloudHost(count, batch_size=B)
    A, Bu, W = system.model
    inputs = run_inputs(B)
    inputs["used"][:] = 0.0
    inputs["status"][:] = DROPPED
    inputs["particle_seed"] = np.random.default_rng(5).random((B, 1))
    x = np.array([-2.0, -2.0, 0.3, 0.1, 0.0, -0.1])
    states = [
        np.zeros((B, 6)), np.zeros((B, 36)), np.tile(x, (B, count)),
        np.full((B, count), -math.log(count)), np.ones((B, 1)),
    ]  # fmt: skip
    system = CloudHost(count, batch_size=B)
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, np.asarray(value, dtype=float).ravel())
    set_states(system, context, states)
    particles = read_states(system, after_update(system, context))[2].reshape(B, count, 6)
    # The acceleration noise ū of each particle, from its velocity: ϑ⁺ = ϑ + t (a − ū).
    t = Bu[3, 0]
    noise = inputs["acceleration"][:, None, :] - (particles[:, :, 3:] - x[3:]) / t
    se = 5.0 / math.sqrt(count)
    for run in range(B):
        sample = noise[run]
        assert np.all(np.abs(sample.mean(axis=0)) < se * np.sqrt(np.diag(W))), run
        assert_allclose(np.cov(sample.T), W, atol=5.0 * math.sqrt(2.0 / count) * W.max())
    # Across runs: particle j's draws of two runs are uncorrelated (pooled over particles).
    first = noise[:, :, 0] / math.sqrt(W[0, 0])
    correlation = np.corrcoef(first)[np.triu_indices(B, 1)]
    assert np.abs(correlation).max() < 5.0 / math.sqrt(count)
    # The pooled draws are standard normal in their tails too (ziggurat's layers and tail).
    pooled = (noise / np.sqrt(np.diag(W))).ravel()
    for a in (1.0, 2.0, 3.0):
        p = math.erfc(a / math.sqrt(2.0))
        assert abs(np.mean(np.abs(pooled) > a) - p) < 5.0 * math.sqrt(p / pooled.size)


def test_the_memory_of_a_run():
    assert bytes_per_run(5000) == 8 * (2 * (7 * 5000 + 1) + 2 * 5000)
    assert bytes_per_run(20_000) * 100 < 260e6
    assert bytes_per_run(5000, window=2, navigation_noise=True) > bytes_per_run(5000, window=2)


def test_a_cloud_takes_its_host_s_batch_and_a_double_integrator():
    from drake_uuv.estimators.particle_cloud import ParticleCloud
    from drake_uuv.models.particle_filter import ParticleFilterParameters

    host = CloudHost(COUNT, batch_size=2)
    with pytest.raises(ValueError, match=r"batch_size: must be the host's \(2\), got 3"):
        ParticleCloud(host, ParticleFilterParameters(count=COUNT), np.eye(2), batch_size=3)
    A = host.model[0].copy()
    A[0, 0] = 1.5  # not the double integrator
    host.model = (A, host.model[1], host.model[2])
    with pytest.raises(ValueError, match="model: must be a double integrator"):
        ParticleCloud(host, ParticleFilterParameters(count=COUNT), np.eye(2), batch_size=2)
