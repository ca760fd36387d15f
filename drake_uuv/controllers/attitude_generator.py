"""Attitude commands that make the sonar baseline persistently exciting (Algorithms 1 and 2)."""

import functools
import math

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_uuv.so3 import exp_so3, log_so3, matrix_from_quaternion, minimal_rotation, norm


def zeta(
    k: int, baseline_norm: float, rho: float, h_amplitude: float, h_frequency: float
) -> np.ndarray:
    """Algorithm 2's desired baseline direction ``ζ(k) = |b| [sin(ρkπ), cos(ρkπ), h(k)]``.

    ``h(k) = h_amplitude · cos(h_frequency · kπ)``; the paper uses ρ = 1/24, h = ½ cos(kπ/6).
    """
    return baseline_norm * np.array(
        [
            math.sin(rho * k * math.pi),
            math.cos(rho * k * math.pi),
            h_amplitude * math.cos(h_frequency * k * math.pi),
        ]
    )


class AttitudeGenerator(LeafSystem):
    """The attitude command ``u2(k) = Log(R̄(k) R(k)ᵀ) / t`` so that ``R(k+1) = R̄(k)``.

    ``mode``:

    - ``fixed``: ``u2 = 0`` (the baseline never moves: the filter is not observable).
    - ``random`` (Algorithm 1): ``R̄(k)`` uniformly random, from a normalised standard-normal
      4-vector (a uniformly distributed unit quaternion).
    - ``trajectory`` (Algorithm 2): ``R̄(k)`` the minimal rotation taking ``b`` to the direction of
      ``ζ(k)``, so ``q_s(k+1) ∥ ζ(k)``.

    With ``max_angular_rate`` the command is scaled down to that norm: the attitude then moves
    towards ``R̄(k)`` along the same geodesic without reaching it in one step.

    ``u2`` is a world-frame rate, as the plant (paper eq. 2) left-multiplies by ``Exp(u2 t)``.

    The generator also publishes its *plan*, the attitudes ``R(k+1)`` and ``R(k+2)`` it will
    produce, for a tracking controller that feeds the turning reference ``R q*`` forward.
    ``R(k+1) = Exp(u2(k) t) R(k)`` is known in every mode. ``R(k+2)`` is known for Algorithm 2
    (a deterministic trajectory: the generator rolls its own law one step further, including
    any rate limit) and for ``fixed``; Algorithm 1 draws ``R̄(k+1)`` only at step k+1, so its
    plan holds ``R(k+2) = R(k+1)``.

    .. pydrake_system::

        name: AttitudeGenerator
        input_ports:
        - R_WB
        - rotation_noise
        output_ports:
        - w_W
        - R_WB_plan

    - ``R_WB`` (9, row-major): the current attitude.
    - ``rotation_noise`` (4, random, standard normal): only in ``random`` mode.
    - ``w_W`` (3): the angular velocity command ``u2`` [rad/s].
    - ``R_WB_plan`` (18): the planned ``R(k+1)`` and ``R(k+2)``, each row-major (see above).
    """

    def __init__(
        self,
        mode: str,
        time_step: float,
        baseline_B: np.ndarray,
        rho: float = 1.0 / 24.0,
        h_amplitude: float = 0.5,
        h_frequency: float = 1.0 / 6.0,
        max_angular_rate: float | None = None,
    ) -> None:
        super().__init__()
        if mode not in ("fixed", "random", "trajectory"):
            raise ValueError(
                f"attitude.mode: must be one of fixed, random, trajectory, got {mode!r}"
            )
        self._mode = mode
        self._time_step = float(time_step)
        self._b = np.asarray(baseline_B, dtype=float)
        self._b_norm = float(np.linalg.norm(self._b))
        self._rho, self._h_amplitude, self._h_frequency = rho, h_amplitude, h_frequency
        self._max_rate = max_angular_rate
        # R̄(k) of Algorithm 2 depends on k alone: every run of a Monte Carlo study reuses it.
        self._trajectory_attitude = functools.lru_cache(maxsize=4096)(self._trajectory_attitude)
        self._attitude_port = self.DeclareVectorInputPort("R_WB", 9)
        self._noise_port = (
            self.DeclareVectorInputPort("rotation_noise", 4, RandomDistribution.kGaussian)
            if mode == "random"
            else None
        )
        self.DeclareVectorOutputPort("w_W", 3, self._calc_rate)
        self.DeclareVectorOutputPort("R_WB_plan", 18, self._calc_plan)

    @property
    def mode(self) -> str:
        return self._mode

    def step_index(self, context: Context) -> int:
        """The sample index k of the context's time."""
        return round(context.get_time() / self._time_step)

    def desired_attitude(self, context: Context) -> np.ndarray | None:
        """``R̄(k)``, or None in ``fixed`` mode."""
        if self._mode == "random":
            quaternion = self._noise_port.Eval(context)
            return matrix_from_quaternion(quaternion / norm(quaternion))
        if self._mode == "trajectory":
            return self._trajectory_attitude(self.step_index(context))
        return None

    def _trajectory_attitude(self, k: int) -> np.ndarray:
        """Algorithm 2's ``R̄(k)``: the minimal rotation taking ``b`` along ``ζ(k)``."""
        target = zeta(k, self._b_norm, self._rho, self._h_amplitude, self._h_frequency)
        return minimal_rotation(self._b, target)

    def _command(self, R_desired: np.ndarray, R_WB: np.ndarray) -> np.ndarray:
        """``u2 = Log(R̄ Rᵀ) / t``, scaled down to ``max_angular_rate`` if that is set."""
        rate = log_so3(R_desired @ R_WB.T) / self._time_step
        if self._max_rate is not None:
            rate_norm = norm(rate)
            if rate_norm > self._max_rate:
                rate *= self._max_rate / rate_norm
        return rate

    def _calc_rate(self, context: Context, output: BasicVector) -> None:
        R_desired = self.desired_attitude(context)
        if R_desired is None:
            output.SetZero()
            return
        output.set_value(self._command(R_desired, self._attitude_port.Eval(context).reshape(3, 3)))

    def planned_attitudes(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """``(R(k+1), R(k+2))`` as this generator will command them (see the class notes)."""
        R_WB = self._attitude_port.Eval(context).reshape(3, 3)
        R_desired = self.desired_attitude(context)
        if R_desired is None:
            return R_WB, R_WB
        t = self._time_step
        R_next = exp_so3(self._command(R_desired, R_WB) * t) @ R_WB
        if self._mode != "trajectory":
            return R_next, R_next
        R_desired_next = self._trajectory_attitude(self.step_index(context) + 1)
        return R_next, exp_so3(self._command(R_desired_next, R_next) * t) @ R_next

    def _calc_plan(self, context: Context, output: BasicVector) -> None:
        R_next, R_after = self.planned_attitudes(context)
        output.set_value(np.concatenate([R_next.ravel(), R_after.ravel()]))
