"""The raw-range estimator LeafSystems (``!Ekf``, ``!Iekf``) alone, with ``FixValue``d inputs,
against the plain numpy filter steps of :mod:`drake_uuv.models.filters`."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.estimators import RangeDifferenceKalmanFilter, RawRangeEstimator, make_estimator
from drake_uuv.estimators.raw_range_filter import LINEAR_PHASE, RANGE_PHASE
from drake_uuv.models.filters import (
    HandoverPolicy,
    ekf_update,
    iekf_update,
    predict,
    range_difference_update,
)
from drake_uuv.models.handover import HandoverRule
from drake_uuv.models.measurement import (
    DROPPED,
    OUT_OF_BEAM,
    VALID,
    range_difference_noise,
    range_measurement,
)
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.scenario import ScenarioError, load_scenario
from drake_uuv.testing import discrete_update, fixed_context
from tests.conftest import ETA_UNEQUAL, T, W

F = 3
x0 = np.array([-1.8, -2.3, 0.4, 0.05, 0.0, -0.02])
P0 = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1]) + 0.01
Q_S = np.array([-0.6, 1.1, 0.5])
A_W = np.array([1.0, -3.0, 0.5])
X_TRUE = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
RANGE_PHASE_ONLY = HandoverPolicy(max_linear_steps=0)


def make(method: str = "ekf", handover: HandoverPolicy | None = RANGE_PHASE_ONLY, **kwargs):
    return RawRangeEstimator(
        T, W, x0, P0, ETA_UNEQUAL, F, method=method, handover=handover, **kwargs
    )


def samples(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = range_measurement(X_TRUE, Q_S)
    return (d[:, None] + np.sqrt(ETA_UNEQUAL)[:, None] * rng.standard_normal((2, F))).ravel()


def inputs(**overrides: np.ndarray) -> dict[str, np.ndarray]:
    values = dict(range_samples=samples(), b_W=Q_S, u1_W=A_W, sonar_status=np.zeros(2))
    values.update(overrides)
    return values


def filtered(system, context) -> tuple[np.ndarray, np.ndarray, int, float]:
    return (
        system.GetOutputPort("x_TU_hat").Eval(context),
        system.GetOutputPort("P_TU").Eval(context).reshape(6, 6),
        int(system.GetOutputPort("measurement_status").Eval(context)[0]),
        float(system.GetOutputPort("nis").Eval(context)[0]),
    )


@pytest.mark.parametrize("method", ["ekf", "iekf"])
def test_ports_sizes_and_feedthrough(method: str) -> None:
    system = make(method)
    sizes = {"range_samples": 2 * F, "b_W": 3, "sonar_status": 2, "u1_W": 3}
    assert {n: system.GetInputPort(n).size() for n in sizes} == sizes
    assert system.num_input_ports() == len(sizes)
    kf = RangeDifferenceKalmanFilter(T, W, x0, P0)
    outputs = {kf.get_output_port(i).get_name(): kf.get_output_port(i).size()
               for i in range(kf.num_output_ports())}  # fmt: skip
    assert {n: system.GetOutputPort(n).size() for n in outputs} == outputs  # the KF's ports
    assert system.num_output_ports() == len(outputs)
    x_hat = system.GetOutputPort("x_TU_hat").get_index()
    for name in ("range_samples", "b_W", "sonar_status"):
        assert system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    assert not system.HasDirectFeedthrough(system.GetInputPort("u1_W").get_index(), x_hat)
    x_prior = system.GetOutputPort("x_TU_prior").get_index()
    assert not any(system.HasDirectFeedthrough(i, x_prior) for i in range(len(sizes)))


@pytest.mark.parametrize("method", ["ekf", "iekf"])
def test_one_range_update_matches_the_numpy_step(method: str) -> None:
    system = make(method)
    context = fixed_context(system, **inputs())
    z = samples().reshape(2, F).mean(axis=1)
    R = np.diag(ETA_UNEQUAL / F)
    update = ekf_update if method == "ekf" else iekf_update
    x, P, nis = update(x0, P0, z, Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    assert (status, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # The periodic update predicts from the filtered estimate; the phase stays the range one.
    A, B = double_integrator(T)
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
    x, P, nis = ekf_update(
        x0, P0, measured.mean(axis=1), Q_S, np.diag(ETA_UNEQUAL / F), sonars=used
    )
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert np.all(np.isfinite(x_hat))
    assert_allclose(x_hat, x, rtol=1e-13)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-16)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # One range informs one direction: the update differs from the two-range one.
    two, _, _ = ekf_update(
        x0, P0, samples().reshape(2, F).mean(axis=1), Q_S, np.diag(ETA_UNEQUAL / F)
    )
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
    A, B = double_integrator(T)
    assert_allclose(discrete_update(system, context, 0), A @ x0 + B @ A_W, rtol=1e-14)


def test_linear_phase_is_the_papers_kf_on_the_sample_means() -> None:
    """The start uses Y = ½(z1² − z2²) with the sonar's own noise model at variance η/f."""
    system = make("ekf", handover=HandoverPolicy())
    context = fixed_context(system, **inputs())
    assert system.in_linear_phase(context)
    z = samples().reshape(2, F).mean(axis=1)
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
    Y = 0.5 * (z[0] ** 2 - z[1] ** 2)
    x, P, nis = range_difference_update(x0, P0, Y, m, gamma, Q_S)
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13)
    assert_allclose(P_hat, P, rtol=1e-13)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
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


