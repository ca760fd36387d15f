"""The raw-range filters alone, with ``FixValue``d inputs, against the plain-numpy steps of
:mod:`drake_uuv.models`: ports, the Gaussian updates (EKF, IEKF, UKF), missing returns, the
linear start, a whole hand-over against composed numpy steps, and the factory."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import AddRandomInputs

from drake_uuv.estimators import RangeFilter, make_estimator
from drake_uuv.models.filters import iekf_update, predict, range_difference_update
from drake_uuv.models.handover import HandoverRule, Phase, ThresholdHandover
from drake_uuv.models.measurement import (
    DROPPED,
    OUT_OF_BEAM,
    VALID,
    range_difference_noise,
    range_measurement,
)
from drake_uuv.models.motion import process_noise_covariance
from drake_uuv.models.unscented import (
    SigmaPointParameters,
    ukf_range_update,
    unscented_range_update,
)
from drake_uuv.scenario import Ekf, ScenarioError, Ukf, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation
from drake_uuv.testing import after_update
from tests.conftest import ETA_UNEQUAL, X0, T, W
from tests.estimators.range_filters import (
    A_W,
    NO_BRIDGE,
    P0,
    Q_S,
    RANGE_ONLY,
    SETTING,
    A,
    B,
    F,
    R,
    context_of,
    filtered,
    make,
    means,
    samples,
)

# The EKF's and the UKF's updates as configured by default.
EKF_UPDATE = Ekf().range_update()
UKF_UPDATE = Ukf().range_update()
UPDATES = {"ekf": EKF_UPDATE, "iekf": iekf_update, "ukf": UKF_UPDATE}


@pytest.mark.parametrize("kind", ["ekf", "iekf", "ukf", "pf"])
@pytest.mark.parametrize("bridge", [False, True])
def test_ports_sizes_and_feedthrough(kind: str, bridge: bool) -> None:
    system = make(kind, particle_bridge=bridge) if kind != "pf" else make(kind)
    particles = kind == "pf" or bridge
    sizes = {"range_samples": 2 * F, "sonar_status": 2, "R_WB_nav": 9, "u1_W": 3}
    if particles:
        sizes["particle_seed"] = 1
    names = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
    assert {n: system.GetInputPort(n).size() for n in names} == sizes
    outputs = {
        "x_TU_hat": 6,
        "P_TU": 36,
        "x_TU_prior": 6,
        "P_TU_prior": 36,
        "measurement_status": 1,
        "nis": 1,
        "estimator_phase": 2,
        "estimator_recovery": 4,
    }  # fmt: skip (the recovery, on by default)
    names = [system.get_output_port(i).get_name() for i in range(system.num_output_ports())]
    assert {n: system.GetOutputPort(n).size() for n in names} == outputs
    x_hat = system.GetOutputPort("x_TU_hat").get_index()
    for name in ("range_samples", "R_WB_nav", "sonar_status"):
        assert system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    for name in ["u1_W", *(["particle_seed"] if particles else [])]:
        assert not system.HasDirectFeedthrough(system.GetInputPort(name).get_index(), x_hat)
    x_prior = system.GetOutputPort("x_TU_prior").get_index()
    assert not any(system.HasDirectFeedthrough(i, x_prior) for i in range(len(sizes)))
    builder = DiagramBuilder()
    builder.AddSystem(system)
    assert AddRandomInputs(T, builder) == int(particles)  # exactly the seed port is random


@pytest.mark.parametrize("kind", ["ekf", "iekf", "ukf"])
def test_range_update_is_the_numpy_update_then_the_prediction(kind: str) -> None:
    system = make(kind, **RANGE_ONLY)
    context = context_of(system)
    x, P, nis = UPDATES[kind](X0, P0, means(), Q_S, R)
    x_hat, P_hat, status, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-15)
    assert (status, nis_hat) == (VALID, pytest.approx(nis, rel=1e-12))
    after = after_update(system, context)
    x_next, P_next = predict(x, P, A_W, A, B, process_noise_covariance(W, T))
    assert_allclose(system.prior(after).x[0], x_next, rtol=1e-13)
    assert_allclose(system.prior(after).P[0], P_next, rtol=1e-12)
    assert system.phase(after) is Phase.RANGE and system.linear_updates(after) == 0


def test_the_world_baseline_is_the_attitude_times_the_body_baseline() -> None:
    system = make("ekf", **RANGE_ONLY)
    angle = 0.9
    R_WB = np.array(
        [[math.cos(angle), -math.sin(angle), 0.0], [math.sin(angle), math.cos(angle), 0.0],
         [0.0, 0.0, 1.0]]
    )  # fmt: skip
    context = context_of(system, R_WB_nav=R_WB.ravel())
    x, _, _ = EKF_UPDATE(X0, P0, means(), R_WB @ Q_S, R)
    assert_allclose(filtered(system, context)[0], x, rtol=1e-13)
    assert_allclose(system.ranges(context).q_s[0], R_WB @ Q_S)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
@pytest.mark.parametrize("missing", [0, 1])
def test_one_sonar_updates_with_its_range_only(kind: str, missing: int) -> None:
    system = make(kind, **RANGE_ONLY)
    status = np.zeros(2)
    status[missing] = DROPPED
    measured = samples().reshape(2, F)
    measured[missing] = np.nan
    context = context_of(system, range_samples=measured.ravel(), sonar_status=status)
    x, P, nis = UPDATES[kind](X0, P0, measured.mean(axis=1), Q_S, R, sonars=(1 - missing,))
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13, atol=1e-15)
    assert_allclose(P_hat, P, rtol=1e-13, atol=1e-16)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-12))
    # One range informs one direction: the update differs from the two-range one.
    assert not np.allclose(x, UPDATES[kind](X0, P0, means(), Q_S, R)[0])


def test_no_return_only_predicts() -> None:
    system = make("ekf", **RANGE_ONLY)
    context = context_of(
        system, range_samples=np.full(2 * F, np.nan), sonar_status=[OUT_OF_BEAM, DROPPED]
    )
    x_hat, P_hat, code, nis = filtered(system, context)
    assert_allclose(x_hat, X0)
    assert_allclose(P_hat, P0)
    assert code == OUT_OF_BEAM and math.isnan(nis)
    assert_allclose(system.prior(after_update(system, context)).x[0], A @ X0 + B @ A_W, rtol=1e-14)


def test_ukf_uses_its_sigma_point_parameters() -> None:
    params = SigmaPointParameters(alpha=0.5, beta=0.0, kappa=0.0)
    update = unscented_range_update(params)
    assert_allclose(
        update(X0, P0, means(), Q_S, R)[0],
        ukf_range_update(X0, P0, means(), Q_S, R, (0, 1), params)[0],
    )
    assert not np.allclose(
        update(X0, P0, means(), Q_S, R)[0], ukf_range_update(X0, P0, means(), Q_S, R)[0]
    )
    with pytest.raises(ValueError, match=r"^kappa: n \+ kappa must be > 0"):
        unscented_range_update(SigmaPointParameters(kappa=-6.0))
    with pytest.raises(
        ValueError, match=r"^parameters: must be SigmaPointParameters, got \(1, 2, 0\)$"
    ):
        unscented_range_update((1, 2, 0))


@pytest.mark.parametrize("kind", ["ekf", "ukf", "pf"])
def test_linear_phase_is_the_papers_kf_on_the_sample_means(kind: str) -> None:
    """The start uses Y = ½(z1² − z2²) with the sonar's own noise model at variance η/f."""
    system = make(kind)
    context = context_of(system)
    assert system.phase(context) is Phase.LINEAR
    z = means()
    m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
    x, P, nis = range_difference_update(X0, P0, 0.5 * (z[0] ** 2 - z[1] ** 2), m, gamma, Q_S)
    x_hat, P_hat, code, nis_hat = filtered(system, context)
    assert_allclose(x_hat, x, rtol=1e-13)
    assert_allclose(P_hat, P, rtol=1e-13)
    assert (code, nis_hat) == (VALID, pytest.approx(nis, rel=1e-13))
    # The applied linear update counts towards the hand-over.
    after = after_update(system, context)
    assert system.phase(after) is Phase.LINEAR and system.linear_updates(after) == 1


