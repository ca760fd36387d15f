"""The attitude never moves: the baseline is not exciting, the state is not observable."""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.attitude.base import AttitudeGenerator, AttitudeSetting
from drake_uuv.scenario.attitude import FixedAttitude


class FixedAttitudeGenerator(AttitudeGenerator):
    """``u2 = 0``: with a fixed baseline two directions of the relative state are never seen.

    .. pydrake_system::

        name: FixedAttitudeGenerator
        input_ports:
        - R_WB_nav
        output_ports:
        - u2_W
        - R_WB_plan

    Ports as in :class:`~drake_uuv.attitude.base.AttitudeGenerator` (sizes per run; with
    ``batch_size`` B every port holds B runs row-major). ``config``
    (:class:`~drake_uuv.scenario.FixedAttitude`) has no parameters.
    """

    def __init__(
        self, config: FixedAttitude, *, setting: AttitudeSetting, batch_size: int = 1
    ) -> None:
        super().__init__(setting=setting, batch_size=batch_size)
        self._declare_outputs()

    def desired_attitudes(self, context: Context) -> np.ndarray | None:
        return None