def test_hand_over_happens_and_the_system_tracks_the_numpy_steps() -> None:
    """Stepped alone over 80 steps with a turning baseline, the LeafSystem's estimate,
    covariance and phase equal those of the numpy steps composed here (linear KF on the
    sample means until the hand-over policy says so, then the EKF), and it hands over once."""
    rng = np.random.default_rng(7)
    system = RawRangeEstimator(
        T, W, np.zeros(6), np.eye(6), ETA_UNEQUAL, F, method="ekf", handover=HandoverPolicy()
    )
    context = system.CreateDefaultContext()
    A, B = double_integrator(T)
    Q = process_noise_covariance(W, T)
    policy = HandoverPolicy()
    x, P, linear, linear_steps = np.zeros(6), np.eye(6), True, 0
    x_true = np.array([-2.0, -2.0, 0.0, 0.02, -0.01, 0.0])
    phases = []
    for k in range(80):
        angle = k * math.pi / 24
        q_s = math.sqrt(2) * np.array(
            [math.sin(angle), math.cos(angle), 0.5 * math.cos(k * math.pi / 6)]
        )
        d = range_measurement(x_true, q_s)
        measured = d[:, None] + np.sqrt(ETA_UNEQUAL)[:, None] * rng.standard_normal((2, F))
        a_W = 0.01 * rng.standard_normal(3)
        for name, value in (("range_samples", measured.ravel()), ("b_W", q_s), ("u1_W", a_W),
                            ("sonar_status", np.zeros(2))):  # fmt: skip
            system.GetInputPort(name).FixValue(context, value)
        phases.append(system.in_linear_phase(context))
        assert phases[-1] == linear
        z = measured.mean(axis=1)
        if linear:
            m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
            x, P, _ = range_difference_update(x, P, 0.5 * (z[0] ** 2 - z[1] ** 2), m, gamma, q_s)
            linear_steps += 1
            linear = not policy.handover_due(P, linear_steps)
        else:
            x, P, _ = ekf_update(x, P, z, q_s, np.diag(ETA_UNEQUAL / F))
        x_hat, P_hat, _, _ = filtered(system, context)
        assert_allclose(x_hat, x, rtol=1e-9, atol=1e-12)
        assert_allclose(P_hat, P, rtol=1e-9, atol=1e-14)
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
        x, P = predict(x, P, a_W, A, B, Q)
        x_true = A @ x_true + B @ a_W
    handover = phases.index(False)
    assert 5 < handover < 60 and not any(phases[handover:])
    assert np.trace(P[:3, :3]) < 0.5


