"""The target's random walk: ports, one step in closed form, the colouring of the noise."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import AddRandomInputs

from drake_uuv.plants import TargetRandomWalk
from drake_uuv.scenario import TargetConfig
from drake_uuv.testing import assert_batch_equals_runs, discrete_update, fixed_context
from tests.conftest import T

W = np.array([[0.004, 0.001, 0.0], [0.001, 0.002, 0.0], [0.0, 0.0, 0.001]])


def target_at(p0: np.ndarray, v0: np.ndarray) -> TargetRandomWalk:
    """The target with acceleration covariance W starting at ``p0``, ``v0``."""
    config = TargetConfig(list(p0), list(v0), acceleration_covariance=W.tolist())
    return TargetRandomWalk(config, time_step=T)


def test_ports_and_random_input() -> None:
    target = target_at(np.array([1.0, 2.0, 2.0]), np.array([0.02, 0.1, 0.1]))
    assert target.GetInputPort("acceleration_noise").size() == 3
    # Declared as a random port: Drake's AddRandomInputs finds it and feeds it.
    builder = DiagramBuilder()
    builder.AddSystem(target)
    assert AddRandomInputs(T, builder) == 1
    assert target.GetOutputPort("p_WT").size() == 3 and target.GetOutputPort("v_WT").size() == 3
    assert not target.HasAnyDirectFeedthrough()


def test_one_step_is_the_double_integrator_with_coloured_noise() -> None:
    p0, v0 = np.array([1.0, 2.0, 2.0]), np.array([0.02, 0.1, 0.1])
    target = target_at(p0, v0)
    xi = np.array([0.5, -1.5, 2.0])
    context = fixed_context(target, acceleration_noise=xi)
    assert_allclose(target.GetOutputPort("p_WT").Eval(context), p0)
    assert_allclose(target.GetOutputPort("v_WT").Eval(context), v0)
    u = np.linalg.cholesky(W) @ xi
    assert_allclose(discrete_update(target, context, 0), p0 + T * v0 + 0.5 * T * T * u, rtol=1e-14)
    assert_allclose(discrete_update(target, context, 1), v0 + T * u, rtol=1e-14)


@pytest.mark.parametrize("seed", [3])
def test_acceleration_covariance_is_W(seed: int) -> None:
    """chol(W) ξ has covariance W: check the colouring on many fixed standard-normal draws."""
    target = target_at(np.zeros(3), np.zeros(3))
    rng = np.random.default_rng(seed)
    n = 4000
    accelerations = np.empty((n, 3))
    context = fixed_context(target, acceleration_noise=np.zeros(3))
    for i in range(n):
        target.GetInputPort("acceleration_noise").FixValue(context, rng.standard_normal(3))
        accelerations[i] = discrete_update(target, context, 1) / T
    sample = np.cov(accelerations.T)
    # Standard error of a covariance entry: sqrt((W_ii W_jj + W_ij²) / n); allow 4 of them.
    tolerance = 4 * np.sqrt((np.outer(np.diag(W), np.diag(W)) + W**2) / n)
    assert np.all(np.abs(sample - W) < tolerance)


@pytest.mark.parametrize("batch_size", [1, 3, 8])
def test_a_batch_step_is_each_run_alone(batch_size: int) -> None:
    """Random batches: outputs and the update of B runs equal B single runs, bit for bit."""
    rng = np.random.default_rng(batch_size)
    config = TargetConfig([1.0, 2.0, 2.0], [0.02, 0.1, 0.1], acceleration_covariance=W.tolist())
    states = [rng.normal(size=(batch_size, 3)), rng.normal(size=(batch_size, 3))]
    inputs = {"acceleration_noise": rng.normal(size=(batch_size, 3))}
    assert_batch_equals_runs(
        lambda B: TargetRandomWalk(config, time_step=T, batch_size=B), inputs, states
    )
