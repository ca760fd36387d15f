"""The sonar's timing: pings at their offsets, ranges at their arrival ticks, the FIFO, the
sound-speed error and faults at the ping; the default timing is the tick measurement of old."""

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
    paper_measurement,
)
from drake_uuv.scenario import ScenarioError, SonarConfig, load_scenario
from drake_uuv.sensors import DualSonar
from drake_uuv.sensors.sonar_kernels import beam_axis
from drake_uuv.sensors.sonar_timing import arrival_delays
from tests.conftest import ETA_UNEQUAL, T
from tests.sensors.sonar_harness import (
    Motion,
    drive,
    expected_arrivals,
    rotation,
    standard_draws,
)

STEPS = 40


def sonar_of(config: SonarConfig, noise_model: str = "derived") -> DualSonar:
    return DualSonar(config, noise_model=noise_model, time_step=T)


def timed(offsets: list[float], latency: float = 0.0, **fields: object) -> SonarConfig:
    return SonarConfig(noise_variances=ETA_UNEQUAL.tolist(), ping_offsets=offsets,
                       latency=latency, **fields)  # fmt: skip


@pytest.mark.parametrize(
    ("offsets", "latency", "delays"),
    [
        ([0.0, 0.0], 0.0, (0, 0)),  # the paper's: read at the tick
        ([0.0, 0.3], 0.4, (1, 2)),  # 0.4 s and 0.7 s: the next tick and the one after
        ([0.3, 0.0], 0.2, (1, 1)),  # 0.3 + 0.2 = 0.5 s is one step, not two (tolerance)
        ([0.0, 0.25], 0.0, (0, 1)),  # a ping after the tick is known at the next tick
        ([1e-12, 0.0], 0.0, (1, 0)),  # however soon after the tick
        ([0.0, 0.0], 1.0, (2, 2)),
        ([0.49, 0.0], 10 * T, (11, 10)),  # the longest: 10 steps of latency
    ],
)
def test_arrival_delays(offsets: list[float], latency: float, delays: tuple[int, int]) -> None:
    assert arrival_delays(offsets, latency, T) == delays


def test_a_sonar_built_by_hand_checks_its_timing() -> None:
    message = r"^sonar.ping_offsets: must be in \[0, time_step = 0.5\) each, got \[0.0, 0.5\]$"
    with pytest.raises(ValueError, match=message):
        sonar_of(timed([0.0, 0.5]))
    with pytest.raises(ValueError, match=r"^sonar.latency: must be ≥ 0, got -0.1$"):
        sonar_of(timed([0.0, 0.0], -0.1))
    with pytest.raises(ValueError, match=r"^time_step: must be > 0, got 0$"):
        DualSonar(SonarConfig(), noise_model="derived", time_step=0)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("ping_offsets", "[-0.1, 0.0]", r"sonar.ping_offsets: must be ≥ 0 each, got \[-0.1, 0.0\]"),
        ("ping_offsets", "[0.0, 0.5]", r"sonar.ping_offsets: must be < time_step = 0.5 each, got \[0.0, 0.5\]"),
        ("latency", "5.01", r"sonar.latency: must be ≤ 10 time steps = 5 s, got 5.01"),
        ("latency", "-0.2", r"sonar.latency: must be ≥ 0, got -0.2"),
        ("sound_speed_error", "0.1", r"sonar.sound_speed_error: must be in \(−0.1, 0.1\), got 0.1"),
        ("sound_speed_error", "-0.1", r"sonar.sound_speed_error: must be in \(−0.1, 0.1\), got -0.1"),
    ],
)  # fmt: skip
def test_the_scenario_refuses_bad_timing_in_one_line(field: str, value: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=f"^{message}$") as error:
        load_scenario("paper", [f"sonar.{field}={value}"])
    assert "\n" not in str(error.value)


def test_ports_and_state_with_and_without_timing() -> None:
    plain = sonar_of(timed([0.0, 0.0]))
    names = {plain.get_input_port(i).get_name() for i in range(plain.num_input_ports())}
    assert names == {"p_WU", "R_WB", "p_WT", "range_noise"}
    assert plain.num_discrete_state_groups() == 0  # the paper's: direct feedthrough only
    late = sonar_of(timed([0.0, 0.3], 0.4, samples_per_step=3))
    names = {late.get_input_port(i).get_name() for i in range(late.num_input_ports())}
    assert names == {"p_WU", "v_WU", "R_WB", "p_WT", "v_WT", "range_noise"}
    assert late.delays == (1, 2)
    # The previous tick's geometry, and one FIFO slot of 3 samples + 6 for sonar 2 (d = 2).
    assert late.num_discrete_state_groups() == 2
    assert late.CreateDefaultContext().get_discrete_state(1).size() == 9
    sizes = {"ping_time": 2, "p_TS_W": 6, "range_samples": 6}
    assert {name: late.GetOutputPort(name).size() for name in sizes} == sizes


