"""A batch of runs through the tracking laws: each run's bits are its own, whatever the batch."""

import math

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix

from drake_uuv.models.tracking_laws import heading_rotations, rotate, saturate_norm
from drake_uuv.scenario import LqrTracking, PaperTracking, load_scenario
from drake_uuv.testing import assert_batch_equals_runs
from drake_uuv.tracking import (
    LqrTrackingController,
    PaperTrackingController,
    make_tracking_controller,
)
from tests.tracking.controllers import SETTING

FRAMES = ("body", "world", "heading")


def attitudes(rng: np.random.Generator, batch_size: int) -> np.ndarray:
    """Random attitudes (B×9); run 1 has its x axis vertical (the heading's other branch)."""
    R = [RotationMatrix(RollPitchYaw(rng.normal(size=3))).matrix() for _ in range(batch_size)]
    if batch_size > 1:
        R[1] = RotationMatrix(RollPitchYaw(0.3, -math.pi / 2, 0.0)).matrix()
    return np.array(R).reshape(batch_size, 9)


def random_inputs(rng: np.random.Generator, batch_size: int, plan: bool) -> dict:
    """Estimates near the body-fixed q* = [−2, −2, 0] (odd runs, within 1 cm: unsaturated
    with a limit of 2 m/s²) or metres off (even runs: saturated), a NaN run last when the
    batch has four runs or more."""
    R = attitudes(rng, batch_size)
    x_hat = rng.normal(scale=0.01, size=(batch_size, 6))
    x_hat[::2] *= 300.0
    x_hat[:, :3] += R.reshape(-1, 3, 3) @ [-2.0, -2.0, 0.0]
    inputs = {"x_TU_hat": x_hat, "R_WB_nav": R}
    if plan:
        inputs["R_WB_plan"] = np.hstack([attitudes(rng, batch_size), attitudes(rng, batch_size)])
    if batch_size >= 4:
        inputs["x_TU_hat"][-1, 2] = np.nan
    return inputs


@pytest.mark.parametrize("batch_size", [1, 2, 5])
@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("limit", [None, 2.0])
def test_a_paper_batch_is_each_run_alone(batch_size: int, frame: str, limit: float | None) -> None:
    rng = np.random.default_rng(batch_size)
    config = PaperTracking(reference_frame=frame, max_acceleration=limit)

    def make(B: int) -> PaperTrackingController:
        return PaperTrackingController(config, setting=SETTING, batch_size=B)

    assert_batch_equals_runs(make, random_inputs(rng, batch_size, plan=False))


@pytest.mark.parametrize("batch_size", [1, 2, 5])
@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize(("limit", "feedforward"), [(None, True), (2.0, True), (2.0, False)])
def test_an_lqr_batch_is_each_run_alone(
    batch_size: int, frame: str, limit: float | None, feedforward: bool
) -> None:
    rng = np.random.default_rng(10 + batch_size)
    config = LqrTracking(reference_frame=frame, max_acceleration=limit, feedforward=feedforward)

    def make(B: int) -> LqrTrackingController:
        return LqrTrackingController(config, setting=SETTING, batch_size=B)

    assert_batch_equals_runs(make, random_inputs(rng, batch_size, plan=True))


@pytest.mark.parametrize("tracking", ["!PaperTracking", "!LqrTracking"])
def test_a_nan_run_leaves_the_others_and_the_limit_holds_per_run(tracking: str) -> None:
    scenario = load_scenario("paper", [f"tracking={tracking}", "tracking.max_acceleration=2.0"])
    B = 6
    rng = np.random.default_rng(3)
    inputs = random_inputs(rng, B, plan=True)
    batch = make_tracking_controller(scenario, batch_size=B)
    assert batch.batch_size == B
    context = batch.CreateDefaultContext()
    for name in ("x_TU_hat", "R_WB_nav", "R_WB_plan"):
        if batch.HasInputPort(name):
            batch.GetInputPort(name).FixValue(context, inputs[name].ravel())
    u1_W = batch.GetOutputPort("u1_W").Eval(context).reshape(B, 3)
    assert np.all(np.isnan(u1_W[-1]))
    norms = np.linalg.norm(u1_W[:-1], axis=1)
    assert np.all(norms <= 2.0 + 1e-12)
    assert np.any(np.isclose(norms, 2.0)) and np.any(norms < 1.9)  # both branches ran
    # The gain is the batch's, the same for every run: the one of a single run.
    single = make_tracking_controller(scenario)
    np.testing.assert_array_equal(batch.gain, single.gain)


def test_batched_helpers_match_one_at_a_time() -> None:
    rng = np.random.default_rng(4)
    R = attitudes(rng, 5).reshape(5, 3, 3)
    H = heading_rotations(R)
    for i in range(5):
        np.testing.assert_array_equal(H[i], heading_rotations(R[i : i + 1])[0])
    a = rng.normal(size=(5, 3)) * [[1.0], [10.0], [1.0], [10.0], [np.nan]]
    limited = saturate_norm(a, 3.0)
    for i in range(5):
        np.testing.assert_array_equal(limited[i], saturate_norm(a[i : i + 1], 3.0)[0])
    assert np.all(np.isnan(limited[4]))
    np.testing.assert_array_equal(rotate(R, a[0]), rotate(R, np.tile(a[0], (5, 1))))
    with pytest.raises(ValueError, match=r"^v: must be one 3-vector or one per matrix"):
        rotate(R, a[:2])


def test_a_bad_batch_size_is_named() -> None:
    with pytest.raises(ValueError, match=r"^batch_size: must be an integer ≥ 1, got 0"):
        PaperTrackingController(PaperTracking(), setting=SETTING, batch_size=0)
