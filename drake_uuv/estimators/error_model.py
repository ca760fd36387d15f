"""What an estimator believes of its navigation and its sonars: ``estimator.error_model``.

``modelled`` (the default) takes the scenario's figures (:class:`~drake_uuv.estimators.base.
EstimatorSetting`: the navigation's error figures, the sonars' ping schedule and sound-speed
error) into the filter:

- **attitude noise → measurement noise**: the baseline a filter places the sonars on,
  ``R_WB_nav b``, is off by the AHRS noise: each range gets the extra covariance
  ``J Σ_θ Jᵀ``, the paper's ``Y`` the variance ``(q_s × q)ᵀ Σ_θ (q_s × q)``
  (:mod:`drake_uuv.models.navigation_noise`);
- **attitude noise → process noise** with ``vehicle_motion: commanded``: the commanded world
  acceleration ``R_nav u1`` the filter predicts with is off by ``a × θ``: ``[a]× Σ_θ [a]×ᵀ``
  added to W for the step;
- **navigated velocity → process noise** with ``vehicle_motion: navigation``: the navigated
  velocity ``R_WB_nav v_B`` is off by the DVL's noise and bias (``σ_v² + σ_b²`` per axis; the
  bias turns with the body) and by the AHRS noise turning the velocity, ``θ × v``
  (``[v]× Σ_θ [v]×ᵀ``, 6 cm/s at 1.6 m/s with a 2° yaw noise, six times the DVL's 1 cm/s).
  That error ``Σ_ev`` walks the dead-reckoned position the filter subtracts by ``t² Σ_ev`` a
  step, and is added to the published velocity covariance;
- **the biases** are not estimated as state. The heading bias rotates the whole relative
  frame about z, which ranges cannot see: its error ``b e_z × x`` is a floor, added to the
  published covariance (``σ_ψ² (e_z × x)(e_z × x)ᵀ``). The DVL's bias is in the body frame and
  turns with the vehicle, so it does not accumulate into a drift the target's velocity state
  could not follow: it is noise. The sound-speed scale ``(1 + ε)`` is observable only through
  the baseline's share of a range (``|b|²/(4|q|²)``, 6 % at the paper's 2.8 m): its error
  ``ε |q|`` along the line of sight is a floor on the published covariance, and ``(ε z)²`` is
  added to each range's noise;
- **timing**: each range at its own ping time, late ranges when they arrive
  (:mod:`drake_uuv.estimators.ping_window`).

``ideal`` believes navigation and timing perfect: none of the above, and the ranges that
arrive at a tick are taken as measured then, together. It shows what ignoring them costs.
"""

import functools
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.motion import double_integrator
from drake_uuv.models.navigation_noise import (
    NavigationErrors,
    commanded_acceleration_noise,
    heading_bias_floor,
    navigated_velocity_covariance,
    rotation_vector_covariance,
    sound_speed_floor,
)
from drake_uuv.models.timing import PingSchedule


