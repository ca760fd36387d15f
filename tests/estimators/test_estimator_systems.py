"""The raw-range estimator LeafSystems (``estimator.type: ekf | iekf``) and the bounds in results.

Each system alone with ``FixValue``d inputs against the pure-numpy filter steps; then the
whole loop: the bounds in ``metrics.json``/``summary.json`` and a seeded Monte Carlo check of
the EKF against the PCRLB through the Drake diagram.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.compare import ESTIMATOR_GROUP, Variant, ratio_tables
from drake_uuv.diagram import make_estimator
from drake_uuv.estimators import RangeDifferenceKalmanFilter, RawRangeEstimator
from drake_uuv.estimators.filters_math import (
    HandoverPolicy,
    RawRangeFilter,
    ekf_update,
    iekf_update,
    range_difference_update,
)
from drake_uuv.estimators.pcrlb import (
    kf_riccati_covariance,
    measurement_information,
    pcrlb_along_trajectory,
)
from drake_uuv.estimators.range_model import (
    process_noise_covariance,
    range_difference_measurement,
    range_measurement,
    relative_model_matrices,
)
from drake_uuv.estimators.raw_range_filter import LINEAR_PHASE, RANGE_PHASE
from drake_uuv.metrics import bound_covariances
from drake_uuv.montecarlo import Study, run_study
from drake_uuv.scenario import ScenarioError, load_scenario
from drake_uuv.sensors.dual_sonar import DROPPED, OUT_OF_BEAM, VALID, range_difference_noise
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.testing import discrete_update, fixed_context

T = 0.5
W = np.diag([0.004, 0.001, 0.001])
ETA = np.array([0.01, 0.02])
F = 3
x0 = np.array([-1.8, -2.3, 0.4, 0.05, 0.0, -0.02])
P0 = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1]) + 0.01
Q_S = np.array([-0.6, 1.1, 0.5])
A_W = np.array([1.0, -3.0, 0.5])
X_TRUE = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
RANGE_PHASE_ONLY = HandoverPolicy(max_linear_steps=0)


def make(method: str = "ekf", handover: HandoverPolicy | None = RANGE_PHASE_ONLY, **kwargs):
    return RawRangeEstimator(T, W, x0, P0, ETA, F, method=method, handover=handover, **kwargs)


def samples(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = range_measurement(X_TRUE, Q_S)
    return (d[:, None] + np.sqrt(ETA)[:, None] * rng.standard_normal((2, F))).ravel()


def inputs(**overrides: np.ndarray) -> dict[str, np.ndarray]:
    values = dict(range_samples=samples(), q_s=Q_S, a_W=A_W, sonar_status=np.zeros(2))
    values.update(overrides)
    return values


def filtered(system, context) -> tuple[np.ndarray, np.ndarray, int, float]:
    return (
        system.GetOutputPort("x_hat").Eval(context),
        system.GetOutputPort("P").Eval(context).reshape(6, 6),
        int(system.GetOutputPort("measurement_status").Eval(context)[0]),
        float(system.GetOutputPort("nis").Eval(context)[0]),
    )


@pytest.mark.parametrize("method", ["ekf", "iekf"])
def test_ports_sizes_and_feedthrough(method: str) -> None:
    system = make(method)
    sizes = {"range_samples": 2 * F, "q_s": 3, "sonar_status": 2, "a_W": 3}
    assert {n: system.GetInputPort(n).size() for n in sizes} == sizes
    assert system.num_input_ports() == len(sizes)
    kf = RangeDifferenceKalmanFilter(T, W, x0, P0)
    outputs = {kf.get_output_port(i).get_name(): kf.get_output_port(i).size()
               for i in range(kf.num_output_ports())}  # fmt: skip
    assert {n: system.GetOutputPort(n).size() for n in outputs} == outputs  # the KF's ports
    assert system.num_output_ports() == len(outputs)
    x_hat = system.GetOutputPort("x_hat").get_index()
    for name in ("range_samples", "q_s", "sonar_status"):
        assert system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    assert not system.HasDirectFeedthrough(system.GetInputPort("a_W").get_index(), x_hat)
    x_prior = system.GetOutputPort("x_prior").get_index()
    assert not any(system.HasDirectFeedthrough(i, x_prior) for i in range(len(sizes)))


@pytest.mark.parametrize("method", ["ekf", "iekf"])
def test_one_range_update_matches_the_numpy_step(method: str) -> None:
    system = make(method)
    context = fixed_context(system, **inputs())
    z = samples().reshape(2, F).mean(axis=1)
    R = np.diag(ETA / F)
    update = ekf_update if method == "ekf" else iekf_update
    x, P, nis = update(x0, P0, z, Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    assert (status, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # The periodic update predicts from the filtered estimate; the phase stays the range one.
    A, B = relative_model_matrices(T)
    assert_allclose(discrete_update(system, context, 0), A @ x + B @ A_W, rtol=1e-13)
    assert_allclose(
        discrete_update(system, context, 1).reshape(6, 6),
        A @ P @ A.T + process_noise_covariance(W, T),
        rtol=1e-13,
    )
    assert_allclose(discrete_update(system, context, system.start_state_index), [RANGE_PHASE, 0])


@pytest.mark.parametrize("missing", [0, 1])
def test_single_sonar_updates_with_its_range_only(missing: int) -> None:
    system = make("ekf")
    status = np.zeros(2)
    status[missing] = DROPPED
    measured = samples().reshape(2, F)
    measured[missing] = np.nan
    context = fixed_context(system, **inputs(range_samples=measured.ravel(), sonar_status=status))
    used = (1 - missing,)
    x, P, nis = ekf_update(x0, P0, measured.mean(axis=1), Q_S, np.diag(ETA / F), sonars=used)
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert np.all(np.isfinite(x_hat))
    assert_allclose(x_hat, x, rtol=1e-13)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-16)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # One range informs one direction: the update differs from the two-range one.
    two, _, _ = ekf_update(x0, P0, samples().reshape(2, F).mean(axis=1), Q_S, np.diag(ETA / F))
    assert not np.allclose(x, two)


def test_no_return_only_predicts() -> None:
    system = make("ekf")
    context = fixed_context(
        system,
        **inputs(range_samples=np.full(2 * F, np.nan), sonar_status=[OUT_OF_BEAM, DROPPED]),
    )
    x_hat, P_hat, code, nis = filtered(system, context)
    assert_allclose(x_hat, x0)
    assert_allclose(P_hat, P0)
    assert code == OUT_OF_BEAM and math.isnan(nis)
    A, B = relative_model_matrices(T)
    assert_allclose(discrete_update(system, context, 0), A @ x0 + B @ A_W, rtol=1e-14)


def test_linear_phase_is_the_papers_kf_on_the_sample_means() -> None:
    """The start uses Y = ½(z1² − z2²) with the sonar's own noise model at variance η/f."""
    system = make("ekf", handover=HandoverPolicy())
    context = fixed_context(system, **inputs())
    assert system.in_linear_phase(context)
    z = samples().reshape(2, F).mean(axis=1)
    m, gamma = range_difference_noise("derived", ETA / F, z * z)
    Y = 0.5 * (z[0] ** 2 - z[1] ** 2)
    x, P, nis = range_difference_update(x0, P0, Y, m, gamma, Q_S)
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13)
    assert_allclose(P_hat, P, rtol=1e-13)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # The numpy reference's own moments (range_model) are the same numbers.
    assert range_difference_measurement(z, ETA / F) == pytest.approx((Y, m, gamma), rel=1e-14)
    # The applied linear update counts towards the hand-over.
    assert_allclose(discrete_update(system, context, system.start_state_index), [LINEAR_PHASE, 1])
    # With one sonar the linear start cannot form Y: predict only, nothing counted.
    measured = samples().reshape(2, F)
    measured[1] = np.nan
    system.GetInputPort("range_samples").FixValue(context, measured.ravel())
    system.GetInputPort("sonar_status").FixValue(context, [VALID, DROPPED])
    x_hat, _, code, _ = filtered(system, context)
    assert_allclose(x_hat, x0) and code == DROPPED
    assert_allclose(discrete_update(system, context, system.start_state_index), [LINEAR_PHASE, 0])


