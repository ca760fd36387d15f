"""The filter steps over runs (numba kernels) against the single-run numpy functions, run by
run; a run's bits do not depend on its batch; a failed (NaN) run raises nothing."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models import filter_runs as fr
from drake_uuv.models import raw_range_runs as rr
from drake_uuv.models.filters import (
    ekf_update,
    iekf_update,
    predict,
    range_difference_update,
)
from drake_uuv.models.handover import HandoverRule, Phase, PhaseEvidence, prior_share_update
from drake_uuv.models.measurement import paper_measurement
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.ping_geometry import interpolate_attitude, interpolate_attitude_runs
from drake_uuv.models.so3 import exp_so3
from drake_uuv.models.timing import carried_range, carried_range_runs, transition, update_through
from drake_uuv.models.unscented import ukf_range_update

B = 7
R = np.diag([0.01, 0.02])


def runs(seed: int = 1):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(B, 6))
    x[:, :3] += [-2.0, -2.0, 0.0]
    M = rng.normal(size=(B, 6, 6))
    P = 0.1 * M @ M.transpose(0, 2, 1) + 0.05 * np.eye(6)
    q_s = rng.normal(size=(B, 3))
    z = rng.uniform(2.0, 3.0, size=(B, 2))
    use = np.ones((B, 2), dtype=bool)
    use[1, 0] = use[2, 1] = False
    mask = np.ones(B, dtype=bool)
    mask[3] = False
    return x, P, q_s, z, use, mask


SINGLE = {
    "ekf": ekf_update,
    "iekf": iekf_update,
    "ukf": ukf_range_update,
}
BATCHED = {
    "ekf": rr.ekf_update_runs,
    "iekf": rr.iekf_update_runs,
    "ukf": rr.range_update_runs(ukf_range_update),
}


@pytest.mark.parametrize("kind", list(SINGLE))
def test_a_range_update_of_each_run_is_the_single_runs(kind: str) -> None:
    x, P, q_s, z, use, mask = runs()
    xb, Pb, nis = BATCHED[kind](x, P, z, q_s, R, use, mask)
    for i in range(B):
        if not mask[i]:  # not updated: the prior, no NIS
            assert np.array_equal(xb[i], x[i]) and np.array_equal(Pb[i], P[i])
            assert np.isnan(nis[i])
            continue
        xs, Ps, ns = SINGLE[kind](x[i], P[i], z[i], q_s[i], R, sonars=np.flatnonzero(use[i]))
        assert_allclose(xb[i], xs, rtol=1e-12, atol=1e-13)
        assert_allclose(Pb[i], Ps, rtol=1e-11, atol=1e-13)
        assert nis[i] == pytest.approx(ns, rel=1e-10)
    # A run's bits whatever its batch; a NaN run raises nothing and touches no other run.
    x[5] = np.nan
    P[5] = np.nan
    again = BATCHED[kind](x, P, z, q_s, R, use, mask)
    alone = BATCHED[kind](x[2:3], P[2:3], z[2:3], q_s[2:3], R, use[2:3], mask[2:3])
    assert np.isnan(again[0][5]).all()
    for got, first, single in zip(again, (xb, Pb, nis), alone, strict=True):
        assert np.array_equal(np.delete(got, 5, 0), np.delete(first, 5, 0), equal_nan=True)
        assert np.array_equal(got[2:3], single, equal_nan=True)


def test_the_papers_update_prediction_and_prior_share_are_the_single_runs() -> None:
    x, P, q_s, _, _, mask = runs(2)
    rng = np.random.default_rng(3)
    samples = rng.uniform(2.0, 3.0, size=(B, 2, 3))
    eta = np.tile([0.01, 0.02], (B, 1))
    for model, name in ((0, "derived"), (1, "paper_printed")):
        Y, m, gamma = fr.paper_measurement_runs(samples, eta, model)
        xb, Pb, nis = fr.range_difference_update_runs(x, P, Y, m, gamma, q_s, mask)
        S = fr.prior_share_update_runs(P, Pb, q_s, gamma, mask)
        for i in np.flatnonzero(mask):
            Ys, ms, gs = paper_measurement(samples[i], eta[i], name)
            assert (Y[i], m[i]) == (pytest.approx(Ys, rel=1e-15), pytest.approx(ms, rel=1e-15))
            assert gamma[i] == pytest.approx(gs, rel=1e-14)
            xs, Ps, ns = range_difference_update(x[i], P[i], Ys, ms, gs, q_s[i])
            assert_allclose(xb[i], xs, rtol=1e-13, atol=1e-14)
            assert_allclose(Pb[i], Ps, rtol=1e-12, atol=1e-14)
            assert nis[i] == pytest.approx(ns, rel=1e-12)
            assert_allclose(S[i], prior_share_update(P[i], Pb[i], q_s[i], gs), atol=1e-14)
    A, Bm = double_integrator(0.5)
    a = rng.normal(size=(B, 3))
    xn, Pn = fr.predict_runs(x, P, a, A, Bm, 0.01 * np.eye(6))
    for i in range(B):
        xs, Ps = predict(x[i], P[i], a[i], A, Bm, 0.01 * np.eye(6))
        assert_allclose(xn[i], xs, rtol=1e-14)
        assert_allclose(Pn[i], Ps, rtol=1e-13)


def test_the_rules_phases_over_runs_are_each_runs() -> None:
    """The compiled rule against its tests' methods, run by run (mixed phases)."""
    x, P, q_s, _, _, _ = runs(4)
    rule = HandoverRule(particle_bridge=True, second_order_tolerance=0.5)
    rng = np.random.default_rng(5)
    phases = rng.choice([int(Phase.LINEAR), int(Phase.RANGE), int(Phase.PARTICLE)], size=B)
    S = rng.choice([0.001, 1.0], size=B)[:, None, None] * P
    done = rng.integers(0, 4, size=B).astype(float)
    nis = rng.choice([1.0, 100.0], size=B)
    evidence = PhaseEvidence(x, 0.01 * P, nis, done, S, q_s, np.array([0.05, 0.07]), True, True)
    following, redraw = rule.next_phases(phases, evidence)
    for i in range(B):
        one = PhaseEvidence(
            x[i], 0.01 * P[i], nis[i], int(done[i]), S[i], q_s[i], np.array([0.05, 0.07]),
            True, True,
        )  # fmt: skip
        forgotten = rule.prior_forgotten(one.P, one.linear_updates, one.prior_share)
        holds = rule.gaussian_holds(one.x, one.P, one.q_s, one.noise_std)
        if phases[i] == Phase.LINEAR:
            expected = Phase.RANGE if (forgotten and holds) else Phase.PARTICLE
            expected = expected if forgotten else Phase.LINEAR
        elif phases[i] == Phase.PARTICLE:
            expected = Phase.RANGE if holds else Phase.PARTICLE
        else:
            wide = rule.fallback_due(one.x, one.P, one.q_s)
            expected = Phase.PARTICLE if (wide or rule.lost(one.nis)) else Phase.RANGE
            assert redraw[i] == (not wide and rule.lost(one.nis))
        assert following[i] == expected


