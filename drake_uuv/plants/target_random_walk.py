"""The non-cooperative target: a double integrator driven by Gaussian acceleration noise."""

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.plants.double_integrator import double_integrator


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
        - state

    - ``acceleration_noise`` (3, random, standard normal): ``ξ`` with ``ū = chol(W) ξ``.
    - ``state`` (6): ``[p_WT, v_WT]``, position and velocity of the target in the world.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_position: np.ndarray,
        initial_velocity: np.ndarray,
    ) -> None:
        super().__init__()
        self._A, self._B = double_integrator(time_step)
        self._L = np.linalg.cholesky(np.asarray(acceleration_covariance, dtype=float))
        self._noise_port = self.DeclareVectorInputPort(
            "acceleration_noise", 3, RandomDistribution.kGaussian
        )
        self._state_index = self.DeclareDiscreteState(
            np.concatenate([initial_position, initial_velocity])
        )
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._update)
        self.DeclareStateOutputPort("state", self._state_index)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        x = context.get_discrete_state(self._state_index).get_value()
        acceleration = self._L @ self._noise_port.Eval(context)
        discrete_state.set_value(self._state_index, self._A @ x + self._B @ acceleration)
