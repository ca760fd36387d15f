"""The attitude never moves: the baseline is not exciting, the state is not observable."""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.attitude.base import AttitudeGenerator
from drake_uuv.scenario import Scenario


class FixedAttitudeGenerator(AttitudeGenerator):
    """``u2 = 0``: with a fixed baseline two directions of the relative state are never seen.

    .. pydrake_system::

        name: FixedAttitudeGenerator
        input_ports:
        - R_WB
        output_ports:
        - u2_W
        - R_WB_plan

    Ports as in :class:`~drake_uuv.attitude.base.AttitudeGenerator`.
    """

    def __init__(self, time_step: float) -> None:
        super().__init__(time_step)
        self._declare_outputs()

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> "FixedAttitudeGenerator":
        """The generator of ``scenario.attitude``."""
        return cls(scenario.time_step)

    def desired_attitude(self, context: Context) -> np.ndarray | None:
        return None
