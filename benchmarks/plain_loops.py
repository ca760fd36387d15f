"""Plain batched loops of the closed loop's arithmetic, the references ``bench_batch.py`` times.

Each loop steps all B runs of a batch at once with no Drake: the plant, the target's random
walk, the two sonars, an estimator, the attitude generator and the tracking law, each a few
numpy passes over a leading run axis. Each returns every run's position RMSE from the
scenario's steady-state start, the diagram's ``position_rmse`` metric, so the benchmark can
check that a loop does the diagram's work (``bench_batch.py --check``).

The plant's, the target's and the sonars' noise comes from the diagram's own sources
(:func:`~drake_uuv.primitives.run_noise.run_draws` with the random ports' names:
``range_noise``, ``acceleration_noise``), so a loop sees the diagram's measurements and
target wherever its arithmetic is the diagram's.

- :func:`plain_paper_loop`: the paper's configuration (kinematic plant, the paper's KF,
  Algorithm 2, the paper's law).
- :func:`plain_ekf_loop`: the same with the EKF on the two raw ranges after a linear start.
- :func:`plain_particle_loop`: the same with a bootstrap particle filter after a linear start.
- :func:`plain_hovering_loop`: the ``hovering_auv`` scenario: the 8-thruster vehicle through
  the repository's own compiled step, the paper's KF predicting with the navigated motion,
  rate-limited Algorithm 2 and the LQR law in the world frame.

No loop is written for ``realistic``: its sonars ping at offsets and arrive late, so its
filters step each run's particles (20 000) through a window of late ranges at their ping
times, with modelled navigation errors; a plain loop of that would be a second
implementation of the particle window, not a reference for the framework's cost.
"""

import math

import numpy as np

from drake_uuv.models.attitude_plans import attitude_commands, trajectory_attitude
from drake_uuv.models.measurement import MIN_RANGE
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.so3 import exp_so3_runs, log_so3_runs, minimal_rotation_runs
from drake_uuv.models.tracking_laws import lqr_gain, reference_feedforward, saturate_norm
from drake_uuv.models.vehicle_kernels import attitude_runs, stepped_runs
from drake_uuv.plants.factory import plant_setting
from drake_uuv.plants.low_level_controller import low_level_law
from drake_uuv.plants.marine_vehicle import vehicle_initial_state
from drake_uuv.primitives.run_noise import run_draws
from drake_uuv.scenario import Scenario
from drake_uuv.scenario.tracking import LqrTracking

#: The step whose update is the raw-range filters' first, in the plain loops: the diagram's
#: default hand-over rule (paper scenario, seeds 0-99, the logged ``estimator_phase``) leaves
#: the linear start at step 23 in 94 runs and at step 22 in 6; the EKF's particle bridge
#: holds 16 of them on particles for that one step.
HANDOVER_STEP = 23


def _range_means(
    scenario: Scenario, seeds: np.ndarray, k: int, q: np.ndarray, q_s: np.ndarray
) -> np.ndarray:
    """The sonars' per-sonar sample means (B, 2) of step k: the true ranges plus the
    ``range_noise`` source's draws, sonar 1's f samples then sonar 2's (as the sonar)."""
    eta = np.asarray(scenario.sonar.noise_variances, float)
    f = scenario.sonar.samples_per_step
    d = np.stack([np.linalg.norm(q + 0.5 * q_s, axis=1), np.linalg.norm(q - 0.5 * q_s, axis=1)], 1)
    noise = run_draws(seeds, "range_noise", k, 2 * f)
    if f == 1:
        return d + np.sqrt(eta) * noise
    return d + (np.sqrt(eta)[:, None] * noise.reshape(-1, 2, f)).mean(axis=2)


