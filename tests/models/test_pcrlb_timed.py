"""The PCRLB with ranges at their ping times, counted once arrived (models/pcrlb_timed)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drake_uuv.models.measurement import MIN_RANGE
from drake_uuv.models.pcrlb import pcrlb_along_trajectory, symmetrise
from drake_uuv.models.pcrlb_timed import pcrlb_timed, ping_rows
from tests.conftest import ETA_UNEQUAL, T, W


def _psd_le(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    """a ⪯ b (all stacked matrices), up to rounding."""
    gap = np.linalg.eigvalsh(b - a).min(axis=-1)
    return bool(np.all(gap >= -rtol * np.abs(b).max()))


def _geometry(steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(steps, 3)) * 2.0 + [-2.0, -2.0, 0.0], rng.normal(size=(steps, 3))


def _noise(steps: int, rng: np.random.Generator, correlated: bool = True) -> np.ndarray:
    """Each step's 2×2 range-error covariance (a shared error makes a cross term)."""
    noise = np.zeros((steps, 2, 2))
    noise[:, [0, 1], [0, 1]] = ETA_UNEQUAL
    if correlated:
        shared = rng.normal(size=(steps, 2)) * 0.05
        noise += shared[:, :, None] * shared[:, None, :]
    return noise


def _timing(steps: int, offsets: tuple[float, float], latency: float, rng: np.random.Generator):
    """Ping offsets, arrival lags ``ceil((τ + L)/t)`` and a few pings that never arrive."""
    tau = np.broadcast_to(np.asarray(offsets), (steps, 2)).copy()
    lag = np.ceil((tau + latency) / T - 1e-9).astype(int)
    tau[rng.random((steps, 2)) < 0.15] = np.nan  # dropped
    return tau, lag


def test_pings_at_the_tick_reduce_to_todays_recursion() -> None:
    """τ = 0 and no latency: the augmented step is today's recursion, to rounding."""
    steps = 60
    q, q_s = _geometry(steps, 0)
    available = np.random.default_rng(1).random((steps, 2)) > 0.2
    today = pcrlb_along_trajectory(q, q_s, 2.0 * np.eye(6), W, ETA_UNEQUAL, 3, T, available)
    noise = np.zeros((steps, 2, 2))
    noise[:, [0, 1], [0, 1]] = ETA_UNEQUAL / 3
    p_TS = np.stack([q + 0.5 * q_s, q - 0.5 * q_s], axis=1)
    tau = np.where(available, 0.0, np.nan)
    mine = pcrlb_timed(tau, np.zeros((steps, 2), int), p_TS, noise, 2.0 * np.eye(6), W, T)
    assert np.abs(mine - today).max() <= 1e-12 * np.abs(today).max()


def _position_map(time: float, steps: int) -> np.ndarray:
    """``q(time)`` as a linear map (3 × (6 + 6·steps)) of ``[x_0, ū_0, w_0, ū_1, w_1, …]``,
    written out from the kinematics: ``ū_k`` acts over ``[k t, (k+1) t)``, ``w_k`` (a
    position jump) at the end of step k."""
    L = np.zeros((3, 6 + 6 * steps))
    L[:, :3], L[:, 3:6] = np.eye(3), time * np.eye(3)
    for k in range(steps):
        start, end = k * T, (k + 1) * T
        if time <= start:
            break
        if time < end:
            weight = 0.5 * (time - start) ** 2
        else:
            weight = 0.5 * T * T + T * (time - end)
            L[:, 6 + 6 * k + 3 : 6 + 6 * k + 6] = np.eye(3)
        L[:, 6 + 6 * k : 6 + 6 * k + 3] = -weight * np.eye(3)
    return L


def _velocity_map(time: float, steps: int) -> np.ndarray:
    L = np.zeros((3, 6 + 6 * steps))
    L[:, 3:6] = np.eye(3)
    for k in range(steps):
        L[:, 6 + 6 * k : 6 + 6 * k + 3] = -np.clip(time - k * T, 0.0, T) * np.eye(3)
    return L


