"""The paper's Algorithm 2: the baseline follows a fixed, persistently exciting trajectory."""

import functools

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.attitude.base import AttitudeGenerator
from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.scenario import Scenario


class TrajectoryAttitudeGenerator(AttitudeGenerator):
    """Algorithm 2: ``R̄(k)`` the minimal rotation taking ``b`` along
    ``ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)]``, ``h(k) = h_amplitude · cos(h_frequency · kπ)``
    (:func:`~drake_uuv.models.attitude_plans.trajectory_attitude`), so ``q_s(k+1) ∥ ζ(k)``.

    The trajectory is deterministic, so the plan's ``R(k+2)`` rolls the law one step further
    (including any rate limit).

    .. pydrake_system::

        name: TrajectoryAttitudeGenerator
        input_ports:
        - R_WB
        output_ports:
        - u2_W
        - R_WB_plan

    Ports as in :class:`~drake_uuv.attitude.base.AttitudeGenerator`.
    """

    def __init__(
        self,
        time_step: float,
        baseline_B: np.ndarray,
        rho: float = 1.0 / 24.0,
        h_amplitude: float = 0.5,
        h_frequency: float = 1.0 / 6.0,
        max_angular_rate: float | None = None,
    ) -> None:
        super().__init__(time_step, max_angular_rate)
        b = np.asarray(baseline_B, dtype=float)
        if b.shape != (3,) or not np.all(np.isfinite(b)) or not b @ b > 0.0:
            raise ValueError(f"baseline_B: must be a non-zero finite 3-vector, got {baseline_B!r}")

        # R̄(k) depends on k alone: every run of a Monte Carlo study reuses it.
        @functools.lru_cache(maxsize=4096)
        def attitude(k: int) -> np.ndarray:
            return trajectory_attitude(k, b, rho, h_amplitude, h_frequency)

        self._attitude = attitude
        self._declare_outputs()

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "TrajectoryAttitudeGenerator":
        """The generator of ``scenario.attitude``."""
        config = scenario.attitude
        return cls(
            scenario.time_step,
            np.asarray(scenario.sonar.baseline),
            config.rho,
            config.h_amplitude,
            config.h_frequency,
            config.max_angular_rate,
        )

    def desired_attitude(self, context: Context) -> np.ndarray | None:
        return self._attitude(self.step_index(context))

    def next_desired_attitude(self, context: Context) -> np.ndarray | None:
        return self._attitude(self.step_index(context) + 1)