def test_hand_over_happens_and_the_system_tracks_the_numpy_filter() -> None:
    """Stepped alone over 80 steps with a turning baseline: the LeafSystem's estimate,
    covariance and phase equal RawRangeFilter's at every step, and it hands over once."""
    rng = np.random.default_rng(7)
    system = RawRangeEstimator(T, W, np.zeros(6), np.eye(6), ETA, F, method="ekf")
    context = system.CreateDefaultContext()
    A, B = relative_model_matrices(T)
    reference = RawRangeFilter(np.zeros(6), np.eye(6), A, B, process_noise_covariance(W, T), ETA, F)
    x_true = np.array([-2.0, -2.0, 0.0, 0.02, -0.01, 0.0])
    phases = []
    for k in range(80):
        angle = k * math.pi / 24
        q_s = math.sqrt(2) * np.array(
            [math.sin(angle), math.cos(angle), 0.5 * math.cos(k * math.pi / 6)]
        )
        d = range_measurement(x_true, q_s)
        measured = (d[:, None] + np.sqrt(ETA)[:, None] * rng.standard_normal((2, F))).ravel()
        a_W = 0.01 * rng.standard_normal(3)
        for name, value in (("range_samples", measured), ("q_s", q_s), ("a_W", a_W),
                            ("sonar_status", np.zeros(2))):  # fmt: skip
            system.GetInputPort(name).FixValue(context, value)
        phases.append(system.in_linear_phase(context))
        assert phases[-1] == reference.linear_phase
        reference.update(measured, q_s)
        x_hat, P_hat, _, _ = filtered(system, context)
        assert_allclose(x_hat, reference.x, rtol=1e-9, atol=1e-12)
        assert_allclose(P_hat, reference.P, rtol=1e-9, atol=1e-14)
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
        reference.predict(a_W)
        x_true = A @ x_true + B @ a_W
    handover = phases.index(False)
    assert 5 < handover < 60 and not any(phases[handover:])
    assert np.trace(reference.P[:3, :3]) < 0.5