def _batch_bound(tau, lag, p_TS, noise, P0, Ws, position_noise, tick) -> np.ndarray:
    """The posterior covariance of ``x(tick)`` from every ping arrived by ``tick``: one
    linear-Gaussian problem on the whole history (no recursion); ``position_noise`` N×3×3."""
    steps = len(tau)
    prior = [P0] + [block for k in range(steps) for block in (Ws[k], position_noise[k])]
    information = np.linalg.inv(_block_diagonal(prior))
    for k in range(steps):
        counted = [i for i in (0, 1) if np.isfinite(tau[k, i]) and lag[k, i] <= tick - k]
        if not counted:
            continue
        rows = np.array(
            [
                p_TS[k, i] / np.linalg.norm(p_TS[k, i]) @ _position_map(k * T + tau[k, i], steps)
                for i in counted
            ]
        )
        R = noise[k][np.ix_(counted, counted)]
        information += rows.T @ np.linalg.solve(R, rows)
    L = np.vstack([_position_map(tick * T, steps), _velocity_map(tick * T, steps)])
    return L @ np.linalg.solve(information, L.T)


def _block_diagonal(blocks: list[np.ndarray]) -> np.ndarray:
    size = sum(len(b) for b in blocks)
    out, at = np.zeros((size, size)), 0
    for b in blocks:
        out[at : at + len(b), at : at + len(b)] = b
        at += len(b)
    return out


@pytest.mark.parametrize("offsets, latency, correlated", [
    ((0.0, 0.0), 0.0, False), ((0.1, 0.35), 0.0, False), ((0.0, 0.25), 0.7, False),
    ((0.45, 0.2), 1.3, False), ((0.0, 0.25), 0.7, True),
])  # fmt: skip
def test_the_bound_is_the_batch_posterior_of_the_whole_history(
    offsets, latency, correlated
) -> None:
    """Against the information of every arrived ping on ``[x_0, ū_0, …]`` at once; the
    position noise per axis, or a full 3×3 per step (the attitude noise turning a navigated
    velocity)."""
    steps = 7
    rng = np.random.default_rng(2)
    tau, lag = _timing(steps, offsets, latency, rng)
    q, _ = _geometry(steps, 3)
    p_TS = np.stack([q + [0.5, 0.4, 0.0], q - [0.5, 0.4, 0.0]], axis=1)
    noise = _noise(steps, rng)
    P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1])
    Ws = W + 0.002 * rng.random((steps, 1, 1)) * np.eye(3)
    if correlated:
        L = 0.03 * rng.standard_normal((steps, 3, 3))
        position_noise = L @ np.swapaxes(L, 1, 2) + 1e-6 * np.eye(3)
        blocks = position_noise
    else:
        position_noise = 1e-3 * rng.random(steps)
        blocks = position_noise[:, None, None] * np.eye(3)
    bounds = pcrlb_timed(tau, lag, p_TS, noise, P0, Ws, T, position_noise=position_noise)
    for tick in range(steps):
        expected = _batch_bound(tau, lag, p_TS, noise, P0, Ws, blocks, tick)
        assert_allclose(bounds[tick], expected, rtol=1e-9, atol=1e-12)


def test_the_bound_is_the_error_covariance_of_simulated_runs() -> None:
    """Monte Carlo of the linear-Gaussian model on a fine time grid: the best linear
    estimate of ``x_j`` from the pings arrived by tick j, fitted on the runs themselves, has
    the bound as its error covariance (to sampling error)."""
    steps, tick, runs, grid = 4, 3, 100_000, 20
    offsets, latency = (0.1, 0.35), 0.6  # on the grid: 4 and 14 of 20 substeps
    rng = np.random.default_rng(5)
    tau = np.broadcast_to(np.asarray(offsets), (steps, 2)).copy()
    lag = np.ceil((tau + latency) / T - 1e-9).astype(int)
    los = rng.normal(size=(steps, 2, 3))
    los /= np.linalg.norm(los, axis=-1, keepdims=True)
    noise = _noise(steps, rng)
    P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1])
    x = rng.multivariate_normal(np.zeros(6), P0, size=runs)
    p, v = x[:, :3].copy(), x[:, 3:].copy()
    measured, h = [], T / grid
    for k in range(tick):
        u_bar = rng.multivariate_normal(np.zeros(3), W, size=runs)
        errors = rng.multivariate_normal(np.zeros(2), noise[k], size=runs)
        for n in range(grid):  # exact for the step's constant acceleration −ū
            for i in (0, 1):
                if round(tau[k, i] / h) == n and lag[k, i] <= tick - k:
                    measured.append(p @ los[k, i] + errors[:, i])
            p, v = p + h * v - 0.5 * h * h * u_bar, v - h * u_bar
    y = np.column_stack(measured)
    truth = np.hstack([p, v])
    fit, *_ = np.linalg.lstsq(y, truth, rcond=None)
    residual = truth - y @ fit
    sample = residual.T @ residual / (runs - y.shape[1])
    bound = pcrlb_timed(tau, lag, los, noise, P0, W, T)[tick]
    standard_error = np.sqrt((np.outer(np.diag(bound), np.diag(bound)) + bound**2) / runs)
    assert np.all(np.abs(sample - bound) <= 5.0 * standard_error)
    assert y.shape[1] == 4  # pings of steps 0 and 1 by tick 3; step 2's are in flight


