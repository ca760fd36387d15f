"""The non-cooperative target: a double integrator driven by Gaussian acceleration noise."""

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.motion import double_integrator_step
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.primitives.setting import time_step_field
from drake_uuv.scenario.schema import TargetConfig


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

    ``config`` (:class:`~drake_uuv.scenario.TargetConfig`) gives W and the initial state;
    ``time_step`` is the period t [s] of its steps.
    """

    def __init__(self, config: TargetConfig, *, time_step: float) -> None:
        super().__init__()
        self._time_step = time_step_field(time_step)
        self._L = np.linalg.cholesky(np.asarray(config.acceleration_covariance, dtype=float))
        self._noise_port = declare_random_input(
            self, "acceleration_noise", 3, RandomDistribution.kGaussian
        )
        self._p_index = self.DeclareDiscreteState(np.asarray(config.initial_position, float))
        self._v_index = self.DeclareDiscreteState(np.asarray(config.initial_velocity, float))
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)
        self.DeclareStateOutputPort("p_WT", self._p_index)
        self.DeclareStateOutputPort("v_WT", self._v_index)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state = context.get_discrete_state()
        acceleration = self._L @ self._noise_port.Eval(context)
        p, v = double_integrator_step(
            state.value(self._p_index), state.value(self._v_index), acceleration, self._time_step
        )
        discrete_state.set_value(self._p_index, p)
        discrete_state.set_value(self._v_index, v)