def _old_tick_measurement(
    config: SonarConfig, x: dict[str, np.ndarray], draws: dict[str, np.ndarray], prior, P
) -> dict[str, np.ndarray]:
    """The sonar of before timing, as it computed a tick's outputs (the same operations)."""
    b, eta, f = np.asarray(config.baseline), np.asarray(config.noise_variances), 1
    q_s = x["R_WB"].reshape(3, 3) @ b
    q = x["p_WU"] - x["p_WT"]
    half = 0.5 * q_s
    to_s1, to_s2 = q + half, q - half
    true_ranges = np.array([math.sqrt(float(to_s1 @ to_s1)), math.sqrt(float(to_s2 @ to_s2))])
    samples = true_ranges[:, np.newaxis] + np.sqrt(eta)[:, np.newaxis] * draws[
        "range_noise"
    ].reshape(2, f)
    status = np.zeros(2)
    status[true_ranges > config.max_range] = OUT_OF_RANGE
    radius = config.search_sigma * math.sqrt(max(np.linalg.eigvalsh(P[:3, :3])[-1], 0.0))
    for i, offset in enumerate((0.5 * q_s, -0.5 * q_s)):
        to_target, axis = -(q + offset), -(prior + offset)
        distance = math.sqrt(float(axis @ axis))
        half_angle = max(
            math.radians(config.beam_half_angle_deg),
            math.pi if radius >= distance else math.asin(radius / distance),
        )
        cos_angle = (to_target @ axis) / (
            math.sqrt(float(to_target @ to_target)) * distance + 1e-300
        )
        if status[i] == VALID and cos_angle < math.cos(half_angle):
            status[i] = OUT_OF_BEAM
    uniform = draws["fault_uniform"]
    status[(status == VALID) & (uniform[:2] < config.dropout_probability)] = DROPPED
    multipath = np.where(
        uniform[2:] < config.outlier_probability,
        config.outlier_scale * draws["multipath_noise"],
        0.0,
    )
    samples += multipath[:, np.newaxis]
    samples[status != VALID] = np.nan
    Y, m, gamma = paper_measurement(samples, eta)
    return {"range_samples": samples.ravel(), "ranges": samples[:, 0], "Y": [Y], "m": [m],
            "Gamma": [gamma], "b_W": q_s, "sonar_status": status, "multipath": multipath,
            "ping_time": np.full(2, x["time"]), "p_TS_W": np.r_[to_s1, to_s2]}  # fmt: skip


def test_the_default_timing_is_the_tick_measurement_of_before_bit_for_bit() -> None:
    """Every output of every tick equals the sonar of before timing, with every fault on."""
    config = SonarConfig(noise_variances=ETA_UNEQUAL.tolist(), max_range=6.0,
                         beam_half_angle_deg=25.0, dropout_probability=[0.2, 0.1],
                         outlier_probability=0.3, outlier_scale=0.7)  # fmt: skip
    motion, draws = Motion(), standard_draws(STEPS, 1)
    rng = np.random.default_rng(5)
    P = np.diag([0.02, 0.05, 0.01, 1, 1, 1])
    priors = np.array([motion.p_TS(n * T).mean(axis=0) for n in range(STEPS)])
    priors += rng.normal(scale=1.0, size=priors.shape)
    out = drive(sonar_of(config), motion, STEPS, draws, priors, P)
    statuses = set()
    for n in range(STEPS):
        x = motion.inputs(n * T) | {"time": n * T}
        old = _old_tick_measurement(config, x, {k: v[n] for k, v in draws.items()}, priors[n], P)
        for name, value in old.items():
            assert_array_equal(out[name][n], value, err_msg=f"{name} at tick {n}")
        statuses |= set(old["sonar_status"])
    assert statuses == {VALID, DROPPED, OUT_OF_BEAM, OUT_OF_RANGE}  # every path was taken