def test_bad_method_and_scenario_values_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^method: must be one of ekf, iekf, got 'ukf'"):
        make("ukf")
    with pytest.raises(ScenarioError, match=r"^estimator: unknown variant !Foo \(known: !PaperKf"):
        load_scenario("paper", ["estimator=!Foo"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: must be ≥ 0"):
        load_scenario("paper", ["estimator=!Ekf", "estimator.linear_start_max_steps=-1"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_position_variance"):
        load_scenario("paper", ["estimator=!Ekf", "estimator.linear_start_position_variance=0"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: unknown field"):
        load_scenario("paper", ["estimator.linear_start_max_steps=3"])  # the paper's KF has none


@pytest.mark.parametrize("kind, tag", [("ekf", "Ekf"), ("iekf", "Iekf")])
def test_make_estimator_builds_the_raw_range_filters(kind: str, tag: str) -> None:
    scenario = load_scenario(
        "paper", [f"estimator=!{tag}", "sonar.samples_per_step=4",
                  "estimator.linear_start_max_steps=50"]
    )  # fmt: skip
    system = make_estimator(scenario)
    assert isinstance(system, RawRangeEstimator) and system.method == kind
    assert system.GetInputPort("range_samples").size() == 8
    assert system.handover == HandoverRule(
        max_linear_steps=50, second_order_tolerance=1.0, particle_bridge=True
    )
    threshold = load_scenario(
        "paper", [f"estimator=!{tag}", "estimator.handover=threshold",
                  "estimator.linear_start_position_variance=0.3"]
    )  # fmt: skip
    assert make_estimator(threshold).handover == HandoverPolicy(0.3, 1, None)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["estimator=!Ukf", "estimator.particle_fallback_factor=0.5"],
         r"^estimator.particle_fallback_factor: must be ≥ 1, got 0.5$"),
        (["estimator=!Ekf", "estimator.handover_angle=null"],
         r"^estimator.handover_angle: must be set with particle_bridge .*, got None$"),
        (["estimator=!Ekf", "estimator.particle_count=5"],
         r"^estimator.particle_count: must be in \[10, 1e7\], got 5$"),
        (["estimator=!PaperKf", "estimator.particle_bridge=true"],
         r"^estimator.particle_bridge: unknown field"),
        (["estimator=!ParticleFilter", "estimator.particle_bridge=false"],
         r"^estimator.particle_bridge: unknown field"),
    ],
)  # fmt: skip
def test_bad_bridge_values_name_the_field(overrides: list[str], message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", overrides)


@pytest.mark.parametrize("tag", ["Ekf", "Iekf", "Ukf"])
def test_the_scenario_sets_the_bridge_of_each_gaussian_filter(tag: str) -> None:
    bridged = make_estimator(load_scenario("paper", [f"estimator=!{tag}",
                                                     "estimator.particle_count=300",
                                                     "estimator.particle_fallback_factor=1.5"]))  # fmt: skip
    assert bridged.handover.particle_bridge and bridged.handover.fallback_factor == 1.5
    assert bridged.particle_parameters.count == 300
    assert bridged.HasInputPort("particle_seed")
    plain = make_estimator(
        load_scenario("paper", [f"estimator=!{tag}", "estimator.particle_bridge=false"])
    )
    assert not plain.handover.particle_bridge and plain.particle_parameters is None
    assert not plain.HasInputPort("particle_seed")
    # The absolute threshold has no Gaussian test to bridge: no particles either.
    threshold = make_estimator(
        load_scenario("paper", [f"estimator=!{tag}", "estimator.handover=threshold"])
    )
    assert threshold.particle_parameters is None