class _PaperKf:
    """The paper's KF on ``Y = ½(z1² − z2²)`` with the derived noise model, Joseph form: the
    paper's estimator and the raw-range filters' linear start (with the means' ``η/f``)."""

    def __init__(self, scenario: Scenario, B: int) -> None:
        t = scenario.time_step
        est = scenario.estimator
        self.A, self.Bm = double_integrator(t)
        W = est.filter_acceleration_covariance(scenario.target.acceleration_covariance)
        self.Q = self.Bm @ W @ self.Bm.T
        self.eta = np.asarray(scenario.sonar.noise_variances, float) / (
            scenario.sonar.samples_per_step
        )
        self.x = np.tile(np.asarray(est.initial_estimate, float), (B, 1))
        self.P = np.tile(np.asarray(est.initial_covariance, float), (B, 1, 1))

    def update(self, k: int, z: np.ndarray, q_s: np.ndarray) -> np.ndarray:
        """The filtered estimate of step k (B, 6) from the range means ``z`` (B, 2)."""
        eta, x, P = self.eta, self.x, self.P
        B = len(z)
        Y = 0.5 * (z[:, 0] ** 2 - z[:, 1] ** 2)
        m = 0.5 * (eta[0] - eta[1])
        gamma = eta[0] * np.maximum(z[:, 0] ** 2 - eta[0], 0) + eta[1] * np.maximum(
            z[:, 1] ** 2 - eta[1], 0
        )
        gamma = gamma + 0.5 * (eta[0] ** 2 + eta[1] ** 2)
        C = np.concatenate([q_s, np.zeros((B, 3))], axis=1)
        PC = (P @ C[:, :, None])[:, :, 0]
        S = (C * PC).sum(1) + gamma
        K = PC / S[:, None]
        self.x = x + K * (Y - (C * x).sum(1) - m)[:, None]
        I_KC = np.eye(6) - K[:, :, None] * C[:, None, :]
        self.P = (
            I_KC @ P @ I_KC.transpose(0, 2, 1)
            + gamma[:, None, None] * K[:, :, None] * K[:, None, :]
        )
        return self.x

    def predict(self, k: int, a_W: np.ndarray) -> None:
        """To step k+1 with the commanded world acceleration ``a_W`` (B, 3)."""
        self.x = self.x @ self.A.T + a_W @ self.Bm.T
        self.P = self.A @ self.P @ self.A.T + self.Q

    def predict_navigated(self, X: np.ndarray, X_next: np.ndarray) -> None:
        """To step k+1 with the vehicle's navigated states ``[p, v]`` (B, 6) at k and k+1:
        the target predicted alone, ``Υ̂(k+1|k) = A (Υ̂ − X(k)) + X(k+1)``."""
        self.x = (self.x - X) @ self.A.T + X_next
        self.P = self.A @ self.P @ self.A.T + self.Q


class _Ekf(_PaperKf):
    """The paper's KF until :data:`HANDOVER_STEP`, then the first-order EKF on both raw range
    means (``h(x) = [|q + ½q_s|, |q − ½q_s|]``, ``R = diag(η/f)``, Joseph form)."""

    def __init__(self, scenario: Scenario, B: int, handover_step: int = HANDOVER_STEP) -> None:
        super().__init__(scenario, B)
        self.R = np.diag(self.eta)
        self.handover_step = handover_step

    def update(self, k: int, z: np.ndarray, q_s: np.ndarray) -> np.ndarray:
        if k < self.handover_step:
            return super().update(k, z, q_s)
        x, P, R = self.x, self.P, self.R
        B = len(z)
        H = np.zeros((B, 2, 6))
        rays = np.stack([x[:, :3] + 0.5 * q_s, x[:, :3] - 0.5 * q_s], 1)  # (B, 2, 3)
        h = np.linalg.norm(rays, axis=2)
        H[:, :, :3] = rays / np.maximum(h, MIN_RANGE)[:, :, None]
        PHt = P @ H.transpose(0, 2, 1)
        K = PHt @ np.linalg.inv(H @ PHt + R)
        self.x = x + (K @ (z - h)[:, :, None])[:, :, 0]
        I_KH = np.eye(6) - K @ H
        self.P = I_KH @ P @ I_KH.transpose(0, 2, 1) + K @ R @ K.transpose(0, 2, 1)
        return self.x