def step_transition(tau: float) -> np.ndarray:
    """``G(τ) = [Φ(τ), −B(τ)]`` (6×9), written out here (the package's is
    :func:`drake_uuv.models.timing.transition`): ``x(τ) = G(τ) z + B(τ) a_k``."""
    G = np.zeros((6, 9))
    G[:, :6] = np.eye(6)
    G[:3, 3:6] = tau * np.eye(3)
    G[:3, 6:] = -0.5 * tau * tau * np.eye(3)
    G[3:, 6:] = -tau * np.eye(3)
    return G


def _direct_bound(tau, lag, p_TS, noise, P0, tick) -> np.ndarray:
    """Tick ``tick``'s bound, every step from the prior again with what has arrived by then."""
    G = step_transition(T)
    P = P0
    for k in range(tick + 1):
        J = np.zeros((9, 9))
        J[:6, :6], J[6:, 6:] = np.linalg.inv(P), np.linalg.inv(W)
        counted = [i for i in (0, 1) if np.isfinite(tau[k, i]) and lag[k, i] <= tick - k]
        if counted:
            u = p_TS[k, counted] / np.linalg.norm(p_TS[k, counted], axis=1, keepdims=True)
            H = ping_rows(tau[k, counted], u)
            J += H.T @ np.linalg.solve(noise[k][np.ix_(counted, counted)], H)
        if k == tick:
            return np.linalg.inv(J[:6, :6])
        P = G @ np.linalg.inv(J) @ G.T


def test_the_latency_window_is_a_direct_recomputation_at_every_tick() -> None:
    steps = 40
    rng = np.random.default_rng(7)
    tau, lag = _timing(steps, (0.05, 0.4), 4.8, rng)  # up to ten steps in flight
    q, q_s = _geometry(steps, 8)
    p_TS = np.stack([q + 0.5 * q_s, q - 0.5 * q_s], axis=1)
    noise = _noise(steps, rng)
    bounds = pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), W, T)
    assert lag.max() == 11
    for tick in range(steps):
        direct = _direct_bound(tau, lag, p_TS, noise, np.eye(6), tick)
        assert_allclose(bounds[tick], direct, rtol=1e-9, atol=1e-13)


def test_more_noise_or_later_arrivals_never_lower_the_bound() -> None:
    steps = 50
    rng = np.random.default_rng(9)
    tau, lag = _timing(steps, (0.1, 0.3), 0.0, rng)
    q, q_s = _geometry(steps, 10)
    p_TS = np.stack([q + 0.5 * q_s, q - 0.5 * q_s], axis=1)
    noise = _noise(steps, rng, correlated=False)
    base = pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), W, T)
    worse = [
        pcrlb_timed(tau, lag + 2, p_TS, noise, np.eye(6), W, T),
        pcrlb_timed(tau, lag, p_TS, _noise(steps, rng) + noise, np.eye(6), W, T),
        pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), 2.0 * W, T),
        pcrlb_timed(tau, lag, p_TS, noise, np.eye(6), W, T, position_noise=1e-4),
    ]
    for bound in worse:
        assert _psd_le(base, bound)
        assert (
            np.trace(bound[10:], axis1=1, axis2=2).mean()
            > np.trace(base[10:], axis1=1, axis2=2).mean()
        )


