"""The dual sonar alone: ports, noise-free geometry, noise scaling, the Y-noise moments."""

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.measurement import range_difference_noise
from drake_uuv.scenario import SonarConfig
from drake_uuv.sensors import DualSonar
from drake_uuv.testing import fixed_context
from tests.conftest import T

b = np.array([-1.0, 1.0, 0.0])
eta = np.array([0.01, 0.04])
R = RotationMatrix(RollPitchYaw(0.2, -0.1, 0.7)).matrix()
p_WU = np.array([0.5, -1.0, 2.0])
p_WT = np.array([3.0, 1.0, -1.0])


def sonar_of(samples_per_step: int = 1, noise_model: str = "derived") -> DualSonar:
    """The sonars with baseline b and variances η (no faults)."""
    config = SonarConfig(b.tolist(), eta.tolist(), samples_per_step)
    return DualSonar(config, noise_model=noise_model, time_step=T)


def context_for(sonar: DualSonar, noise: np.ndarray):
    return fixed_context(
        sonar,
        p_WU=p_WU,
        R_WB=R.ravel(),
        p_WT=p_WT,
        range_noise=noise,
    )


def test_ports() -> None:
    sonar = sonar_of(samples_per_step=4)
    sizes = {"p_WU": 3, "R_WB": 9, "p_WT": 3, "range_noise": 8}
    inputs = [sonar.get_input_port(i) for i in range(sonar.num_input_ports())]
    assert {p.get_name(): p.size() for p in inputs} == sizes
    outputs = {"ranges": 2, "range_samples": 8, "Y": 1, "m": 1, "Gamma": 1, "b_W": 3,
               "sonar_status": 2, "multipath": 2, "ping_time": 2, "p_TS_W": 6}  # fmt: skip
    ports = [sonar.get_output_port(i) for i in range(sonar.num_output_ports())]
    assert {p.get_name(): p.size() for p in ports} == outputs


def test_noise_free_ranges_and_linear_measurement() -> None:
    sonar = sonar_of()
    context = context_for(sonar, np.zeros(2))
    q_s = R @ b
    p_s1, p_s2 = p_WU + 0.5 * q_s, p_WU - 0.5 * q_s
    d = [np.linalg.norm(p_s1 - p_WT), np.linalg.norm(p_s2 - p_WT)]
    assert_allclose(sonar.GetOutputPort("ranges").Eval(context), d, rtol=1e-14)
    assert_allclose(sonar.GetOutputPort("b_W").Eval(context), q_s, rtol=1e-14)
    # Y = ½(d1² − d2²) = q_sᵀ q exactly when there is no noise.
    q = p_WU - p_WT
    assert_allclose(sonar.GetOutputPort("Y").Eval(context), [q_s @ q], rtol=1e-12)


def test_noise_is_scaled_by_sqrt_eta_and_first_sample_forms_Y() -> None:
    sonar = sonar_of(samples_per_step=3)
    noise = np.array([1.0, -2.0, 0.5, 0.3, 1.1, -0.7])
    context = context_for(sonar, noise)
    clean = sonar.GetOutputPort("ranges").Eval(context_for(sonar, np.zeros(6)))
    samples = sonar.GetOutputPort("range_samples").Eval(context).reshape(2, 3)
    assert_allclose(samples, clean[:, None] + np.sqrt(eta)[:, None] * noise.reshape(2, 3))
    d1, d2 = samples[:, 0]
    assert_allclose(sonar.GetOutputPort("ranges").Eval(context), [d1, d2])
    assert_allclose(sonar.GetOutputPort("Y").Eval(context), [0.5 * (d1**2 - d2**2)])
    mean_squares = np.mean(samples**2, axis=1)
    m, gamma = range_difference_noise("derived", eta, mean_squares)
    assert_allclose(sonar.GetOutputPort("m").Eval(context), [m])
    assert_allclose(sonar.GetOutputPort("Gamma").Eval(context), [gamma])


def test_derived_model_matches_the_noise_statistics() -> None:
    """Monte Carlo of v̄ = Y − q_sᵀ q: its mean and variance are the derived m and Γ."""
    rng = np.random.default_rng(7)
    n = 200_000
    d_true = np.array([3.0, 4.5])
    v = rng.standard_normal((n, 2)) * np.sqrt(eta)
    d = d_true + v
    noise = 0.5 * (d[:, 0] ** 2 - d[:, 1] ** 2) - 0.5 * (d_true[0] ** 2 - d_true[1] ** 2)
    m, gamma = range_difference_noise("derived", eta, d_true**2 + eta)
    # Tolerances: 5 standard errors of the sample mean and of the sample variance.
    assert abs(noise.mean() - m) < 5 * np.sqrt(gamma / n)
    fourth = np.mean((noise - noise.mean()) ** 4)
    assert abs(noise.var() - gamma) < 5 * np.sqrt((fourth - gamma**2) / n)


def test_m_and_gamma_follow_the_given_noise_model() -> None:
    """The builder passes the estimator's noise model; the sonar publishes its m and Γ."""
    noise = np.array([0.4, -0.9])
    printed = sonar_of(noise_model="paper_printed")
    context = context_for(printed, noise)
    samples = printed.GetOutputPort("range_samples").Eval(context)
    m, gamma = range_difference_noise("paper_printed", eta, samples**2)
    assert_allclose(printed.GetOutputPort("m").Eval(context), [eta.sum()])
    assert_allclose(printed.GetOutputPort("Gamma").Eval(context), [gamma])
    assert m == eta.sum()
    with pytest.raises(ValueError, match=r"noise_model: must be derived or paper_printed"):
        sonar_of(noise_model="exact")


@pytest.mark.parametrize(
    ("samples_per_step", "noise_model", "sound_speed_error"),
    [(1, "derived", 0.0), (3, "derived", 0.02), (2, "paper_printed", -0.01)],
)
def test_a_sonar_without_faults_gives_the_faulty_path_s_outputs_to_the_bit(
    samples_per_step: int, noise_model: str, sound_speed_error: float
) -> None:
    """The plain sonar's direct output against the pings' path, which a range limit no
    target reaches switches on: the same numbers, every port."""
    config = SonarConfig(
        b.tolist(), eta.tolist(), samples_per_step, sound_speed_error=sound_speed_error
    )
    limited = dataclasses.replace(config, max_range=1e9)
    noise = np.random.default_rng(3).standard_normal(2 * samples_per_step)
    plain = DualSonar(config, noise_model=noise_model, time_step=T)
    pinged = DualSonar(limited, noise_model=noise_model, time_step=T)
    a, c = context_for(plain, noise), context_for(pinged, noise)
    a.SetTime(2.5), c.SetTime(2.5)
    for i in range(plain.num_output_ports()):
        x, y = plain.get_output_port(i).Eval(a), pinged.get_output_port(i).Eval(c)
        assert np.array_equal(x, y), plain.get_output_port(i).get_name()
    assert_allclose(plain.GetOutputPort("ping_time").Eval(a), [2.5, 2.5])
