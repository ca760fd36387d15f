"""The cautious loop: the feedback scaled by the covariance, the hold until the hand-over and
the plant's top speed, each in closed form on fixed inputs and run by run in a batch."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.handover import Phase
from drake_uuv.models.tracking_laws import (
    caution_scales,
    paper_gain_matrix,
    speed_limited_acceleration,
)
from drake_uuv.scenario import LqrTracking, PaperTracking, load_scenario
from drake_uuv.testing import assert_batch_equals_runs, fixed_context
from drake_uuv.tracking import LqrTrackingController, PaperTrackingController, TrackingSetting
from tests.conftest import T
from tests.tracking.controllers import SETTING
from tests.tracking.test_tracking_batch import FRAMES, random_inputs

Q_STAR = np.array([-2.0, -2.0, 0.0])
# An estimate 1 m off q* along x, 0.5 m/s along y; the paper's world command is −K (x̂ − [q*, 0]).
X_HAT = np.r_[Q_STAR + [1.0, 0.0, 0.0], 0.0, 0.5, 0.0]
# Position variances 1, 4 and 0.25 m² (the velocity's play no part).
P = np.diag([1.0, 4.0, 0.25, 9.0, 9.0, 9.0])


def covariance(diagonal: list[float]) -> np.ndarray:
    return np.diag(np.r_[diagonal, 1.0, 1.0, 1.0]).ravel()


def test_the_scales_in_closed_form() -> None:
    P_runs = np.stack([covariance([1.0, 4.0, 0.25]), covariance([-1.0, 0.0, 0.0])])
    # σ = 1 m: tr P_qq = 5.25 gives 1/6.25; per axis 1/(1 + P_ii).
    assert_allclose(caution_scales(P_runs, 1.0, "trace")[0], [0.16] * 3, rtol=1e-15)
    assert_allclose(caution_scales(P_runs, 1.0, "axis")[0], [0.5, 0.2, 0.8], rtol=1e-15)
    # σ = 2 m: the reference variance is 4 m².
    assert_allclose(caution_scales(P_runs, 2.0, "axis")[0], [0.8, 0.5, 16 / 17], rtol=1e-15)
    # A negative variance (a broken covariance) counts as none: the law's own gain.
    assert_array = np.testing.assert_array_equal
    assert_array(caution_scales(P_runs, 1.0, "trace")[1], [1.0] * 3)
    assert_array(caution_scales(P_runs, 1.0, "axis")[1], [1.0] * 3)
    nan = covariance([np.nan, 1.0, 1.0])
    assert np.all(np.isnan(caution_scales(nan, 1.0, "trace")))
    assert np.isnan(caution_scales(nan, 1.0, "axis")[0, 0])
    assert_array(caution_scales(nan, 1.0, "axis")[0, 1:], [0.5, 0.5])
    with pytest.raises(ValueError, match=r"^scaling: must be one of trace, axis, got 'sum'$"):
        caution_scales(P_runs, 1.0, "sum")


def test_the_speed_limit_in_closed_form() -> None:
    v = np.array([[0.5, 0.0, 0.0], [0.1, 0.0, 0.0], [2.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    a = np.array([[1.0, 0.8, 0.0], [0.1, 0.1, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    limited = speed_limited_acceleration(v, a, T, 0.76)
    asked = np.array([1.0, 0.4, 0.0])
    assert_allclose(limited[0], (0.76 * asked / np.linalg.norm(asked) - v[0]) / T, rtol=1e-14)
    np.testing.assert_array_equal(limited[1], a[1])  # within the limit: untouched
    assert_allclose(limited[2], [(0.76 - 2.0) / T, 0.0, 0.0], rtol=1e-14)  # too fast: brakes
    assert np.all(np.isnan(limited[3]))
    assert speed_limited_acceleration(v, a, T, None) is a


def paper(**fields) -> PaperTrackingController:
    config = PaperTracking(desired_relative_position=list(Q_STAR), alpha=1.2, **fields)
    return PaperTrackingController(config, setting=SETTING)


def lqr(setting: TrackingSetting = SETTING, **fields) -> LqrTrackingController:
    config = LqrTracking(desired_relative_position=list(Q_STAR), feedforward=False, **fields)
    return LqrTrackingController(config, setting=setting)


def u1_W(system, **inputs) -> np.ndarray:
    return system.GetOutputPort("u1_W").Eval(fixed_context(system, **inputs))


def test_off_the_laws_read_only_their_own_ports() -> None:
    names = [paper().get_input_port(i).get_name() for i in range(paper().num_input_ports())]
    assert names == ["x_TU_hat", "R_WB_nav"]
    on = paper(caution_position_std=1.0, hold_until_handover=True)
    names = [on.get_input_port(i).get_name() for i in range(on.num_input_ports())]
    assert names == ["x_TU_hat", "R_WB_nav", "P_TU", "estimator_phase", "v_WU_nav"]
    limited = lqr(TrackingSetting(time_step=T, max_speed=0.76))
    assert limited.HasInputPort("v_WU_nav") and not limited.HasInputPort("P_TU")


@pytest.mark.parametrize("scaling", ["trace", "axis"])
def test_the_paper_law_scaled_by_the_covariance(scaling: str) -> None:
    R = np.eye(3).ravel()
    full = u1_W(paper(), x_TU_hat=X_HAT, R_WB_nav=R)
    assert_allclose(full, -paper_gain_matrix(T, 1.2) @ (X_HAT - np.r_[Q_STAR, 0, 0, 0]))
    cautious = paper(caution_position_std=1.0, caution_scaling=scaling)
    scaled = u1_W(cautious, x_TU_hat=X_HAT, R_WB_nav=R, P_TU=P.ravel())
    s = [0.16] * 3 if scaling == "trace" else [0.5, 0.2, 0.8]
    assert_allclose(scaled, np.multiply(s, full), rtol=1e-14)
    # A known position (P_qq = 0) leaves the paper's command.
    known = np.diag([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).ravel()
    assert_allclose(u1_W(cautious, x_TU_hat=X_HAT, R_WB_nav=R, P_TU=known), full, rtol=1e-15)


def test_the_lqr_law_scales_its_feedback_not_its_feedforward() -> None:
    config = LqrTracking(desired_relative_position=list(Q_STAR), reference_frame="world")
    plain = LqrTrackingController(config, setting=SETTING)
    config.caution_position_std = 1.0
    cautious = LqrTrackingController(config, setting=SETTING)
    # A plan turning about z: the world reference is fixed, so a_ff = 0 and ν = 0 here.
    R = np.eye(3).ravel()
    inputs = dict(x_TU_hat=X_HAT, R_WB_nav=R, R_WB_plan=np.r_[R, R])
    full = u1_W(plain, **inputs)
    assert_allclose(u1_W(cautious, P_TU=P.ravel(), **inputs), 0.16 * full, rtol=1e-14)
    # With a turning body-fixed q*, the feed-forward stays whole: a = a_ff − s K e.
    config = LqrTracking(desired_relative_position=list(Q_STAR), caution_position_std=1.0)
    turning = LqrTrackingController(config, setting=SETTING)
    c, s = math.cos(0.3), math.sin(0.3)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    plan = np.r_[Rz.ravel(), (Rz @ Rz).ravel()]
    context = fixed_context(turning, x_TU_hat=X_HAT, R_WB_nav=R, R_WB_plan=plan, P_TU=P.ravel())
    reference, a_ff = turning.reference(context)
    expected = a_ff[0] - 0.16 * turning.gain @ (X_HAT - reference[0])
    assert_allclose(turning.acceleration(context)[0], expected, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("law", [paper, lqr])
def test_the_law_holds_station_during_the_linear_start(law) -> None:
    """In the linear start the law's command gives way to one that brings the vehicle to rest."""
    R = np.eye(3).ravel()
    inputs = dict(x_TU_hat=X_HAT, R_WB_nav=R)
    if law is lqr:
        inputs["R_WB_plan"] = np.r_[R, R]
    full = u1_W(law(), **inputs)
    held = law(hold_until_handover=True)
    linear = [float(Phase.LINEAR), 12.0]
    # At rest it stays at rest: no command at all.
    at_rest = u1_W(held, estimator_phase=linear, v_WU_nav=np.zeros(3), **inputs)
    np.testing.assert_array_equal(at_rest, np.zeros(3))
    # Moving (a run sent back to its linear start), it stops in one step: v + t a = 0 ...
    v = np.array([0.3, -0.4, 0.1])
    stopping = u1_W(held, estimator_phase=linear, v_WU_nav=v, **inputs)
    assert_allclose(v + T * stopping, np.zeros(3), atol=1e-15)
    # ... or as fast as the law's acceleration limit lets it, along −v.
    limited = u1_W(law(hold_until_handover=True, max_acceleration=0.2), estimator_phase=linear,
                   v_WU_nav=v, **inputs)  # fmt: skip
    assert_allclose(limited, -0.2 * v / np.linalg.norm(v), rtol=1e-14)
    for phase in (Phase.RANGE, Phase.PARTICLE):
        after = u1_W(held, estimator_phase=[float(phase), 30.0], v_WU_nav=v, **inputs)
        np.testing.assert_array_equal(after, full)


