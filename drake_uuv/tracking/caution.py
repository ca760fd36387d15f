"""The cautious loop: what a tracking law does about an estimate it should not yet trust.

Under certainty equivalence a tracking law acts on the estimate as if it were the truth,
even on a linear start's first guesses; a vehicle with no top speed then chases them. Each
option below is off by default (the paper's loop, bit for bit) and declares the input port
it reads only when it is on:

- **caution** (``caution_position_std`` σ, reads ``P_TU``): the feedback is scaled by
  :func:`~drake_uuv.models.tracking_laws.caution_scales`, 1 for a known position and falling
  as 1/variance beyond σ², so a wide estimate moves the vehicle little;
- **hold** (``hold_until_handover``, reads ``estimator_phase`` and ``v_WU_nav``): while the
  raw-range filter is in its linear start the vehicle holds station, the command bringing it
  to rest (``−v/t``, within the law's acceleration limit) instead of the law's. A vehicle
  that starts at rest stays still (with perfect navigation exactly: no command at all); one
  sent back to the linear start by the filter's recovery stops instead of coasting on at
  the speed it had (on the kinematic plant, which keeps any velocity it is given, coasting
  carried such runs tens of metres away). Nothing to hold for with an estimator that never
  hands over, the paper's KF (the setting's ``estimator_hands_over``);
- **top speed** (the lower of the plant's, the setting's ``max_speed``, and the law's own
  ``max_speed``; reads ``v_WU_nav``): the command limited so that the navigated velocity
  stays within it
  (:func:`~drake_uuv.models.tracking_laws.speed_limited_acceleration`), so that ``u1_W``
  is the acceleration the plant applies (exactly, with perfect navigation).
"""

import numpy as np
from pydrake.systems.framework import Context, LeafSystem

from drake_uuv.models.handover import Phase
from drake_uuv.models.tracking_laws import (
    caution_scales,
    saturate_norm,
    speed_limited_acceleration,
)
from drake_uuv.primitives.batch import per_run
from drake_uuv.scenario.tracking import TrackingOptions
from drake_uuv.tracking.base import TrackingSetting

_LINEAR = float(Phase.LINEAR)


class CautiousLoop:
    """The cautious options of one tracking system: its extra ports and their arithmetic on
    the world acceleration (B×3), each run alone (masks, no branch on the batch)."""

    def __init__(
        self,
        system: LeafSystem,
        config: TrackingOptions,
        *,
        setting: TrackingSetting,
        batch_size: int,
    ) -> None:
        B = self._batch_size = batch_size
        self._time_step = setting.time_step
        self._position_std = config.caution_position_std
        self._scaling = config.caution_scaling
        self._max_acceleration = config.max_acceleration
        speeds = [v for v in (setting.max_speed, config.max_speed) if v is not None]
        self._max_speed = min(speeds) if speeds else None
        self._covariance_port = self._phase_port = self._velocity_port = None
        if self._position_std is not None:
            self._covariance_port = system.DeclareVectorInputPort("P_TU", 36 * B)
        if config.hold_until_handover and setting.estimator_hands_over:
            self._phase_port = system.DeclareVectorInputPort("estimator_phase", 2 * B)
        if self._max_speed is not None or self._phase_port is not None:
            self._velocity_port = system.DeclareVectorInputPort("v_WU_nav", 3 * B)

    @property
    def scales(self) -> bool:
        """Whether the feedback falls with the covariance."""
        return self._covariance_port is not None

    @property
    def limits(self) -> bool:
        """Whether the command is held or limited after the law (hold, top speed)."""
        return self._phase_port is not None or self._velocity_port is not None

    def scale_factors(self, context: Context) -> np.ndarray:
        """The feedback's factors (B×3, world axes) from this step's ``P_TU``."""
        P = per_run(self._covariance_port.Eval(context), self._batch_size)
        return caution_scales(P, self._position_std, self._scaling)

    def limited(self, context: Context, a_W: np.ndarray) -> np.ndarray:
        """``a_W`` (B×3) bringing the run to rest where it holds station, then within the top
        speed."""
        B = self._batch_size
        v = None  # read once, and only where a run holds or a top speed applies
        if self._phase_port is not None:
            phase = per_run(self._phase_port.Eval(context), B)[:, 0]
            holding = (phase == _LINEAR)[:, np.newaxis]
            if holding.any():
                v = per_run(self._velocity_port.Eval(context), B)
                rest = saturate_norm(-v / self._time_step, self._max_acceleration)
                a_W = np.where(holding, rest, a_W)
        if self._max_speed is not None:
            v = per_run(self._velocity_port.Eval(context), B) if v is None else v
            a_W = speed_limited_acceleration(v, a_W, self._time_step, self._max_speed)
        return a_W
