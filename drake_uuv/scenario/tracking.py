"""The tracking slot's variants: the law holding the target at q*, one dataclass each.

The factory that builds the system of each variant is
:func:`drake_uuv.tracking.make_tracking_controller`.
"""

import math
from dataclasses import dataclass, field

from drake_uuv.models.information import TrackingPlanningModel
from drake_uuv.scenario.validation import check_choice, check_positive, check_vector, fail

# The paper proves bounded tracking for α in (1 − 1/√2, 1 + 1/√2).
ALPHA_PROVEN_INTERVAL = (1.0 - 1.0 / math.sqrt(2.0), 1.0 + 1.0 / math.sqrt(2.0))
# The frames q* may be fixed in.
REFERENCE_FRAMES = ("body", "world", "heading")
# How the cautious loop scales the feedback: by tr P_qq, or per world axis by P_ii.
CAUTION_SCALINGS = ("trace", "axis")


@dataclass
class TrackingOptions:
    """Fields every tracking law has."""

    # q*, the desired relative position q = p_WU − p_WT [m], in reference_frame.
    desired_relative_position: list[float] = field(default_factory=lambda: [-2.0, -2.0, 0.0])
    # The frame q* is fixed in: "body" (the paper's: the desired point turns with the body, so
    # under Algorithm 2 it sweeps a circle of radius |q*| around the target), "world" (fixed),
    # or "heading" (turns with the body's yaw only).
    reference_frame: str = "body"
    # Largest |world acceleration| [m/s²]; None means unlimited (the paper).
    max_acceleration: float | None = None
    # The cautious loop (both off by default: the paper's certainty equivalence, which acts on
    # the estimate as if it were the truth, even on a linear start's first guesses).
    # caution_position_std σ [m]: the feedback falls with the estimate's position variance
    # (the law then reads P_TU), by s = 1/(1 + tr P_qq/σ²) with caution_scaling "trace", or
    # by s_i = 1/(1 + P_ii/σ²) along each world axis with "axis". None: no scaling.
    caution_position_std: float | None = None
    caution_scaling: str = "trace"
    # Hold station while the estimator is in its linear start: the command brings the
    # vehicle to rest (-v/t, within max_acceleration) and keeps it there, so a run sent back
    # to the linear start by a recovery stops rather than coasts (the law then reads the
    # raw-range filters' estimator_phase and v_WU_nav; the paper's KF never hands over, and
    # with it the option holds nothing).
    hold_until_handover: bool = False
    # A top speed [m/s] the law keeps to (None: only the plant's, if it has one): the command
    # is limited so that the navigated velocity stays within it (the law then reads v_WU_nav),
    # and u1_W reports the limited acceleration. Unlike the plant's, it holds on every plant.
    max_speed: float | None = None

    def validate(self, name: str) -> None:
        check_vector(f"{name}.desired_relative_position", self.desired_relative_position, 3)
        check_choice(f"{name}.reference_frame", self.reference_frame, REFERENCE_FRAMES)
        if self.max_acceleration is not None:
            check_positive(f"{name}.max_acceleration", self.max_acceleration)
        if self.caution_position_std is not None:
            check_positive(f"{name}.caution_position_std", self.caution_position_std)
        check_choice(f"{name}.caution_scaling", self.caution_scaling, CAUTION_SCALINGS)
        if not isinstance(self.hold_until_handover, bool):
            fail(f"{name}.hold_until_handover", "must be true or false", self.hold_until_handover)
        if self.max_speed is not None:
            check_positive(f"{name}.max_speed", self.max_speed)

    def planning_model(self) -> TrackingPlanningModel:
        """What an attitude planner assumes of this law: q* if it turns with the body, and a
        reference lag of one step (the law aims at the current point ``R(k) q*``)."""
        return TrackingPlanningModel(self._body_reference(), reference_lag=1)

    def _body_reference(self) -> tuple[float, float, float] | None:
        """q* when it is fixed in the body frame, else None."""
        if self.reference_frame != "body":
            return None
        x, y, z = self.desired_relative_position
        return (float(x), float(y), float(z))


@dataclass
class PaperTracking(TrackingOptions):
    """The paper's law (its section III-B), ``u1 = −(2α/t²)(Rᵀ q̂ − q*) − (2/t) Rᵀ ϑ̂``."""

    alpha: float = 1.2
    # The paper proves bounded tracking only for α in ALPHA_PROVEN_INTERVAL.
    allow_unproven_alpha: bool = False

    def validate(self, name: str) -> None:
        super().validate(name)
        check_positive(f"{name}.alpha", self.alpha)
        low, high = ALPHA_PROVEN_INTERVAL
        if not low < self.alpha < high and not self.allow_unproven_alpha:
            fail(
                f"{name}.alpha",
                f"must be in ({low:.4f}, {high:.4f}) where the paper proves bounded tracking "
                f"(set {name}.allow_unproven_alpha=true to run it anyway)",
                self.alpha,
            )


@dataclass
class LqrTracking(TrackingOptions):
    """A discrete LQR gain on the relative double integrator, with the attitude plan's
    reference fed forward. ``Q = diag(position_weight I, velocity_weight I)`` on the
    relative-state error and ``R = input_weight I`` on the world acceleration; the defaults
    follow Bryson's rule (weight = 1/acceptable²): 1 m of position error, 2 m/s of velocity
    error, √10 ≈ 3.2 m/s² of acceleration."""

    position_weight: float = 1.0
    velocity_weight: float = 0.25
    input_weight: float = 0.1
    # Feed the attitude plan's reference velocity and acceleration forward (false: regulate to
    # the current point R q* only, which lags the turning reference).
    feedforward: bool = True

    def planning_model(self) -> TrackingPlanningModel:
        """As :meth:`TrackingOptions.planning_model`, with no lag when the plan is fed forward
        (the law then lands on the next reference ``R(k+1) q*``)."""
        return TrackingPlanningModel(
            self._body_reference(), reference_lag=0 if self.feedforward else 1
        )

    def validate(self, name: str) -> None:
        super().validate(name)
        check_positive(f"{name}.position_weight", self.position_weight)
        check_positive(f"{name}.velocity_weight", self.velocity_weight, strict=False)
        check_positive(f"{name}.input_weight", self.input_weight)


#: The tracking slot. The first member is the default of an untagged section.
TrackingConfig = PaperTracking | LqrTracking
