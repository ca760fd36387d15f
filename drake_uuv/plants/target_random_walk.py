"""The non-cooperative target: a double integrator driven by Gaussian acceleration noise."""

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from drake_uuv.models.motion import double_integrator_step
from drake_uuv.primitives.batch import batch_size_field, per_run, tiled
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

    Sizes are per run: with ``batch_size`` B every port and state holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each run from the same initial state.

    ``config`` (:class:`~drake_uuv.scenario.TargetConfig`) gives W and the initial state;
    ``time_step`` is the period t [s] of its steps.
    """

    def __init__(self, config: TargetConfig, *, time_step: float, batch_size: int = 1) -> None:
        super().__init__()
        self._time_step = time_step_field(time_step)
        self.batch_size = B = batch_size_field(batch_size)
        self._L = np.linalg.cholesky(np.asarray(config.acceleration_covariance, dtype=float))
        self._noise_port = declare_random_input(
            self, "acceleration_noise", 3, RandomDistribution.kGaussian, batch_size=B
        )
        self._p_index = self.DeclareDiscreteState(tiled(config.initial_position, B))
        self._v_index = self.DeclareDiscreteState(tiled(config.initial_velocity, B))
        self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, self._update)
        self.DeclareStateOutputPort("p_WT", self._p_index)
        self.DeclareStateOutputPort("v_WT", self._v_index)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        state, B = context.get_discrete_state(), self.batch_size
        xi = per_run(self._noise_port.Eval(context), B)
        # ū = L ξ per run, written out so each run sums in the same order whatever B.
        L = self._L
        acceleration = xi[:, 0:1] * L[:, 0] + xi[:, 1:2] * L[:, 1] + xi[:, 2:3] * L[:, 2]
        p, v = double_integrator_step(
            per_run(state.value(self._p_index), B),
            per_run(state.value(self._v_index), B),
            acceleration,
            self._time_step,
        )
        discrete_state.set_value(self._p_index, p.ravel())
        discrete_state.set_value(self._v_index, v.ravel())