SCHEDULES = [
    ([0.0, 0.0], 0.0),
    ([0.1, 0.35], 0.0),
    ([0.0, 0.25], 0.0),
    ([0.0, 0.3], 0.4),
    ([0.3, 0.0], 0.2),
    ([0.0, 0.0], 1.0),
    ([0.49, 0.0], 10 * T),
]


@pytest.mark.parametrize(("offsets", "latency"), SCHEDULES)
@pytest.mark.parametrize("samples_per_step", [1, 3])
def test_each_arriving_range_is_its_ping_s_geometry_and_draws(
    offsets: list[float], latency: float, samples_per_step: int
) -> None:
    """At each tick, each sonar's range is the ping of the step the schedule says, taken at its
    ping time: ``(1 + ε)|p_TS_W| + √η v`` with the draw of the tick that measured it, and
    ``p_TS_W`` the closed-form geometry at the ping (not the interpolation); nothing before
    its first arrival. Over 40 ticks: the FIFO holds up to 10 pings in flight."""
    config = timed(offsets, latency, sound_speed_error=0.02, samples_per_step=samples_per_step)
    sonar = sonar_of(config)
    motion, draws = Motion(), standard_draws(STEPS, samples_per_step)
    out = drive(sonar, motion, STEPS, draws)
    expected = expected_arrivals(config, motion, STEPS, draws, sonar.delays)
    assert_array_equal(out["sonar_status"], expected["sonar_status"])
    for name in ("range_samples", "ranges", "ping_time", "p_TS_W", "multipath"):
        assert_allclose(out[name], expected[name], rtol=0, atol=1e-9, err_msg=name)
    Y = out["Y"][:, 0]
    assert_allclose(Y, expected["Y"], rtol=1e-12, atol=1e-9)
    both = np.all(expected["sonar_status"] == VALID, axis=1)
    assert np.all(np.isnan(Y[~both])) and np.all(np.isnan(out["Gamma"][~both]))
    assert np.all(np.isfinite(out["Gamma"][both]))
    first = max(sonar.delays)
    assert both[first:].all() and not both[:first].any()
    # b_W stays the tick's own baseline.
    b_W = [motion.attitude(n * T) @ motion.baseline for n in range(STEPS)]
    assert_allclose(out["b_W"], b_W, atol=1e-12)


def test_a_known_schedule() -> None:
    """τ = [0, 0.3] s, L = 0.4 s, t = 0.5 s: sonar 1's ping of step k arrives at tick k + 1
    (0.4 s), sonar 2's at k + 2 (0.7 s); nothing before."""
    config = timed([0.0, 0.3], 0.4)
    out = drive(sonar_of(config), Motion(), 6, standard_draws(6, 1))
    assert_array_equal(out["sonar_status"][:3], [[NO_ARRIVAL, NO_ARRIVAL], [VALID, NO_ARRIVAL],
                                                 [VALID, VALID]])  # fmt: skip
    assert np.isnan(out["ranges"][0]).all() and np.isnan(out["ranges"][1, 1])
    assert np.isnan(out["p_TS_W"][0]).all() and np.isnan(out["ping_time"][:2, 1]).all()
    assert_allclose(out["ping_time"][1:, 0], [0.0, 0.5, 1.0, 1.5, 2.0], atol=1e-15)
    assert_allclose(out["ping_time"][2:, 1], [0.3, 0.8, 1.3, 1.8], atol=1e-15)


def test_sound_speed_scales_the_true_range() -> None:
    """ε = 0.05 at the paper's timing: each range is 1.05 × the true one, plus the noise."""
    config = timed([0.0, 0.0], sound_speed_error=0.05)
    motion, draws = Motion(), standard_draws(5, 1)
    out = drive(sonar_of(config), motion, 5, draws)
    true = np.array([np.linalg.norm(motion.p_TS(n * T), axis=1) for n in range(5)])
    noise = np.sqrt(ETA_UNEQUAL) * draws["range_noise"]
    assert_allclose(out["ranges"], 1.05 * true + noise, rtol=1e-14)