def test_bad_timing_is_named() -> None:
    p_TS, noise = np.ones((3, 2, 3)), np.broadcast_to(np.eye(2), (3, 2, 2))
    lag = np.ones((3, 2), int)
    with pytest.raises(ValueError, match=r"tau must be in \[0, time_step = 0.5\)"):
        pcrlb_timed(np.full((3, 2), 0.5), lag, p_TS, noise, np.eye(6), W, T)
    with pytest.raises(ValueError, match="lag must be ≥ 0, got -1"):
        pcrlb_timed(np.zeros((3, 2)), -lag, p_TS, noise, np.eye(6), W, T)
    with pytest.raises(ValueError, match="cannot arrive at its own step's tick"):
        pcrlb_timed(np.full((3, 2), 0.1), 0 * lag, p_TS, noise, np.eye(6), W, T)
    with pytest.raises(ValueError, match=r"tau must have shape \(N, 2\)"):
        pcrlb_timed(np.zeros(3), lag, p_TS, noise, np.eye(6), W, T)


# --- The reference: the recursion in numpy, step by step (the kernel's independent twin) ------


def _reference_information(tau, lag, p_TS, noise, window: int) -> np.ndarray:
    """Each step's information on its ``z`` (N × (window+1) × 9 × 9) by arrival lag: entry
    ``[k, ℓ]`` is ``Hᵀ R⁻¹ H`` over the pings of step k with ``lag ≤ ℓ`` (an absent ping's
    row zeroed and its noise decoupled)."""
    present = np.isfinite(tau)
    p_TS = np.where(present[..., None], p_TS, 1.0)
    los = p_TS / np.maximum(np.linalg.norm(p_TS, axis=-1, keepdims=True), MIN_RANGE)
    rows = ping_rows(np.where(present, tau, 0.0), los)
    out = np.empty((tau.shape[0], window + 1, 9, 9))
    for ell in range(window + 1):
        counted = present & (lag <= ell)
        h = np.where(counted[..., None], rows, 0.0)
        both = counted[:, :, None] & counted[:, None, :]
        R = np.where(both, noise, np.eye(2))
        out[:, ell] = np.swapaxes(h, -1, -2) @ np.linalg.solve(R, h)
    return out


def reference_pcrlb_timed(tau, lag, p_TS, noise, P0, W, time_step, position_noise=0.0):
    """:func:`pcrlb_timed` of one run as numpy wrote it: the complete recursion, then every
    tick's fast-forward through the last ``D`` steps batched over the ticks."""
    tau = np.asarray(tau, dtype=float)
    present = np.isfinite(tau)
    lags = np.where(present, lag, 0).astype(int)
    window = int(lags.max(initial=0))
    steps = lags.shape[0]
    info = _reference_information(tau, lags, p_TS, np.asarray(noise, dtype=float), window)
    W_inv = np.linalg.inv(np.broadcast_to(np.asarray(W, dtype=float), (steps, 3, 3)))
    Qp = np.zeros((steps, 6, 6))
    position_noise = np.asarray(position_noise, dtype=float)
    if position_noise.ndim < 2:  # per-axis variances
        position_noise = position_noise[..., None, None] * np.eye(3)
    Qp[:, :3, :3] = np.broadcast_to(position_noise, (steps, 3, 3))
    G = step_transition(time_step)

    def advance(P: np.ndarray, k: np.ndarray, information: np.ndarray) -> np.ndarray:
        J = np.zeros(P.shape[:-2] + (9, 9))
        J[..., :6, :6] = np.linalg.inv(P)
        J[..., 6:, 6:] = W_inv[k]
        P_z = symmetrise(np.linalg.inv(symmetrise(J + information)))
        return symmetrise(G @ P_z @ G.T + Qp[k])

    complete = np.empty((steps, 6, 6))
    complete[0] = symmetrise(np.asarray(P0, dtype=float).reshape(6, 6))
    for k in range(steps - 1):
        complete[k + 1] = advance(complete[k], np.array(k), info[k, window])
    ticks = np.arange(steps)
    start = np.maximum(ticks - window, 0)
    P = complete[start]
    for m in range(window):
        k = start + m
        active = k < ticks
        k = np.minimum(k, steps - 1)
        ell = np.clip(ticks - k, 0, window)
        P = np.where(active[:, None, None], advance(P, k, info[k, ell]), P)
    J = np.linalg.inv(P) + info[:, 0, :6, :6]
    return symmetrise(np.linalg.inv(symmetrise(J)))