def test_bad_method_and_scenario_values_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^method: must be one of ekf, iekf, got 'ukf'"):
        make("ukf")
    with pytest.raises(ScenarioError, match=r"^estimator.type: must be one of kf, ekf, iekf"):
        load_scenario("paper", ["estimator.type=ukf"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: must be ≥ 0"):
        load_scenario("paper", ["estimator.linear_start_max_steps=-1"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_position_variance"):
        load_scenario("paper", ["estimator.linear_start_position_variance=0"])


@pytest.mark.parametrize("kind", ["ekf", "iekf"])
def test_make_estimator_builds_the_raw_range_filters(kind: str) -> None:
    scenario = load_scenario(
        "paper", [f"estimator.type={kind}", "sonar.samples_per_step=4",
                  "estimator.linear_start_max_steps=50"]
    )  # fmt: skip
    system = make_estimator(scenario)
    assert isinstance(system, RawRangeEstimator) and system.method == kind
    assert system.GetInputPort("range_samples").size() == 8
    assert system.handover == HandoverPolicy(0.5, 1, 50)


# ------------------------------------------------------------------- bounds in the results


def test_run_bounds_are_the_pcrlb_and_the_kf_riccati_on_the_true_trajectory() -> None:
    scenario = load_scenario("paper", ["steps=120", "steady_state_start=60"])
    log = ClosedLoopSimulation(scenario).run(2).log
    bounds = bound_covariances(log, scenario)
    q = log["p_uuv"] - log["p_target"]
    eta = np.asarray(scenario.sonar.noise_variances)
    expected = pcrlb_along_trajectory(q, log["q_s"], np.eye(6), W, eta, 1, T)
    assert_allclose(bounds["pcrlb"], expected, rtol=1e-12, atol=1e-15)
    d = np.stack(
        [range_measurement(np.r_[qk, 0, 0, 0], s) for qk, s in zip(q, log["q_s"], strict=True)]
    )
    gamma = d**2 @ eta + 0.5 * eta @ eta  # the derived Γ on the true ranges
    riccati = kf_riccati_covariance(log["q_s"], np.eye(6), W, gamma, T)
    assert_allclose(bounds["kf_riccati"], riccati, rtol=1e-9, atol=1e-13)


@pytest.fixture(scope="module")
def ekf_study(tmp_path_factory):
    """30 seeded EKF runs through the Drake diagram, 300 steps, steady state k ≥ 100 (the
    hand-over is at k ≈ 30 and the EKF settles within a few tens of steps)."""
    scenario = load_scenario(
        "paper", ["estimator.type=ekf", "steps=300", "steady_state_start=100"], seed=1000
    )
    folder = tmp_path_factory.mktemp("ekf_study")
    return run_study(Study("ekf", scenario, 30, folder), workers=1, progress=False, figures=False)


def _ratio_and_error(result, part: str, bound: float) -> tuple[float, float]:
    """RMSE / bound and its standard error from the run-to-run spread (delta method)."""
    mse = result.column(f"{part}_rmse") ** 2
    se_mse = mse.std(ddof=1) / math.sqrt(mse.size)
    return math.sqrt(mse.mean()) / bound, se_mse / (2 * math.sqrt(mse.mean())) / bound


def test_ekf_through_the_diagram_is_within_1_1_of_the_pcrlb(ekf_study) -> None:
    """Issue 4: the EKF's steady-state RMSE within 1.1× the PCRLB over 30 runs.

    Against the mean of the per-run bounds (what an estimator efficient on every trajectory
    attains) outright; against the proven Monte Carlo bound, which sits ~8 % lower in this
    loop (estimators/pcrlb.py), not significantly above 1.1 (Z = 3 standard errors of the
    run-to-run spread). Never significantly below 1: the bound holds.
    """
    s = ekf_study.summary
    z = 3.0
    for part in ("position", "velocity"):
        per_run, se_run = _ratio_and_error(ekf_study, part, s[f"pcrlb_per_run_{part}_rmse"])
        proven, se = _ratio_and_error(ekf_study, part, s[f"pcrlb_{part}_rmse"])
        assert z * se < 0.1, "30 runs must resolve the 10 % margin"
        assert per_run <= 1.1, f"{part}: {per_run:.3f}× the per-run bound"
        assert proven - z * se <= 1.1, f"{part}: {proven:.3f} ± {se:.3f}× the PCRLB"
        assert proven >= 1.0 - z * se and per_run >= 1.0 - z * se_run
        assert s[f"{part}_rmse_over_pcrlb"] == pytest.approx(proven, rel=1e-12)
        assert s[f"pcrlb_{part}_rmse"] <= s[f"pcrlb_per_run_{part}_rmse"]  # Jensen


def test_ekf_is_consistent_and_the_papers_kf_is_not_efficient(ekf_study, tmp_path) -> None:
    s = ekf_study.summary
    # Mean of 30 runs' time-averaged NEES: the χ²(6·30)/30 band at 99 % is about [4.7, 7.5].
    assert 4.7 < s["nees_mean"] < 7.5
    # The paper's KF on the same seeds: far above the bound, near its own Riccati covariance.
    scenario = load_scenario(
        "paper", ["estimator.type=kf", "steps=300", "steady_state_start=100"], seed=1000
    )
    kf = run_study(Study("kf", scenario, 10, tmp_path), workers=1, progress=False, figures=False)
    k = kf.summary
    assert k["position_rmse_over_pcrlb"] > 2.0
    assert k["position_rmse"] == pytest.approx(k["kf_riccati_position_rmse"], rel=0.25)
    assert s["kf_riccati_position_rmse"] > 2 * s["pcrlb_per_run_position_rmse"]


def test_ratio_tables_pivot_estimator_by_attitude_mode() -> None:
    def summary(position: float, velocity: float) -> dict:
        return {"position_rmse_over_pcrlb": position, "velocity_rmse_over_pcrlb": velocity,
                "position_rmse_over_per_run_pcrlb": position / 1.1,
                "velocity_rmse_over_per_run_pcrlb": velocity and velocity / 1.1}  # fmt: skip

    rows = [
        (Variant(f"{e}-{m}", ESTIMATOR_GROUP, (f"estimator.type={e}", f"attitude.mode={m}")),
         summary(p, v))
        for e, m, p, v in [("kf", "trajectory", 3.0, 1.5), ("ekf", "trajectory", 1.08, 1.01),
                           ("ekf", "random", 1.2, None)]
    ]  # fmt: skip
    rows.append((Variant("other", "another group", ()), summary(77.0, 77.0)))
    text = ratio_tables(rows)
    assert "| estimator | trajectory | random |" in text
    assert "| kf | 3 / 1.5 | — / — |" in text
    assert "| ekf | 1.08 / 1.01 | 1.2 / — |" in text
    assert "77" not in text  # other groups stay out
    assert ratio_tables(rows[-1:]) == ""


def test_bounds_drop_the_information_of_missing_returns() -> None:
    rng = np.random.default_rng(4)
    q, q_s = rng.normal(size=(6, 3)) * 2, rng.normal(size=(6, 3))
    available = np.array([[1, 1], [1, 0], [0, 1], [0, 0], [1, 1], [0, 1]], dtype=bool)
    full = measurement_information(q, q_s, ETA, F)
    masked = measurement_information(q, q_s, ETA, F, available)
    for k, (first, second) in enumerate(available):
        alone = [measurement_information(q[k : k + 1], q_s[k : k + 1], ETA, F, [[i == 0, i == 1]])
                 for i in (0, 1)]  # fmt: skip
        expected = first * alone[0][0] + second * alone[1][0]
        assert_allclose(masked[k], expected, atol=1e-12)
    assert_allclose(masked[[0, 4]], full[[0, 4]])
    # Y needs both ranges: the KF's Riccati recursion only predicts at the other steps.
    gamma = np.full(6, 0.1)
    covs = kf_riccati_covariance(q_s, np.eye(6), W, gamma, T, available)
    A, _ = relative_model_matrices(T)
    Q = process_noise_covariance(W, T)
    assert_allclose(covs[1], A @ covs[0] @ A.T + Q, rtol=1e-12)
    assert_allclose(covs[3], A @ covs[2] @ A.T + Q, rtol=1e-12)
    with pytest.raises(ValueError, match=r"available must have shape \(6, 2\)"):
        measurement_information(q, q_s, ETA, F, available[:3])
