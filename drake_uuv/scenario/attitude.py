"""The attitude slot's variants: how the vehicle turns its sonar baseline, chosen by tag.

The factory that builds the system of each variant is
:func:`drake_uuv.attitude.make_attitude_generator`.
"""

from dataclasses import dataclass

import numpy as np

from drake_uuv.scenario.validation import check_finite, check_positive


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


#: The attitude slot. The first member is the default of an untagged section.
AttitudeConfig = TrajectoryAttitude | RandomAttitude | FixedAttitude
