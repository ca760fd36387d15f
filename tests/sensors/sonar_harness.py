"""The sonar alone, driven tick by tick through a closed-form motion, and what it should output.

:class:`Motion` is a vehicle and a target at constant accelerations, the vehicle turning at a
constant world rate: its geometry at any time is closed-form (Drake's ``AngleAxis`` for the
attitude), independent of the sonar's interpolation. :func:`drive` steps a sonar as the
Simulator does (outputs at tick n from the state before the tick's update, then the update)
with the draws of each tick fixed on its random ports; :func:`expected_arrivals` says, from
the timing model alone, which ping each sonar delivers at each tick and what it measured.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
)
from drake_uuv.scenario import SonarConfig
from drake_uuv.sensors import DualSonar
from tests.conftest import T

#: The outputs a test compares, with their sizes per sonar pair.
OUTPUTS = ("ranges", "range_samples", "Y", "m", "Gamma", "b_W", "sonar_status", "multipath",
           "ping_time", "p_TS_W")  # fmt: skip


def rotation(rotation_vector: np.ndarray) -> np.ndarray:
    """``Exp(rotation_vector)`` by Drake's ``AngleAxis``."""
    angle = float(np.linalg.norm(rotation_vector))
    if angle == 0.0:
        return np.eye(3)
    return RotationMatrix(AngleAxis(angle, rotation_vector / angle)).matrix()


@dataclass
class Motion:
    """Vehicle and target at constant accelerations, the vehicle turning at ``omega`` (W)."""

    p_U0: np.ndarray = field(default_factory=lambda: np.array([0.5, -1.0, 2.0]))
    v_U0: np.ndarray = field(default_factory=lambda: np.array([0.3, -0.2, 0.1]))
    a_U: np.ndarray = field(default_factory=lambda: np.array([0.04, 0.01, -0.03]))
    R0: np.ndarray = field(
        default_factory=lambda: RotationMatrix(RollPitchYaw(0.2, -0.1, 0.7)).matrix()
    )
    omega: np.ndarray = field(default_factory=lambda: np.array([0.3, -0.5, 0.9]))
    p_T0: np.ndarray = field(default_factory=lambda: np.array([3.0, 1.0, -1.0]))
    v_T0: np.ndarray = field(default_factory=lambda: np.array([0.1, 0.2, -0.1]))
    a_T: np.ndarray = field(default_factory=lambda: np.array([-0.02, 0.01, 0.015]))
    baseline: np.ndarray = field(default_factory=lambda: np.array([-1.0, 1.0, 0.0]))

    def inputs(self, t: float) -> dict[str, np.ndarray]:
        """The sonar's geometric inputs at time ``t``."""
        return {
            "p_WU": self.p_U0 + t * self.v_U0 + 0.5 * t * t * self.a_U,
            "v_WU": self.v_U0 + t * self.a_U,
            "R_WB": self.attitude(t).ravel(),
            "R_WB_nav": self.attitude(t).ravel(),  # a perfect navigation: pointing by truth
            "p_WT": self.p_T0 + t * self.v_T0 + 0.5 * t * t * self.a_T,
            "v_WT": self.v_T0 + t * self.a_T,
        }

    def attitude(self, t: float) -> np.ndarray:
        return rotation(self.omega * t) @ self.R0

    def p_TS(self, t: float) -> np.ndarray:
        """Both sonars from the target at ``t`` (2×3): ``q ± ½ R b``."""
        x = self.inputs(t)
        q, half = x["p_WU"] - x["p_WT"], 0.5 * self.attitude(t) @ self.baseline
        return np.array([q + half, q - half])