def test_the_law_respects_the_top_speed_and_reports_what_it_applies() -> None:
    R = np.eye(3).ravel()
    inputs = dict(x_TU_hat=X_HAT, R_WB_nav=R, R_WB_plan=np.r_[R, R])
    full = u1_W(lqr(), **inputs)
    limited = lqr(TrackingSetting(time_step=T, max_speed=0.76))
    v = np.array([0.0, 0.7, 0.0])
    got = u1_W(limited, v_WU_nav=v, **inputs)
    assert np.linalg.norm(v + T * full) > 0.76  # the law alone would break the limit
    assert_allclose(np.linalg.norm(v + T * got), 0.76, rtol=1e-14)
    assert_allclose(got, speed_limited_acceleration(v[None], full[None], T, 0.76)[0])
    # u1_B is the same acceleration in the body: what the plant gets is what u1_W says.
    context = fixed_context(limited, v_WU_nav=v, **inputs)
    assert_allclose(limited.GetOutputPort("u1_B").Eval(context), got, rtol=1e-15)


def cautious_inputs(rng: np.random.Generator, B: int, plan: bool) -> dict:
    """Every branch in one batch: estimates near and far, a NaN run; covariances small, wide,
    broken (negative) and NaN; each phase and a NaN one; velocities below, near and beyond
    the top speed."""
    inputs = random_inputs(rng, B, plan=plan)
    variances = rng.uniform(0.0, 5.0, size=(B, 6)) * rng.choice([1e-3, 1.0, 10.0], size=(B, 1))
    if B > 2:
        variances[1, 0] = -1.0
        variances[2, 1] = np.nan
    inputs["P_TU"] = np.stack([np.diag(d).ravel() for d in variances])
    phases = np.array([Phase.LINEAR, Phase.RANGE, Phase.PARTICLE, np.nan], dtype=float)
    inputs["estimator_phase"] = np.stack([phases[np.arange(B) % 4], np.arange(B)], axis=1)
    inputs["v_WU_nav"] = rng.normal(scale=0.6, size=(B, 3))
    return inputs


