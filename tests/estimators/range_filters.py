"""Builders and inputs of the raw-range filter tests: one filter alone, inputs fixed."""

import math

import numpy as np

from drake_uuv.estimators import EstimatorSetting, RangeFilter
from drake_uuv.models.measurement import range_measurement
from drake_uuv.models.motion import double_integrator
from drake_uuv.scenario import Ekf, Iekf, ParticleFilter, Ukf
from drake_uuv.testing import fixed_context
from tests.conftest import ETA_UNEQUAL, X0, T, W

F = 3
P0 = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1]) + 0.01
Q_S = np.array([-0.6, 1.1, 0.5])  # the body baseline; with R_WB = I also the world baseline
A_W = np.array([1.0, -3.0, 0.5])
X_TRUE = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
A, B = double_integrator(T)
R = np.diag(ETA_UNEQUAL / F)
COUNT = 400
SETTING = EstimatorSetting(
    time_step=T, acceleration_covariance=W, noise_variances=ETA_UNEQUAL, samples_per_step=F,
    baseline_B=Q_S,
)  # fmt: skip
CONFIGS = {"ekf": Ekf, "iekf": Iekf, "ukf": Ukf, "pf": ParticleFilter}
#: The Gaussian update from the first step: no linear start, no particles.
RANGE_ONLY = dict(handover="threshold", linear_start_max_steps=0)
#: The rule without the bridge (the EKF's second-order test stays its default).
NO_BRIDGE = dict(particle_bridge=False)


def make(kind: str = "ekf", **fields) -> RangeFilter:
    """A raw-range filter of ``kind`` from ``X0``, ``P0``, with ``COUNT`` particles."""
    config = CONFIGS[kind](
        initial_estimate=X0.tolist(), initial_covariance=P0.tolist(), particle_count=COUNT,
        **fields,
    )  # fmt: skip
    return RangeFilter(config, setting=SETTING)


def samples(seed: int = 0) -> np.ndarray:
    """f noisy samples per sonar of the ranges of ``X_TRUE`` (sonar 1's first), seeded."""
    rng = np.random.default_rng(seed)
    d = range_measurement(X_TRUE, Q_S)
    return (d[:, None] + np.sqrt(ETA_UNEQUAL)[:, None] * rng.standard_normal((2, F))).ravel()


def means(measured: np.ndarray | None = None) -> np.ndarray:
    return (samples() if measured is None else measured).reshape(2, F).mean(axis=1)


def inputs(system: RangeFilter, seed_value: float = 0.5, **overrides) -> dict[str, np.ndarray]:
    values = dict(
        range_samples=samples(), R_WB_nav=np.eye(3).ravel(), u1_W=A_W, sonar_status=np.zeros(2)
    )
    if system.HasInputPort("particle_seed"):
        values["particle_seed"] = [seed_value]
    values.update(overrides)
    return values


def context_of(system: RangeFilter, **overrides):
    return fixed_context(system, **inputs(system, **overrides))


def filtered(system, context) -> tuple[np.ndarray, np.ndarray, int, float]:
    return (
        system.GetOutputPort("x_TU_hat").Eval(context),
        system.GetOutputPort("P_TU").Eval(context).reshape(6, 6),
        int(system.GetOutputPort("measurement_status").Eval(context)[0]),
        float(system.GetOutputPort("nis").Eval(context)[0]),
    )


def seed_rng(seed_value: float = 0.5) -> np.random.Generator:
    """The generator a periodic update seeds from the ``particle_seed`` port's value."""
    return np.random.default_rng(int(seed_value * 2.0**53))


def uniform_log_weights(count: int = COUNT) -> np.ndarray:
    return np.full(count, -math.log(count))
