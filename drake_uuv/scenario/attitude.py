"""The attitude slot's variants: how the vehicle turns its sonar baseline, chosen by tag.

The factory that builds the system of each variant is
:func:`drake_uuv.attitude.make_attitude_generator`.
"""

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.scenario.validation import check_choice, check_finite, check_positive, fail


@dataclass
class FixedAttitude:
    """The attitude never changes: the baseline is not exciting, the state not observable."""

    def validate(self, name: str) -> None:
        pass


@dataclass
class RateLimitedAttitude:
    """Fields of the generators that move the attitude."""

    # Largest commanded |u2| [rad/s]; None means unlimited (the paper).
    max_angular_rate: float | None = None

    def validate(self, name: str) -> None:
        if self.max_angular_rate is not None:
            check_positive(f"{name}.max_angular_rate", self.max_angular_rate)


@dataclass
class RandomAttitude(RateLimitedAttitude):
    """The paper's Algorithm 1: a uniformly random attitude every step."""


@dataclass
class TrajectoryAttitude(RateLimitedAttitude):
    """The paper's Algorithm 2: the minimal rotation taking ``b`` along
    ``ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)]``, ``h(k) = h_amplitude · cos(h_frequency · kπ)``."""

    rho: float = 1.0 / 24.0
    h_amplitude: float = 0.5
    h_frequency: float = 1.0 / 6.0

    def validate(self, name: str) -> None:
        super().validate(name)
        for field_name in ("rho", "h_amplitude", "h_frequency"):
            value = getattr(self, field_name)
            check_finite(f"{name}.{field_name}", np.asarray(value), value)


@dataclass
class InformationSeeking:
    """Turns the baseline toward what the filter knows least: each step the attitude within a
    rotation budget that maximises an information criterion of the next measurement(s),
    under a floor on the excitation Gramian (see ``drake_uuv/models/information.py``)."""

    # Rotation budget [rad] per step: the angle of R(k+1) R(k)ᵀ. 0.39 is about Algorithm 2's
    # mean rotation per step in the paper scenario (0.381 rad over 500 steps).
    max_angle_per_step: float = 0.39
    # d_optimal (log det of the posterior information), a_optimal (trace of the posterior
    # covariance, the default: trace P_qq is the squared position RMSE itself) or e_optimal
    # (its largest eigenvalue, i.e. the smallest eigenvalue of the information).
    criterion: str = "a_optimal"
    # The block the criterion acts on: "position" (q) or "full" (q and ϑ).
    block: str = "position"
    # Steps of the receding horizon the criterion is summed over.
    horizon: int = 1
    # [m²] floor on the smallest eigenvalue of Σ q_s q_sᵀ over every window of
    # excitation_window steps (0: no floor), enforced pe_lead steps before a window closes.
    excitation_floor: float = 1.0
    # N [steps] of those windows (24: the paper's persistent-excitation window, eq. 10).
    excitation_window: int = 24
    pe_lead: int = 6
    # [m/s²] limit on the acceleration of the turning reference R q* (None: no limit).
    max_reference_acceleration: float | None = None
    # Relative position the plan assumes for the next steps: "auto" ("hold" for the paper's
    # KF, which needs none; "reference" for the raw-range filters, whose ranges depend on
    # it: q follows R q*), "hold", "coast" or "reference".
    position_prediction: str = "auto"

    def validate(self, name: str) -> None:
        budget = self.max_angle_per_step
        if not (math.isfinite(budget) and 0.0 < budget <= math.pi):
            fail(f"{name}.max_angle_per_step", "must be in (0, π]", budget)
        check_choice(f"{name}.criterion", self.criterion, ("d_optimal", "a_optimal", "e_optimal"))
        check_choice(f"{name}.block", self.block, ("position", "full"))
        predictions = ("auto", "hold", "coast", "reference")
        check_choice(f"{name}.position_prediction", self.position_prediction, predictions)
        if not 1 <= self.horizon <= 50:
            fail(f"{name}.horizon", "must be in [1, 50]", self.horizon)
        check_positive(f"{name}.excitation_floor", self.excitation_floor, strict=False)
        if not 3 <= self.excitation_window <= 10**6:
            fail(f"{name}.excitation_window", "must be in [3, 1e6]", self.excitation_window)
        if self.pe_lead < 0:
            fail(f"{name}.pe_lead", "must be ≥ 0", self.pe_lead)
        if self.pe_lead > self.excitation_window - 3:
            window = self.excitation_window
            fail(f"{name}.pe_lead", f"must be ≤ {name}.excitation_window − 3 = {window - 3}",
                 self.pe_lead)  # fmt: skip
        if self.max_reference_acceleration is not None:
            check_positive(f"{name}.max_reference_acceleration", self.max_reference_acceleration)


#: The attitude slot. The first member is the default of an untagged section.
AttitudeConfig = TrajectoryAttitude | RandomAttitude | FixedAttitude | InformationSeeking