class _ParticleFilter(_PaperKf):
    """The paper's KF until :data:`HANDOVER_STEP`; at the step before it, N particles drawn
    from the KF's filtered Gaussian; from it on a bootstrap particle filter (see
    :func:`plain_particle_loop`). Particles ``(B, 6, N)``: each run's six coordinates are
    contiguous rows, so the passes are plain strided numpy and the moments batched
    products."""

    def __init__(
        self, scenario: Scenario, seeds: np.ndarray, handover_step: int = HANDOVER_STEP
    ) -> None:
        B = len(seeds)
        super().__init__(scenario, B)
        est = scenario.estimator
        self.n = est.particle_count
        self.threshold = est.particle_resample_threshold * self.n
        self.bandwidth = est.particle_parameters().bandwidth
        self.W_factor = np.linalg.cholesky(
            est.filter_acceleration_covariance(scenario.target.acceleration_covariance)
        )
        self.t = scenario.time_step
        self.handover_step = handover_step
        # One generator for the batch: the particles' draws are not the diagram's anyway.
        self.rng = np.random.default_rng(np.asarray(seeds).tolist())
        self.X = self.w = self.log_w = None

    def update(self, k: int, z: np.ndarray, q_s: np.ndarray) -> np.ndarray:
        if k < self.handover_step:
            return super().update(k, z, q_s)
        X, eta = self.X, self.eta
        q = X[:, :3]
        # |q ± ½q_s|² = |q|² + |q_s|²/4 ± q·q_s: two passes over the cloud, not six.
        squared = np.einsum("bin,bin->bn", q, q) + 0.25 * (q_s * q_s).sum(1)[:, None]
        cross = np.einsum("bi,bin->bn", q_s, q)
        d1 = np.sqrt(np.maximum(squared + cross, 0.0))
        d2 = np.sqrt(np.maximum(squared - cross, 0.0))
        log_w = self.log_w - 0.5 * (
            (z[:, 0, None] - d1) ** 2 / eta[0] + (z[:, 1, None] - d2) ** 2 / eta[1]
        )
        log_w -= log_w.max(axis=1, keepdims=True)
        w = np.exp(log_w)
        total = w.sum(axis=1, keepdims=True)
        w /= total
        self.log_w = log_w - np.log(total)
        self.w = w
        self.x = (X @ w[:, :, None])[:, :, 0]
        centred = X - self.x[:, :, None]
        P = (centred * w[:, None, :]) @ centred.transpose(0, 2, 1)
        self.P = 0.5 * (P + P.transpose(0, 2, 1))
        return self.x

    def predict(self, k: int, a_W: np.ndarray) -> None:
        if k < self.handover_step - 1:
            super().predict(k, a_W)
            return
        B, n = len(a_W), self.n
        if k == self.handover_step - 1:  # the cloud, drawn from the linear start's Gaussian
            L = np.linalg.cholesky(self.P)
            self.X = self.x[:, :, None] + L @ self.rng.standard_normal((B, 6, n))
            self.log_w = np.full((B, n), -math.log(n))
        else:
            self._resample()
        # x⁺ = A x + B (a_W − ū), each particle its own ū ~ N(0, W).
        acceleration = a_W[:, :, None] - self.W_factor @ self.rng.standard_normal((B, 3, n))
        X, t = self.X, self.t
        X[:, :3] += t * X[:, 3:] + (0.5 * t * t) * acceleration
        X[:, 3:] += t * acceleration

    def _resample(self) -> None:
        """Systematic resampling of the runs whose effective sample size is under the
        threshold, then Liu and West's shrinkage towards the posterior's moments."""
        runs = np.flatnonzero(1.0 / (self.w * self.w).sum(axis=1) < self.threshold)
        if runs.size == 0:
            return
        r, n = runs.size, self.n
        cdf = np.cumsum(self.w[runs], axis=1)
        cdf[:, -1] = 1.0
        # One search for all the runs: run i's CDF and positions shifted by 2i do not overlap.
        shift = 2.0 * np.arange(r)[:, None]
        positions = (np.arange(n) + self.rng.random((r, 1))) / n
        found = np.searchsorted((cdf + shift).ravel(), (positions + shift).ravel(), "right")
        chosen = np.minimum(found.reshape(r, n) - n * np.arange(r)[:, None], n - 1)
        X = np.take_along_axis(self.X[runs], chosen[:, None, :], axis=2)
        h = self.bandwidth
        if h > 0.0:
            a = math.sqrt(1.0 - h * h)
            # The cloud's covariance is full rank once the process noise has mixed into the
            # velocity; the jitter covers a run whose cloud collapsed onto a few particles.
            L = np.linalg.cholesky(self.P[runs] + 1e-12 * np.eye(6))
            X *= a
            X += ((1.0 - a) * self.x[runs])[:, :, None]
            X += (h * L) @ self.rng.standard_normal((r, 6, n))
        self.X[runs] = X
        self.log_w[runs] = -math.log(n)