def drive(
    sonar: DualSonar,
    motion: Motion,
    steps: int,
    draws: dict[str, np.ndarray],
    priors: np.ndarray | None = None,
    covariance: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """The sonar's outputs at ticks 0 … steps − 1 (one row per tick).

    ``draws`` holds each random port's value per tick (steps × size); ``priors`` the
    estimator's predicted relative position per tick (steps × 3, for a beam), with the
    covariance ``covariance`` (6×6) at every tick.
    """
    context = sonar.CreateDefaultContext()
    rows: dict[str, list[np.ndarray]] = {name: [] for name in OUTPUTS}
    for n in range(steps):
        context.SetTime(n * T)
        values = motion.inputs(n * T) | {name: value[n] for name, value in draws.items()}
        if priors is not None:
            values |= {"x_TU_prior": np.r_[priors[n], 0, 0, 0], "P_TU_prior": covariance.ravel()}
        for name, value in values.items():
            if sonar.HasInputPort(name):
                sonar.GetInputPort(name).FixValue(context, value)
        for name in OUTPUTS:
            rows[name].append(np.array(sonar.GetOutputPort(name).Eval(context)))
        if sonar.num_discrete_state_groups():
            context.SetDiscreteState(sonar.EvalUniquePeriodicDiscreteUpdate(context))
    return {name: np.array(value) for name, value in rows.items()}


def standard_draws(steps: int, samples_per_step: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Draws of every random port a sonar may have, a different value at every tick."""
    rng = np.random.default_rng(seed)
    return {
        "range_noise": rng.standard_normal((steps, 2 * samples_per_step)),
        "fault_uniform": rng.uniform(size=(steps, 4)),
        "multipath_noise": rng.exponential(size=(steps, 2)),
    }


def expected_arrivals(
    config: SonarConfig,
    motion: Motion,
    steps: int,
    draws: dict[str, np.ndarray],
    delays: tuple[int, int],
    priors: np.ndarray | None = None,
    search_radius: float = 0.0,
) -> dict[str, np.ndarray]:
    """What arrives at each tick by the timing model: sonar i at tick n delivers the ping of
    step ``j = n − d_i`` (none before its first), sent at ``j t + τ_i``, measured (its noise
    and fault draws) at tick n when ``d_i = 0``, else at tick j + 1; its faults follow its own
    geometry and the prediction ``priors[j]`` of its step."""
    f = config.samples_per_step
    eta = np.asarray(config.noise_variances)
    samples = np.full((steps, 2, f), math.nan)
    status = np.full((steps, 2), NO_ARRIVAL)
    multipath = np.zeros((steps, 2))
    ping_time = np.full((steps, 2), math.nan)
    p_TS_W = np.full((steps, 2, 3), math.nan)
    for n in range(steps):
        for i in range(2):
            j = n - delays[i]
            if j < 0:
                continue
            m = n if delays[i] == 0 else j + 1
            ping_time[n, i] = j * T + config.ping_offsets[i]
            p_TS = motion.p_TS(ping_time[n, i])[i]
            p_TS_W[n, i] = p_TS
            status[n, i] = _ping_status(config, motion, i, ping_time[n, i], p_TS, priors, j,
                                        search_radius)  # fmt: skip
            uniform = draws["fault_uniform"][m]
            if status[n, i] == VALID and uniform[i] < config.dropout_probability[i]:
                status[n, i] = DROPPED
            if uniform[2 + i] < config.outlier_probability:
                multipath[n, i] = config.outlier_scale * draws["multipath_noise"][m][i]
            noise = draws["range_noise"][m][i * f : (i + 1) * f]
            measured = (1.0 + config.sound_speed_error) * np.linalg.norm(p_TS)
            samples[n, i] = measured + math.sqrt(eta[i]) * noise + multipath[n, i]
            if status[n, i] != VALID:
                samples[n, i] = math.nan
    first = samples[:, :, 0]
    return {
        "range_samples": samples.reshape(steps, 2 * f),
        "ranges": first,
        "Y": 0.5 * (first[:, 0] ** 2 - first[:, 1] ** 2),
        "sonar_status": status,
        "multipath": multipath,
        "ping_time": ping_time,
        "p_TS_W": p_TS_W.reshape(steps, 6),
    }


def _ping_status(
    config: SonarConfig,
    motion: Motion,
    sonar: int,
    time: float,
    p_TS: np.ndarray,
    priors: np.ndarray | None,
    step: int,
    search_radius: float,
) -> int:
    """OUT_OF_RANGE beyond the maximum range, OUT_OF_BEAM off the axis to the prediction of
    the ping's step (``priors[step]``), else VALID."""
    if config.max_range is not None and np.linalg.norm(p_TS) > config.max_range:
        return OUT_OF_RANGE
    if config.beam_half_angle_deg is None:
        return VALID
    offset = (0.5 if sonar == 0 else -0.5) * motion.attitude(time) @ motion.baseline
    axis = -(priors[step] + offset)
    distance = np.linalg.norm(axis)
    scanned = math.pi if search_radius >= distance else math.asin(search_radius / distance)
    cone = max(math.radians(config.beam_half_angle_deg), scanned)
    cos_angle = -p_TS @ axis / (np.linalg.norm(p_TS) * np.linalg.norm(axis))
    return OUT_OF_BEAM if cos_angle < math.cos(cone) else VALID