@pytest.mark.parametrize("kind", ["ekf", "ukf", "pf"])
def test_a_step_without_both_ranges_only_predicts_in_the_linear_phase(kind: str) -> None:
    system = make(kind)
    measured = samples().reshape(2, F)
    measured[1] = np.nan
    context = context_of(system, range_samples=measured.ravel(), sonar_status=[VALID, DROPPED])
    x_hat, _, code, nis = filtered(system, context)
    assert_allclose(x_hat, X0)
    assert code == DROPPED and math.isnan(nis)
    after = after_update(system, context)
    assert system.phase(after) is Phase.LINEAR and system.linear_updates(after) == 0
    assert_allclose(system.start.prior_share(after)[0], A @ P0 @ A.T, rtol=1e-13)


def test_hand_over_happens_and_the_system_tracks_the_numpy_steps() -> None:
    """Stepped alone over 80 steps with a turning baseline, the LeafSystem's estimate,
    covariance and phase equal those of the numpy steps composed here (linear KF on the
    sample means until the threshold says so, then the EKF), and it hands over once."""
    rng = np.random.default_rng(7)
    system = RangeFilter(Ekf(handover="threshold"), setting=SETTING)
    context = system.CreateDefaultContext()
    Q = process_noise_covariance(W, T)
    policy = ThresholdHandover()
    x, P, linear, linear_steps = np.zeros(6), np.eye(6), True, 0
    x_true = np.array([-2.0, -2.0, 0.0, 0.02, -0.01, 0.0])
    phases = []
    b = Q_S
    for k in range(80):
        angle = k * math.pi / 24
        axis = np.array([math.sin(angle), math.cos(angle), 0.5 * math.cos(k * math.pi / 6)])
        R_WB = _rotation_taking(b, axis)
        q_s = R_WB @ b
        d = range_measurement(x_true, q_s)
        measured = d[:, None] + np.sqrt(ETA_UNEQUAL)[:, None] * rng.standard_normal((2, F))
        a_W = 0.01 * rng.standard_normal(3)
        for name, value in (("range_samples", measured.ravel()), ("R_WB_nav", R_WB.ravel()),
                            ("u1_W", a_W), ("sonar_status", np.zeros(2))):  # fmt: skip
            system.GetInputPort(name).FixValue(context, value)
        phases.append(system.phase(context) is Phase.LINEAR)
        assert phases[-1] == linear
        z = measured.mean(axis=1)
        if linear:
            m, gamma = range_difference_noise("derived", ETA_UNEQUAL / F, z * z)
            x, P, _ = range_difference_update(x, P, 0.5 * (z[0] ** 2 - z[1] ** 2), m, gamma, q_s)
            linear_steps += 1
            linear = not policy.handover_due(P, linear_steps)
        else:
            x, P, _ = EKF_UPDATE(x, P, z, q_s, R)
        x_hat, P_hat, _, _ = filtered(system, context)
        assert_allclose(x_hat, x, rtol=1e-9, atol=1e-12)
        assert_allclose(P_hat, P, rtol=1e-9, atol=1e-14)
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
        x, P = predict(x, P, a_W, A, B, Q)
        x_true = A @ x_true + B @ a_W
    handover = phases.index(False)
    assert 5 < handover < 60 and not any(phases[handover:])
    assert np.trace(P[:3, :3]) < 0.5