def _random_case(steps: int, rng: np.random.Generator, latency: float | None = None):
    """Random offsets (some at the tick), latency, dropped pings, correlated noise, a
    per-step W and a full position noise."""
    offsets = np.where(rng.random(2) < 0.3, 0.0, rng.uniform(0.0, T, 2))
    if latency is None:
        latency = rng.choice([0.0, rng.uniform(0.0, 3.0)])
    tau, lag = _timing(steps, tuple(offsets), latency, rng)
    q, q_s = _geometry(steps, int(rng.integers(1000)))
    p_TS = np.stack([q + 0.5 * q_s, q - 0.5 * q_s], axis=1)
    noise = _noise(steps, rng)
    Ws = W + 0.002 * rng.random((steps, 1, 1)) * np.eye(3)
    L = 0.03 * rng.standard_normal((steps, 3, 3))
    position_noise = L @ np.swapaxes(L, 1, 2) + 1e-6 * np.eye(3)
    return tau, lag, p_TS, noise, Ws, position_noise


def test_the_kernel_is_the_numpy_recursion_on_random_timings() -> None:
    """Random offsets, latencies (none, or up to six steps) and dropped pings: the compiled
    recursion equals the numpy one to rounding."""
    rng = np.random.default_rng(11)
    P0 = np.diag([1.0, 2.0, 0.5, 0.3, 0.2, 0.1])
    for latency in (0.0, 0.2, 0.7, 2.9, None, None, None):
        tau, lag, p_TS, noise, Ws, Qp = _random_case(80, rng, latency)
        mine = pcrlb_timed(tau, lag, p_TS, noise, P0, Ws, T, position_noise=Qp)
        reference = reference_pcrlb_timed(tau, lag, p_TS, noise, P0, Ws, T, position_noise=Qp)
        assert_allclose(mine, reference, rtol=1e-10, atol=1e-10 * np.abs(reference).max())
        scalar = pcrlb_timed(tau, lag, p_TS, noise, P0, W, T, position_noise=1e-4)
        expected = reference_pcrlb_timed(tau, lag, p_TS, noise, P0, W, T, position_noise=1e-4)
        assert_allclose(scalar, expected, rtol=1e-10, atol=1e-10 * np.abs(expected).max())


def test_a_batch_is_each_run_alone_bit_for_bit() -> None:
    """Runs of different windows (no latency, one step, several) and a run with NaN in its
    geometry from step 20 on: each run's bound is its bits alone, in any order and batch
    size; the NaN run is finite before its NaN pings arrive and NaN at the end."""
    rng = np.random.default_rng(12)
    steps = 40
    cases = [_random_case(steps, rng, latency) for latency in (0.0, 0.3, 1.7, 0.0, 0.9)]
    cases[3][2][20:] = np.nan  # p_TS of run 3
    tau, lag, p_TS, noise, Ws, Qp = (np.stack(parts) for parts in zip(*cases, strict=True))
    P0 = np.eye(6)
    batch = pcrlb_timed(tau, lag, p_TS, noise, P0, Ws, T, position_noise=Qp)
    assert batch.shape == (5, steps, 6, 6)
    for i, case in enumerate(cases):
        tau_i, lag_i, p_TS_i, noise_i, Ws_i, Qp_i = case
        alone = pcrlb_timed(tau_i, lag_i, p_TS_i, noise_i, P0, Ws_i, T, position_noise=Qp_i)
        assert np.array_equal(batch[i], alone, equal_nan=True), i
    order = [4, 2, 0, 3, 1]
    again = pcrlb_timed(
        tau[order], lag[order], p_TS[order], noise[order], P0, Ws[order], T,
        position_noise=Qp[order],
    )  # fmt: skip
    assert np.array_equal(again, batch[order], equal_nan=True)
    assert np.isfinite(batch[3, :20]).all() and np.isnan(batch[3, 25:]).all()
    assert np.isfinite(batch[[0, 1, 2, 4]]).all()