@dataclass(frozen=True)
class ErrorModel:
    """The errors a filter models (all zero for ``error_model: ideal``).

    Its functions take the values of a batch of runs along leading axes (an attitude (…, 3, 3),
    an acceleration (…, 3), ranges (…, 2)). Whether a term is added at all (None otherwise)
    depends on the model alone, never on a run's values.
    """

    errors: NavigationErrors
    schedule: PingSchedule
    sound_speed_error: float = 0.0
    navigated_motion: bool = False  # vehicle_motion: navigation

    @property
    def active(self) -> bool:
        """Whether any navigation or sound-speed error is modelled (timing aside)."""
        return self.errors.any or self.sound_speed_error != 0.0

    @functools.cached_property
    def attitude_noise(self) -> bool:
        return bool(np.any(self.errors.attitude_noise > 0.0))

    @property
    def adds_process_noise(self) -> bool:
        """Whether :meth:`process_noise` adds anything (with the paper's timing)."""
        velocity = self.errors.velocity_noise > 0.0 or self.errors.velocity_bias > 0.0
        if self.navigated_motion:
            return velocity or self.attitude_noise
        return self.attitude_noise

    def attitude_covariance(self, R_WB_nav: np.ndarray) -> np.ndarray | None:
        """``Σ_θ`` (…, 3, 3) of the AHRS noise at navigated attitudes (…, 3, 3); None without
        attitude noise."""
        if not self.attitude_noise:
            return None
        return rotation_vector_covariance(R_WB_nav, self.errors.attitude_noise)

    def range_variance(self, z: np.ndarray) -> np.ndarray | None:
        """Extra variance of each range from the sound speed, ``(ε z)²`` (None without)."""
        if self.sound_speed_error == 0.0:
            return None
        return (self.sound_speed_error * np.nan_to_num(z)) ** 2

    def acceleration_covariance(
        self, a_W: np.ndarray, sigma_theta: np.ndarray | None
    ) -> np.ndarray | None:
        """What the attitude noise ``sigma_theta`` (:meth:`attitude_covariance`) adds to W for a
        step commanded with ``a_W`` (…, 3) (commanded motion only; None otherwise)."""
        if self.navigated_motion or sigma_theta is None:
            return None
        return commanded_acceleration_noise(a_W, sigma_theta)

    def velocity_covariance(
        self, v_W_nav: np.ndarray, sigma_theta: np.ndarray | None
    ) -> np.ndarray | None:
        """``Σ_ev`` (…, 3, 3) of the navigated velocity's error at the navigated velocity
        (…, 3) and the attitude noise ``sigma_theta`` (:meth:`attitude_covariance`):
        ``(σ_v² + σ_b²) I + [v]× Σ_θ [v]×ᵀ`` (navigated motion only; None otherwise or when the
        model makes it zero)."""
        if not self.navigated_motion:
            return None
        errors = self.errors
        if sigma_theta is None and errors.velocity_noise == 0.0 and errors.velocity_bias == 0.0:
            return None
        covariance = navigated_velocity_covariance(
            v_W_nav, sigma_theta, errors.velocity_noise, errors.velocity_bias
        )
        return np.broadcast_to(covariance, np.shape(v_W_nav) + (3,))

    def process_noise(
        self,
        time_step: float,
        a_W: np.ndarray,
        sigma_theta: np.ndarray | None,
        v_W_nav: np.ndarray,
    ) -> np.ndarray | None:
        """What the navigation adds to a step's Q (…, 6, 6) with the paper's timing: the
        commanded acceleration's error through the double integrator (commanded motion), or
        the dead-reckoned position's walk ``t² Σ_ev`` (navigated motion). None when the model
        adds nothing."""
        if not self.adds_process_noise:
            return None
        Q = np.zeros(np.shape(a_W)[:-1] + (6, 6))
        W = self.acceleration_covariance(a_W, sigma_theta)
        if W is not None:
            _, B = double_integrator(time_step)
            Q += B @ W @ B.T
        velocity = self.velocity_covariance(v_W_nav, sigma_theta)
        if velocity is not None:
            Q[..., :3, :3] += (time_step * time_step) * velocity
        return Q

    @property
    def adds_floor(self) -> bool:
        """Whether :meth:`floor` adds anything (with a velocity covariance: always)."""
        return self.active and (self.errors.heading_bias > 0.0 or self.sound_speed_error != 0.0)

    def floor(
        self, x: np.ndarray, velocity_covariance: np.ndarray | None = None
    ) -> np.ndarray | None:
        """What the published covariance adds to the filter's own at the estimates ``x``
        (B, 6; or one estimate (6)): the heading bias's and the sound-speed scale's floors, and
        the navigated velocity's error ``velocity_covariance`` (:meth:`velocity_covariance`;
        None when there is none). None when the model adds nothing."""
        if not self.active or (not self.adds_floor and velocity_covariance is None):
            return None
        x = np.asarray(x, dtype=float)
        single = x.ndim == 1
        x = x.reshape(-1, 6)
        floor = np.zeros((len(x), 6, 6))
        if self.errors.heading_bias > 0.0:
            floor += heading_bias_floor(x[:, :3], x[:, 3:], self.errors.heading_bias)
        if self.sound_speed_error != 0.0:
            floor += sound_speed_floor(x[:, :3], self.sound_speed_error)
        if velocity_covariance is not None:
            floor[:, 3:, 3:] += velocity_covariance
        return floor[0] if single else floor


def ideal_model(time_step: float) -> ErrorModel:
    """The error model of ``error_model: ideal``: nothing, the paper's timing."""
    return ErrorModel(NavigationErrors(), PingSchedule(time_step))