def _rotation_taking(b: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The minimal rotation taking the direction of ``b`` to that of ``direction``."""
    u, v = b / np.linalg.norm(b), direction / np.linalg.norm(direction)
    axis = np.cross(u, v)
    s, c = np.linalg.norm(axis), float(u @ v)
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


@pytest.mark.parametrize("tag", ["Ekf", "Iekf", "Ukf", "ParticleFilter"])
def test_make_estimator_builds_the_pieces_the_config_names(tag: str) -> None:
    scenario = load_scenario(
        "paper", [f"estimator=!{tag}", "sonar.samples_per_step=4",
                  "estimator.linear_start_max_steps=50"]
    )  # fmt: skip
    system = make_estimator(scenario)
    assert isinstance(system, RangeFilter)
    assert system.GetInputPort("range_samples").size() == 8
    expected = {
        "Ekf": HandoverRule(max_linear_steps=50, second_order_tolerance=1.0, particle_bridge=True),
        "Iekf": HandoverRule(max_linear_steps=50, second_order_tolerance=1.0, particle_bridge=True),
        "Ukf": HandoverRule(max_linear_steps=50, particle_bridge=True),
        "ParticleFilter": HandoverRule(angle_tolerance=None, max_linear_steps=50),
    }
    assert system.policy == expected[tag]
    assert system.cloud is not None and system.cloud.parameters.count == 5000
    threshold = load_scenario(
        "paper", [f"estimator=!{tag}", "estimator.handover=threshold",
                  "estimator.linear_start_position_variance=0.3"]
    )  # fmt: skip
    policy = make_estimator(threshold).policy
    assert policy == ThresholdHandover(0.3, 1, None)
    # The absolute threshold has no Gaussian test to bridge: particles only without an update.
    assert (make_estimator(threshold).cloud is None) is (tag != "ParticleFilter")


@pytest.mark.parametrize("tag", ["Ekf", "Iekf", "Ukf"])
def test_the_scenario_sets_the_bridge_of_each_gaussian_filter(tag: str) -> None:
    bridged = make_estimator(load_scenario("paper", [f"estimator=!{tag}",
                                                     "estimator.particle_count=300",
                                                     "estimator.particle_fallback_factor=1.5"]))  # fmt: skip
    assert bridged.policy.particle_bridge and bridged.policy.fallback_factor == 1.5
    assert bridged.cloud.parameters.count == 300
    assert bridged.HasInputPort("particle_seed")
    plain = make_estimator(
        load_scenario("paper", [f"estimator=!{tag}", "estimator.particle_bridge=false"])
    )
    assert not plain.policy.particle_bridge and plain.cloud is None
    assert not plain.HasInputPort("particle_seed")


def test_bad_scenario_values_are_refused() -> None:
    with pytest.raises(ScenarioError, match=r"^estimator: unknown variant !Foo \(known: PaperKf"):
        load_scenario("paper", ["estimator=!Foo"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: must be ≥ 0"):
        load_scenario("paper", ["estimator=!Ekf", "estimator.linear_start_max_steps=-1"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_position_variance"):
        load_scenario("paper", ["estimator=!Ekf", "estimator.linear_start_position_variance=0"])
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: unknown field"):
        load_scenario("paper", ["estimator.linear_start_max_steps=3"])  # the paper's KF has none
    with pytest.raises(ScenarioError, match=r"^estimator.linear_start_max_steps: must not be 0"):
        make("pf", linear_start_max_steps=0)


def test_a_filter_without_a_gaussian_update_needs_the_linear_start() -> None:
    class ParticlesOnly(Ekf):
        """A throwaway variant: the EKF's fields, no Gaussian update."""

        def range_update(self) -> None:
            return None

    with pytest.raises(ValueError, match=r"^handover: a filter without a Gaussian update draws"):
        RangeFilter(ParticlesOnly(linear_start_max_steps=0), setting=SETTING)
    assert RangeFilter(ParticlesOnly(), setting=SETTING).cloud is not None


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
        (["estimator=!ParticleFilter", "estimator.particle_kernel=polar"],
         r"^estimator.particle_kernel: must be one of cartesian, range_bearing, got 'polar'$"),
    ],
)  # fmt: skip
def test_bad_bridge_values_name_the_field(overrides: list[str], message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        load_scenario("paper", overrides)


def test_bad_noise_values_name_the_field() -> None:
    with pytest.raises(ScenarioError, match=r"^estimator.noise_model: must be one of derived"):
        make("ukf", noise_model="exact")
    with pytest.raises(ValueError, match=r"^config: must be an estimator's dataclass, got 3"):
        RangeFilter(3, setting=SETTING)


def test_no_bridge_leaves_a_gaussian_filter_without_particles() -> None:
    assert make("ekf", **NO_BRIDGE).cloud is None


@pytest.mark.parametrize(
    ("kind", "offset", "gate", "after"),
    [
        ("ekf", 0.0, 1e-3, Phase.RANGE),  # ranges that agree: the hand-over goes ahead
        ("ekf", 3.0, 1e-3, Phase.LINEAR),  # 3 m beyond the Gaussian's ranges: it waits
        ("ekf", 3.0, None, Phase.RANGE),  # no gate: it goes ahead
        ("pf", 3.0, 1e-3, Phase.LINEAR),
        ("pf", 0.0, 1e-3, Phase.PARTICLE),
    ],
)
def test_a_due_hand_over_waits_while_the_ranges_contradict_its_gaussian(
    kind: str, offset: float, gate: float | None, after: Phase
) -> None:
    """One linear update, after which the hand-over is forced (``linear_start_max_steps:
    1``): it happens unless the tick's raw ranges lie beyond the χ² quantile of 1 − gate
    under the filtered Gaussian (the KF's covariance there is a few dm, the ranges' noise
    centimetres: 3 m is far beyond, the true ranges well inside)."""
    fields = dict(handover="threshold", linear_start_max_steps=1, handover_range_gate=gate)
    system = make(kind, **fields)
    context = context_of(system, range_samples=samples() + offset)
    assert system.phase(context) is Phase.LINEAR
    assert system.phase(after_update(system, context)) is after


@pytest.mark.parametrize("value", [0.0, 1.0, -0.1])
def test_a_hand_over_gate_outside_0_to_1_is_refused_naming_it(value: float) -> None:
    with pytest.raises(
        ScenarioError, match=r"^estimator.handover_range_gate: must be in \(0, 1\), got"
    ):
        load_scenario("paper", ["estimator=Ekf", f"estimator.handover_range_gate={value}"])


@pytest.mark.slow
def test_far_standoff_seed_137_is_kept_by_the_gate_and_by_tempering_alike() -> None:
    """The seed the particle filter lost at 14 m: at its hand-over the ranges' NIS under the
    linear start's Gaussian was 22; the cloud drawn from it kept one particle under Bayes'
    rule, and its covariance lost its rank. The hand-over gate waits for a better start; the
    tempered update, without the gate, keeps 20 particles' worth and the cloud its rank.
    Either way the run ends within 2 m."""
    for overrides in ([], ["estimator.handover_range_gate=null"]):
        kept = ClosedLoopSimulation(load_scenario("far_standoff", overrides)).run_batch([137])
        assert kept.failures == [None], overrides
        assert kept.metrics["final_position_error"][0] < 2.0, overrides


@pytest.mark.slow
def test_a_cloud_drawn_at_28_m_keeps_its_rank() -> None:
    """28 m of standoff in the world frame, σ = 0.1 m, the particle filter and the EKF's
    particle bridge: seed 134's cloud, drawn at the hand-over from a Gaussian 3.6 m wide,
    kept fewer than two particles' worth under Bayes' rule, and the monitor stopped the run
    (covariance not positive definite at step 24). With the tempered update it runs to the
    end, within the 28 m regime's typical error."""
    sets = [
        "sonar.noise_variances=[0.01, 0.01]", "tracking.reference_frame=world",
        "tracking.desired_relative_position=[-20.0, -20.0, 0.0]",
    ]  # fmt: skip
    for estimator in ("estimator=!ParticleFilter", "estimator=!Ekf"):
        scenario = load_scenario("paper", [*sets, estimator])
        kept = ClosedLoopSimulation(scenario).run_batch([134])
        assert kept.failures == [None], estimator
        assert kept.metrics["final_position_error"][0] < 5.0, estimator


def test_the_late_ranges_window_centres_the_range_bearing_kernel_on_the_vehicle(monkeypatch):
    """The realistic scenario (late ranges, navigated motion) on the kinematic plant: every
    resampling of the window's anchor cloud with the range-bearing kernel is told the
    navigated vehicle state at a past tick (the anchor), about which the cloud's mean lies at
    the true relative distance there; the vehicle moves, so the stored frame alone would not
    do."""
    from drake_uuv.estimators import particle_window
    from drake_uuv.models.particle_filter import normalised, resample_regularised
    from drake_uuv.models.range_bearing import range_bearing_frame

    calls = []

    def recorded(particles, log_weights, rng, parameters, **options):
        offset = np.array(options["offset"])  # a view of the window's arrays
        if range_bearing_frame(particles, normalised(log_weights), offset) is not None:
            calls.append((particles.copy(), offset))
        return resample_regularised(particles, log_weights, rng, parameters, **options)

    monkeypatch.setattr(particle_window, "resample_regularised", recorded)
    overrides = [
        "plant=KinematicUuv", "steps=80", "steady_state_start=0", "estimator.particle_count=500",
        "estimator.particle_kernel=range_bearing", "estimator.particle_resample_threshold=0.95",
    ]  # fmt: skip
    result = ClosedLoopSimulation(load_scenario("realistic", overrides)).run()
    log = result.log
    navigated = np.hstack([log["p_WU_nav"], log["v_WU_nav"]])
    distance = np.linalg.norm(log["p_WT"] - log["p_WU"], axis=1)
    assert len(calls) > 10
    ticks = []
    for particles, offset in calls:
        tick = np.flatnonzero(np.all(navigated == offset, axis=1))
        assert tick.size == 1, offset  # the navigated state of one past tick
        ticks.append(tick[0])
        mean_range = np.linalg.norm(particles[:3].mean(axis=1) + offset[:3])
        assert abs(mean_range - distance[tick[0]]) < 1.0, (mean_range, distance[tick[0]])
    # The anchor is one tick back (sonar 2 pings 0.25 s late, its range arrives 0.2 s later:
    # within the next step), and the last periodic update is at the next-to-last tick.
    assert np.array_equal(np.diff(ticks), np.ones(len(ticks) - 1))
    assert ticks[-1] == len(navigated) - 3
    assert np.ptp(navigated[:, :3], axis=0).max() > 1.0  # the vehicle moved


def test_with_late_ranges_the_particle_phase_reports_each_arrived_range_once() -> None:
    """The realistic scenario (sonar 2 pings 0.25 s after sonar 1, each range 0.2 s late) on
    the kinematic plant: at every tick of the particle phase the cloud reports the NIS of the
    ranges that arrived at the tick, with one dimension per valid arrival (the sonars'
    status), finite exactly when one arrived; and the filter's estimate hands them to its
    divergence test as its innovations."""
    overrides = [
        "plant=KinematicUuv",
        "steps=90",
        "steady_state_start=0",
        "estimator.particle_count=500",
    ]
    simulation = ClosedLoopSimulation(load_scenario("realistic", overrides))
    estimator = simulation.built.systems["estimator"]
    simulator = Simulator(simulation.diagram)
    root = simulator.get_mutable_context()
    simulation.built.set_random_context(root, [0])
    simulator.Initialize()
    context = estimator.GetMyContextFromRoot(root)
    status_port = estimator.GetInputPort("sonar_status")
    ticks = 0
    for k in range(1, 90):
        simulator.AdvanceTo(k * simulation.scenario.time_step)
        if not estimator.cloud.live(context).all():
            continue
        ticks += 1
        nis, dof = estimator.cloud.innovations(context)
        arrived = int(np.count_nonzero(status_port.Eval(context) == VALID))
        assert dof[0] == arrived, k
        assert np.isfinite(nis[0]) == (arrived > 0), k
        filtered = estimator.filtered_estimate(context)
        assert filtered.innovation_dof[0] == arrived
        if arrived:
            assert filtered.innovation_nis[0] == nis[0] > 0.0
    assert ticks > 20


LATE_PINGS_LQR = [
    "tracking=LqrTracking", "tracking.reference_frame=world", "sonar.noise_variances=[0.25, 0.25]",
    "sonar.ping_offsets=[0.0, 0.25]", "sonar.latency=0.2", "estimator=!ParticleFilter",
    "estimator.error_model=modelled", "estimator.vehicle_motion=navigation",
]  # fmt: skip


@pytest.mark.slow
def test_with_late_ranges_recovery_keeps_the_particle_filter_run_it_lost() -> None:
    """The LQR world-frame law at σ = 0.5 m with late pings and ranges (sonar 2 0.25 s after
    sonar 1, each 0.2 s late), the particle filter modelling them, seed 541 (one of the 3 in
    1000 it loses without recovery): the cloud drawn at the hand-over is far off, its innovations grow and the
    monitor stops the run at step 66. With recovery (the default) the run returns to its
    linear start once, its window of 10 ticks holding both sonars' ranges at each (20
    dimensions) above the threshold, and ends within 2 m."""

    def run(window: str):
        scenario = load_scenario("paper", [*LATE_PINGS_LQR, f"estimator.recovery_window={window}"])
        return ClosedLoopSimulation(scenario).run_batch([541])

    lost = run("null")
    assert lost.failures[0] is not None and "innovations blew up" in lost.failures[0]
    kept = run("10")
    assert kept.failures == [None]
    assert kept.metrics["final_position_error"][0] < 2.0
    restarts, total, threshold, dimensions = kept.log["estimator_recovery"][0, -1]
    assert (restarts, dimensions) == (1, 20)
    assert total > threshold