def _kinematic_loop(scenario: Scenario, seeds: np.ndarray, estimator: _PaperKf) -> np.ndarray:
    """The paper's loop (kinematic plant, target, sonars, Algorithm 2, the paper's law) around
    ``estimator``'s update and prediction; each run's position RMSE from the steady-state
    start."""
    B, t, N = len(seeds), scenario.time_step, scenario.steps
    b = np.asarray(scenario.sonar.baseline, float)
    L = np.linalg.cholesky(np.asarray(scenario.target.acceleration_covariance, float))
    alpha = scenario.tracking.alpha
    k_p, k_v = 2 * alpha / t**2, 2 / t
    q_star = np.asarray(scenario.tracking.desired_relative_position, float)
    att = scenario.attitude
    p = np.tile(np.asarray(scenario.uuv.initial_position, float), (B, 1))
    v = np.tile(np.asarray(scenario.uuv.initial_velocity, float), (B, 1))
    R = np.tile(np.eye(3), (B, 1, 1))
    pt = np.tile(np.asarray(scenario.target.initial_position, float), (B, 1))
    vt = np.tile(np.asarray(scenario.target.initial_velocity, float), (B, 1))
    sq = np.zeros(B)
    for k in range(N):
        q_s = R @ b
        q = p - pt
        x = estimator.update(k, _range_means(scenario, seeds, k, q, q_s), q_s)
        if k >= scenario.steady_state_start:
            sq += ((q - x[:, :3]) ** 2).sum(1)
        # Algorithm 2 (one plan for all runs) and the paper's law.
        zeta = np.linalg.norm(b) * np.array(
            [math.sin(att.rho * k * math.pi), math.cos(att.rho * k * math.pi),
             att.h_amplitude * math.cos(att.h_frequency * k * math.pi)]
        )  # fmt: skip
        R_bar = minimal_rotation_runs(b, zeta[None])
        u2 = log_so3_runs(R_bar @ R.transpose(0, 2, 1)) / t
        R_T = R.transpose(0, 2, 1)
        u1 = (
            -k_p * ((R_T @ x[:, :3, None])[:, :, 0] - q_star)
            - k_v * (R_T @ x[:, 3:, None])[:, :, 0]
        )
        a_W = (R @ u1[:, :, None])[:, :, 0]
        a_T = run_draws(seeds, "acceleration_noise", k, 3) @ L.T
        estimator.predict(k, a_W)
        p, v = p + t * v + 0.5 * t * t * a_W, v + t * a_W
        pt, vt = pt + t * vt + 0.5 * t * t * a_T, vt + t * a_T
        R = exp_so3_runs(u2 * t) @ R
    return np.sqrt(sq / (N - scenario.steady_state_start))


def plain_paper_loop(scenario: Scenario, seeds: np.ndarray) -> np.ndarray:
    """The paper's loop for a batch of runs in plain numpy: the kinematic plant, the target,
    the sonars, the paper's KF in Joseph form, Algorithm 2 and the paper's law. Returns each
    run's position RMSE from the steady-state start (the diagram's, to rounding)."""
    return _kinematic_loop(scenario, seeds, _PaperKf(scenario, len(seeds)))


