"""The paper's Algorithm 1: a uniformly random attitude every step."""

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import Context

from drake_uuv.attitude.base import AttitudeGenerator, AttitudeSetting
from drake_uuv.models.attitude_plans import quaternion_attitudes
from drake_uuv.primitives.batch import per_run
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.scenario.attitude import RandomAttitude


class RandomAttitudeGenerator(AttitudeGenerator):
    """Algorithm 1: ``R̄(k)`` uniformly random on SO(3), so ``R(k+1) = R̄(k)``.

    A normalised standard-normal 4-vector is a uniformly distributed unit quaternion; it
    arrives on a random input port (fed by a seeded ``RandomSource`` in the diagram), so the
    system itself is deterministic given its inputs. ``R̄(k+1)`` is drawn only at step k+1, so
    the plan holds ``R(k+2) = R(k+1)``.

    .. pydrake_system::

        name: RandomAttitudeGenerator
        input_ports:
        - R_WB_nav
        - rotation_noise
        output_ports:
        - u2_W
        - R_WB_plan

    - ``rotation_noise`` (4, random, standard normal): the quaternion before normalising.
    - The other ports as in :class:`~drake_uuv.attitude.base.AttitudeGenerator`.

    Sizes are per run: with ``batch_size`` B every port holds B runs row-major, each run's
    rotation from its own noise.

    ``config`` (:class:`~drake_uuv.scenario.RandomAttitude`) gives the rate limit.
    """

    def __init__(
        self, config: RandomAttitude, *, setting: AttitudeSetting, batch_size: int = 1
    ) -> None:
        super().__init__(
            setting=setting, max_angular_rate=config.max_angular_rate, batch_size=batch_size
        )
        self._noise_port = declare_random_input(
            self, "rotation_noise", 4, RandomDistribution.kGaussian, batch_size=self.batch_size
        )
        self._declare_outputs()

    def desired_attitudes(self, context: Context) -> np.ndarray | None:
        return quaternion_attitudes(per_run(self._noise_port.Eval(context), self.batch_size))
