"""The non-cooperative target: a double integrator driven by Gaussian acceleration noise."""

from typing import Self

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.motion import double_integrator_step
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.scenario import Scenario


class TargetRandomWalk(LeafSystem):
    """``X̄(k+1) = A X̄(k) + B ū(k)``, ``ū ~ N(0, W)``.

    The noise arrives as a standard-normal random input port (fed by a ``RandomSource`` in the
    diagram, seeded through ``SetRandomContext``) and is coloured here by ``chol(W)``, so the
    system itself is deterministic and unit-testable with a fixed input.

    .. pydrake_system::

        name: TargetRandomWalk
        input_ports:
        - acceleration_noise
        output_ports:
        - p_WT
        - v_WT

    - ``acceleration_noise`` (3, random, standard normal): ``ξ`` with ``ū = chol(W) ξ``.
    - ``p_WT``, ``v_WT`` (3 each): position and velocity of the target in the world.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_position: np.ndarray,
        initial_velocity: np.ndarray,
    ) -> None:
        super().__init__()
        self._time_step = float(time_step)
        self._L = np.linalg.cholesky(np.asarray(acceleration_covariance, dtype=float))
        self._noise_port = declare_random_input(
            self, "acceleration_noise", 3, RandomDistribution.kGaussian
        )
        self._p_index = self.DeclareDiscreteState(np.asarray(initial_position, dtype=float))
        self._v_index = self.DeclareDiscreteState(np.asarray(initial_velocity, dtype=float))
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._update)
        self.DeclareStateOutputPort("p_WT", self._p_index)
        self.DeclareStateOutputPort("v_WT", self._v_index)

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> Self:
        """The target of ``scenario.target``."""
        target = scenario.target
        return cls(
            scenario.time_step,
            np.asarray(target.acceleration_covariance),
            np.asarray(target.initial_position),
            np.asarray(target.initial_velocity),
        )

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state = context.get_discrete_state()
        acceleration = self._L @ self._noise_port.Eval(context)
        p, v = double_integrator_step(
            state.value(self._p_index), state.value(self._v_index), acceleration, self._time_step
        )
        discrete_state.set_value(self._p_index, p)
        discrete_state.set_value(self._v_index, v)
