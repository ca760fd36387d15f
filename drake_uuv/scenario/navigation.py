"""The navigation slot's variants: what the vehicle knows of its own attitude and motion.

The paper gives its estimator and controllers the vehicle's true attitude and motion. A real
UUV has an AHRS with a magnetic compass for its attitude, a Doppler velocity log (DVL) for its
velocity, and dead reckoning for its position. ``!PerfectNavigation`` (the default) keeps the
paper's assumption; ``!InertialNavigation`` adds those instruments' errors. The factory that
builds the system of each variant is :func:`drake_uuv.navigation.make_navigation`.

The defaults of ``!InertialNavigation`` are commercial-grade figures:

- AHRS: 0.5° RMS in roll and pitch, 2° RMS in magnetic heading (the order of the VectorNav
  VN-100's datasheet figures for static roll/pitch and magnetic heading);
- compass bias: 2° (a magnetometer calibrated away from the vehicle's motors and batteries
  keeps a heading bias of degrees; Kinsey, Eustice & Whitcomb, "A survey of underwater vehicle
  navigation", IFAC 2006, give 1–2° for magnetic heading in clean conditions);
- DVL: 1 cm/s white noise per axis and step, 0.5 cm/s bias per axis (Water Linked's DVL A50
  quotes a long-term accuracy of 1 % of speed, 0.5 cm/s at 0.5 m/s; single-ping noise is
  larger than the long-term figure).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from drake_uuv.models.navigation_noise import NavigationErrors
from drake_uuv.scenario.validation import check_positive, check_vector, fail


@dataclass
class PerfectNavigation:
    """The paper's assumption: the vehicle knows its true attitude, velocity and position."""

    def validate(self, name: str) -> None:
        pass

    def error_figures(self) -> NavigationErrors:
        return NavigationErrors()


@dataclass
class InertialNavigation:
    """An AHRS with a magnetic compass, a DVL, and dead reckoning (see the module notes)."""

    # σ of the white AHRS noise on roll, pitch and yaw, drawn each step [deg].
    attitude_noise_deg: list[float] = field(default_factory=lambda: [0.5, 0.5, 2.0])
    # σ of the compass's constant heading (yaw) bias, drawn once per run [deg].
    heading_bias_deg: float = 2.0
    # σ of the DVL's white velocity noise per body axis, drawn each step [m/s].
    velocity_noise: float = 0.01
    # σ of the DVL's constant velocity bias per body axis, drawn once per run [m/s].
    velocity_bias: float = 0.005

    def validate(self, name: str) -> None:
        attitude = check_vector(f"{name}.attitude_noise_deg", self.attitude_noise_deg, 3)
        if np.any(attitude < 0.0) or np.any(attitude > 30.0):
            fail(f"{name}.attitude_noise_deg", "must be in [0, 30] each", self.attitude_noise_deg)
        if not 0.0 <= self.heading_bias_deg <= 30.0:
            fail(f"{name}.heading_bias_deg", "must be in [0, 30]", self.heading_bias_deg)
        check_positive(f"{name}.velocity_noise", self.velocity_noise, strict=False)
        check_positive(f"{name}.velocity_bias", self.velocity_bias, strict=False)

    def error_figures(self) -> NavigationErrors:
        return NavigationErrors(
            attitude_noise=np.radians(np.asarray(self.attitude_noise_deg, dtype=float)),
            heading_bias=math.radians(self.heading_bias_deg),
            velocity_noise=float(self.velocity_noise),
            velocity_bias=float(self.velocity_bias),
        )


#: The navigation slot. The first member is the default of an untagged section.
NavigationConfig = PerfectNavigation | InertialNavigation