def test_faults_follow_the_ping_not_the_tick() -> None:
    """A maximum range, a beam and dropouts and outliers judged at the ping time, the beam
    aimed at the prediction of the ping's step, the draws of the tick that measured it.

    The vehicle turns at 1.1 rad/s and the prediction alternates between good and 3 m off,
    so a sonar that judged at the tick, or aimed at the next tick's prediction, would give
    other statuses (checked): the test can tell them apart."""
    config = timed([0.2, 0.45], 0.6, max_range=9.0, beam_half_angle_deg=12.0,
                   dropout_probability=[0.15, 0.25], outlier_probability=0.2,
                   search_sigma=1.0)  # fmt: skip
    motion = dataclasses.replace(Motion(), omega=np.array([0.2, -0.4, 1.0]))
    draws = standard_draws(STEPS, 1, seed=3)
    priors = np.array([motion.p_TS(n * T).mean(axis=0) for n in range(STEPS)])
    priors[1::2] += [3.0, -1.0, 0.5]
    P = np.diag([1e-4, 1e-4, 1e-4, 1.0, 1.0, 1.0])  # a 1-σ scan of 1 cm: the beam decides
    sonar = sonar_of(config)
    out = drive(sonar, motion, STEPS, draws, priors, P)
    expected = expected_arrivals(config, motion, STEPS, draws, sonar.delays, priors, 0.01)
    assert_array_equal(out["sonar_status"], expected["sonar_status"])
    assert_allclose(out["range_samples"], expected["range_samples"], atol=1e-9)
    assert_allclose(out["multipath"], expected["multipath"], atol=1e-12)
    counts = np.bincount(expected["sonar_status"].ravel().astype(int), minlength=6)
    assert counts[[VALID, DROPPED, OUT_OF_BEAM, OUT_OF_RANGE]].min() >= 2, counts
    assert np.count_nonzero(expected["multipath"]) >= 5
    # The alternatives the sonar must not follow: the next tick's prediction (shifted priors),
    # and the geometry and draws of the tick (the default timing).
    shifted = np.roll(priors, -1, axis=0)
    other = expected_arrivals(config, motion, STEPS, draws, sonar.delays, shifted, 0.01)
    assert np.any(other["sonar_status"] != expected["sonar_status"])
    at_tick = drive(sonar_of(timed([0.0, 0.0], 0.0, **{k: getattr(config, k) for k in (
        "max_range", "beam_half_angle_deg", "dropout_probability", "outlier_probability",
        "search_sigma")})), motion, STEPS, draws, priors, P)  # fmt: skip
    late = expected["sonar_status"][sonar.delays[1] :, 1]
    assert np.any(at_tick["sonar_status"][: len(late), 1] != late)


def test_the_beam_axis_by_the_pointing_attitude() -> None:
    """By the true attitude the axis is the predicted direction; by the navigation's, the
    body-frame aim ``R_navᵀ(−(q_prior ± ½ R_nav b))`` carried by the true attitude."""
    motion = Motion()
    R_true = motion.attitude(0.3)
    q_s = R_true @ motion.baseline
    q_prior = np.array([-2.0, 1.0, 0.5])
    offset = -(0.5 * q_s)  # sonar 2's
    axis = beam_axis(R_true, R_true, q_prior, offset, -1.0, motion.baseline)
    assert_array_equal(axis, -(q_prior - 0.5 * q_s))
    R_nav = rotation(np.array([0.0, 0.0, 0.05])) @ R_true  # a 0.05 rad heading error
    aim_B = R_nav.T @ -(q_prior - 0.5 * R_nav @ motion.baseline)
    axis = beam_axis(R_true, R_nav, q_prior, offset, -1.0, motion.baseline)
    assert_allclose(axis, R_true @ aim_B, atol=1e-14)


def test_the_sonar_points_by_the_navigated_attitude() -> None:
    """A prediction on the target and a 4° beam: by the true attitude every ping returns; by a
    navigation 20° off in heading the pan-tilt looks past the target."""
    config = timed([0.0, 0.0], 0.0, beam_half_angle_deg=4.0, search_sigma=0.0)
    motion = Motion()
    priors = np.array([motion.p_TS(n * T).mean(axis=0) for n in range(6)])
    P = np.eye(6) * 1e-6
    draws = standard_draws(6, 1, seed=1)
    sonar = sonar_of(config)
    assert np.all(drive(sonar, motion, 6, draws, priors, P)["sonar_status"] == VALID)
    turned = dataclasses.replace(motion)
    heading = rotation(np.array([0.0, 0.0, math.radians(20.0)]))
    original = turned.inputs
    turned.inputs = lambda t: original(t) | {"R_WB_nav": (heading @ motion.attitude(t)).ravel()}  # type: ignore[method-assign]
    assert np.all(drive(sonar, turned, 6, draws, priors, P)["sonar_status"] == OUT_OF_BEAM)