def plain_ekf_loop(scenario: Scenario, seeds: np.ndarray) -> np.ndarray:
    """The paper's loop with the EKF on the two raw ranges (``estimator=Ekf``), plain numpy.

    The filter is the EKF's own arithmetic: the paper's KF on the range means' ``Y`` (the
    linear start) for the steps before :data:`HANDOVER_STEP`, the first-order EKF on both
    ranges from it on, every run handing over at that one step. Left out: the hand-over rule
    itself and its range gate (each run's hand-over step, 22 or 23 in the diagram) and the
    particle bridge (the diagram's runs that spend their hand-over step on particles; the
    bridge's state is declared, and copied each step, for every run of the diagram).
    Returns each run's position RMSE from the steady-state start."""
    return _kinematic_loop(scenario, seeds, _Ekf(scenario, len(seeds)))


def plain_particle_loop(scenario: Scenario, seeds: np.ndarray) -> np.ndarray:
    """The paper's loop with the particle filter (``estimator=ParticleFilter``), plain numpy
    over runs × particles: what numpy's passes over the clouds cost, the reference for the
    diagram's compiled kernels.

    The paper's KF (the linear start) until :data:`HANDOVER_STEP`; at the step before, each
    run's N particles drawn from its filtered Gaussian and moved by the model. From then on a
    bootstrap particle filter: each particle weighed by the two range means' Gaussian
    likelihood (``R = diag(η/f)``), the filtered estimate the weighted mean (and covariance);
    a run whose effective sample size is under ``particle_resample_threshold · N`` is
    resampled (systematic) and regularised by Liu and West's shrinkage kernel of the
    configured bandwidth, as the diagram's filter does; every particle then moves by the
    double integrator with the commanded acceleration less its own draw of the target's
    acceleration noise.

    Left out: the hand-over rule (every run hands over at that step) and its range gate, the
    NIS, and per-run random streams: the particles' draws come from one numpy generator
    seeded by the batch's seeds, so a run's particles depend on its batch (the diagram's are
    a function of the run's seed, from counter-based draws). Returns each run's position
    RMSE from the steady-state start."""
    return _kinematic_loop(scenario, seeds, _ParticleFilter(scenario, seeds))