@pytest.mark.parametrize("batch_size", [1, 2, 5, 8])
@pytest.mark.parametrize("scaling", ["trace", "axis"])
def test_a_cautious_batch_is_each_run_alone(batch_size: int, scaling: str) -> None:
    rng = np.random.default_rng(40 + batch_size)
    setting = TrackingSetting(time_step=T, max_speed=0.76)
    fields = dict(
        caution_position_std=1.0, caution_scaling=scaling, hold_until_handover=True,
        max_acceleration=2.0,
    )  # fmt: skip
    for frame in FRAMES:
        inputs = cautious_inputs(rng, batch_size, plan=True)
        lqr_config = LqrTracking(reference_frame=frame, **fields)
        assert_batch_equals_runs(
            lambda B, c=lqr_config: LqrTrackingController(c, setting=setting, batch_size=B),
            inputs,
        )
        del inputs["R_WB_plan"]
        paper_config = PaperTracking(reference_frame=frame, **fields)
        assert_batch_equals_runs(
            lambda B, c=paper_config: PaperTrackingController(c, setting=setting, batch_size=B),
            inputs,
        )


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("tracking.caution_position_std=0", r"^tracking.caution_position_std: must be > 0, got 0"),
        ("tracking.caution_position_std=-1.5", r"^tracking.caution_position_std: must be > 0"),
        ("tracking.caution_scaling=sum", r"^tracking.caution_scaling: must be one of trace, axis"),
    ],
)
def test_a_bad_caution_is_named(override: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        load_scenario("paper", [override])


def test_a_bad_hold_is_named() -> None:
    config = PaperTracking(hold_until_handover="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^tracking.hold_until_handover: must be true or false"):
        config.validate("tracking")


def test_a_bad_top_speed_in_the_setting_is_named() -> None:
    with pytest.raises(ValueError, match=r"^max_speed: must be None or > 0, got -1.0$"):
        TrackingSetting(time_step=T, max_speed=-1.0)


def test_the_law_s_own_top_speed_and_the_plant_s_the_lower_wins() -> None:
    R = np.eye(3).ravel()
    inputs = dict(x_TU_hat=X_HAT, R_WB_nav=R, R_WB_plan=np.r_[R, R], v_WU_nav=[0.0, 0.7, 0.0])
    own = u1_W(lqr(max_speed=0.5), **inputs)
    assert_allclose(np.linalg.norm(np.array([0.0, 0.7, 0.0]) + T * own), 0.5, rtol=1e-14)
    both = lqr(TrackingSetting(time_step=T, max_speed=0.76), max_speed=0.5)
    np.testing.assert_array_equal(u1_W(both, **inputs), own)
    with pytest.raises(ValueError, match=r"^tracking.max_speed: must be > 0, got -0.5$"):
        load_scenario("paper", ["tracking.max_speed=-0.5"])


def test_the_hold_waits_only_for_an_estimator_that_hands_over() -> None:
    from drake_uuv.tracking import make_tracking_controller, tracking_setting

    held = ["tracking.hold_until_handover=true"]
    with_ekf = make_tracking_controller(load_scenario("paper", [*held, "estimator=Ekf"]))
    assert with_ekf.HasInputPort("estimator_phase")
    # The paper's KF is its own linear start throughout: nothing to wait for, no port.
    paper_kf = load_scenario("paper", held)
    assert not tracking_setting(paper_kf).estimator_hands_over
    assert not make_tracking_controller(paper_kf).HasInputPort("estimator_phase")