def test_the_late_range_helpers_over_runs_are_each_runs() -> None:
    rng = np.random.default_rng(6)
    R0 = np.array([exp_so3(2.0 * rng.normal(size=3)) for _ in range(B)])
    R1 = np.array([exp_so3(2.0 * rng.normal(size=3)) for _ in range(B)])
    R1[0] = R0[0]
    s = rng.uniform(0.0, 1.0, size=B)
    s[1] = 0.0
    turned = interpolate_attitude_runs(R0, R1, s)
    for i in range(B):
        assert_allclose(turned[i], interpolate_attitude(R0[i], R1[i], s[i]), atol=1e-14)
    z = rng.normal(size=(B, 9))
    M = rng.normal(size=(B, 9, 9))
    P_z = 0.1 * M @ M.transpose(0, 2, 1) + 0.05 * np.eye(9)
    G1, G2 = transition(0.1)[0], transition(0.3)[0]
    c1, c2 = rng.normal(size=(B, 6)), rng.normal(size=(B, 6))
    q1, q2 = rng.normal(size=(B, 3)), rng.normal(size=(B, 3))
    sonar = rng.integers(0, 2, size=B)
    G1s, G2s = np.broadcast_to(G1, (B, 6, 9)), np.broadcast_to(G2, (B, 6, 9))
    shift, variance = carried_range_runs(z, P_z, sonar, (G1s, c1, q1), (G2s, c2, q2))
    y = (G2s @ z[:, :, None])[:, :, 0] + c2
    y_post = y + 0.1 * rng.normal(size=(B, 6))
    P_y_post = 0.5 * (G2s @ P_z @ G2.T)
    mask = np.ones(B, dtype=bool)
    mask[4] = False
    z_b, P_b = fr.update_through_runs(z, P_z, G2s, y, y_post, P_y_post, mask)
    for i in range(B):
        d, v = carried_range(z[i], P_z[i], sonar[i], (G1, c1[i], q1[i]), (G2, c2[i], q2[i]))
        assert shift[i] == pytest.approx(d, rel=1e-12, abs=1e-14)
        assert variance[i] == pytest.approx(v, rel=1e-12)
        if not mask[i]:
            assert np.array_equal(z_b[i], z[i]) and np.array_equal(P_b[i], P_z[i])
            continue
        zs, Ps = update_through(z[i], P_z[i], G2, y[i], y_post[i], P_y_post[i])
        assert_allclose(z_b[i], zs, rtol=1e-10, atol=1e-12)
        assert_allclose(P_b[i], Ps, rtol=1e-10, atol=1e-12)


def test_an_unknown_range_update_has_no_batched_counterpart() -> None:
    with pytest.raises(ValueError, match=r"^range_update: no batched counterpart of"):
        rr.range_update_runs(lambda *args: None)
    with pytest.raises(ValueError, match=r"^estimator.noise_model: must be derived or paper"):
        fr.noise_model_code("exact")