def plain_hovering_loop(scenario: Scenario, seeds: np.ndarray) -> np.ndarray:
    """The ``hovering_auv`` scenario's loop for a batch of runs, with no Drake.

    The plant is the repository's own compiled outer step of the 8-thruster vehicle
    (``vehicle_kernels.stepped_runs``: the commands latched, then per 50 Hz controller tick
    the computed-torque law, the thrust allocation under saturation and one RK3 step), called
    on all B runs' state as ``SteppedHoveringAuv`` calls it; the vehicle's attitude and world
    velocity are read from its state by ``attitude_runs``. Around it, the scenario's outer
    loop: the target, the sonars, the paper's KF predicting with the navigated motion
    (perfect navigation: the vehicle's own state), Algorithm 2 with its angular-rate limit
    (``attitude_commands``) and the scenario's tracking law, the LQR law with q* fixed in the
    world (its feed-forward of a fixed reference is zero) under the acceleration limit. Only
    that law is written (the scenario's; neither the paper's law nor another frame), and only
    ``integrator: runge_kutta3``, the plant's default. Returns each run's position RMSE from
    the steady-state start (the diagram's, to rounding).
    """
    config, tracking, att = scenario.plant, scenario.tracking, scenario.attitude
    if config.integrator != "runge_kutta3" or not (
        isinstance(tracking, LqrTracking) and tracking.reference_frame == "world"
    ):
        raise ValueError("plain_hovering_loop: written for hovering_auv's RK3 plant and LQR law")
    B, t, N = len(seeds), scenario.time_step, scenario.steps
    b = np.asarray(scenario.sonar.baseline, float)
    L = np.linalg.cholesky(np.asarray(scenario.target.acceleration_covariance, float))
    setting = plant_setting(scenario)
    law = low_level_law(config, t)
    n = law.allocator.num_thrusters
    R0 = np.asarray(setting.initial_R_WB, float)
    x0 = vehicle_initial_state(
        np.asarray(setting.initial_position, float),
        np.asarray(setting.initial_velocity, float),
        R0,
        num_lag_states=n if config.thrust_time_constant > 0.0 else 0,
    )
    state, state_next = np.tile(x0, (B, 1)), np.empty((B, x0.size))
    # The controller's state groups, as ControllerStates starts them (the kernel's outputs).
    latch = np.tile(np.concatenate([np.zeros(6), R0.ravel(), [0.0]]), (B, 1))
    target, rate, v_ref = np.tile(R0.ravel(), (B, 1)), np.zeros((B, 3)), np.zeros((B, 3))
    thrust, wrench, scale = np.zeros((B, n)), np.zeros((B, 6)), np.ones((B, 2))
    counts, counts_next = np.zeros((B, 4)), np.zeros((B, 4))
    K_lqr, _ = lqr_gain(t, tracking.position_weight, tracking.velocity_weight,
                        tracking.input_weight)  # fmt: skip
    q_star = np.asarray(tracking.desired_relative_position, float)
    reference, a_ff = reference_feedforward(q_star, q_star, q_star, t)
    if not tracking.feedforward:
        reference, a_ff = np.concatenate([q_star, np.zeros(3)]), np.zeros(3)
    estimator = _PaperKf(scenario, B)
    pt = np.tile(np.asarray(scenario.target.initial_position, float), (B, 1))
    vt = np.tile(np.asarray(scenario.target.initial_velocity, float), (B, 1))
    R_flat = np.empty((B, 9))

    def navigated(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``R_WB`` (B, 3, 3) and ``[p_WU, v_WU]`` (B, 6) of the vehicle states ``x``."""
        attitude_runs(x, R_flat)
        R = R_flat.reshape(B, 3, 3).copy()
        return R, np.concatenate([x[:, :3], (R @ x[:, 7:10, None])[:, :, 0]], axis=1)

    R, X = navigated(state)
    sq = np.zeros(B)
    for k in range(N):
        q_s = R @ b
        q = X[:, :3] - pt
        x = estimator.update(k, _range_means(scenario, seeds, k, q, q_s), q_s)
        if k >= scenario.steady_state_start:
            sq += ((q - x[:, :3]) ** 2).sum(1)
        R_bar = trajectory_attitude(k, b, att.rho, att.h_amplitude, att.h_frequency)
        u2 = attitude_commands(R_bar.reshape(1, 3, 3), R, t, att.max_angular_rate)
        a_W = saturate_norm(
            a_ff - (K_lqr @ (x - reference)[:, :, None])[:, :, 0], tracking.max_acceleration
        )
        u1 = np.ascontiguousarray((R.transpose(0, 2, 1) @ a_W[:, :, None])[:, :, 0])
        stepped_runs(
            k * t, state, u1, np.ascontiguousarray(u2, dtype=float), counts, *law.arrays,
            state_next, latch, target, rate, v_ref, thrust, wrench, scale, counts_next,
        )  # fmt: skip
        state, state_next = state_next, state
        counts, counts_next = counts_next, counts
        R, X_next = navigated(state)
        estimator.predict_navigated(X, X_next)
        X = X_next
        a_T = run_draws(seeds, "acceleration_noise", k, 3) @ L.T
        pt, vt = pt + t * vt + 0.5 * t * t * a_T, vt + t * a_T
    return np.sqrt(sq / (N - scenario.steady_state_start))


#: Configuration name (``bench_batch.CONFIGS``) → its plain loop.
PLAIN_LOOPS = {
    "paper": plain_paper_loop,
    "ekf": plain_ekf_loop,
    "hovering_auv": plain_hovering_loop,
    "particle_filter": plain_particle_loop,
}
