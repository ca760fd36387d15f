"""The paper's Algorithm 2: the baseline follows a fixed, persistently exciting trajectory."""

import functools

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.attitude.base import AttitudeGenerator, AttitudeSetting
from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.scenario.attitude import TrajectoryAttitude


class TrajectoryAttitudeGenerator(AttitudeGenerator):
    """Algorithm 2: ``R̄(k)`` the minimal rotation taking ``b`` along
    ``ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)]``, ``h(k) = h_amplitude · cos(h_frequency · kπ)``
    (:func:`~drake_uuv.models.attitude_plans.trajectory_attitude`), so ``q_s(k+1) ∥ ζ(k)``.

    The trajectory is deterministic, so the plan's ``R(k+2)`` rolls the law one step further
    (including any rate limit).

    .. pydrake_system::

        name: TrajectoryAttitudeGenerator
        input_ports:
        - R_WB_nav
        output_ports:
        - u2_W
        - R_WB_plan

    Ports as in :class:`~drake_uuv.attitude.base.AttitudeGenerator` (sizes per run; with
    ``batch_size`` B every port holds B runs row-major). ``R̄(k)`` depends on k alone: it is
    computed once per step and every run turns towards it from its own attitude. ``config``
    (:class:`~drake_uuv.scenario.TrajectoryAttitude`) gives ρ, the h amplitude and frequency
    and the rate limit; the ``setting`` the period and the baseline b.
    """

    def __init__(
        self, config: TrajectoryAttitude, *, setting: AttitudeSetting, batch_size: int = 1
    ) -> None:
        super().__init__(
            setting=setting, max_angular_rate=config.max_angular_rate, batch_size=batch_size
        )
        b = setting.baseline_B
        rho, h_amplitude, h_frequency = config.rho, config.h_amplitude, config.h_frequency

        # R̄(k) depends on k alone: every run of the batch (and of a study) reuses it.
        @functools.lru_cache(maxsize=4096)
        def attitude(k: int) -> np.ndarray:
            # Shared by the cache: only read (writable all the same, so that the compiled
            # kernels see the same array type as Algorithm 1's and compile once).
            return trajectory_attitude(k, b, rho, h_amplitude, h_frequency).reshape(1, 3, 3)

        self._attitude = attitude
        self._declare_outputs()

    def desired_attitudes(self, context: Context) -> np.ndarray | None:
        return self._attitude(self.step_index(context))

    def next_desired_attitudes(self, context: Context) -> np.ndarray | None:
        return self._attitude(self.step_index(context) + 1)
