"""A self-contained numpy simulator of the paper's closed loop, for testing the estimators.

Not the product: the Drake diagram is. This reference exists so the filter mathematics can
be checked (and the RMSE/PCRLB ratios measured) without Drake, in a few milliseconds per run.
It follows design.md §1 exactly: target random walk, UUV double integrator driven by
``a_W = R u1``, attitude from Algorithm 2 (``R(k+1) = R̄(k)``, ``R(0) = I``), the paper's
tracking law, two sonars with ``f`` samples each.

Order within step k: sensors read the state at k; the filter updates to ``x̂(k|k)``; the
controller computes ``u1(k)`` from ``x̂(k|k)`` and ``R(k)``; then plant, target, attitude and
filter prediction advance to k+1. Random draws per step, in this order: the ``2f`` range
noises (standard normal), then the target's 3 acceleration noises.

Run ``python -m drake_uuv.estimators._reference --runs 100`` for the RMSE/PCRLB table.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field

import numpy as np

from drake_uuv.estimators.filters_math import (
    HandoverPolicy,
    RawRangeFilter,
    predict,
    range_difference_update,
)
from drake_uuv.estimators.pcrlb import (
    bound_rmse,
    kf_riccati_covariance,
    pcrlb_monte_carlo,
    pcrlb_per_run_mean,
)
from drake_uuv.estimators.range_model import (
    process_noise_covariance,
    range_difference_measurement,
    range_measurement,
    relative_model_matrices,
)

ESTIMATORS = ("kf", "ekf", "iekf")


@dataclass
class ReferenceScenario:
    """The paper's §IV simulation (design.md §1) with the unstated choices filled in."""

    time_step: float = 0.5
    steps: int = 500
    W: np.ndarray = field(default_factory=lambda: np.diag([0.004, 0.001, 0.001]))
    eta: np.ndarray = field(default_factory=lambda: np.array([0.01, 0.01]))
    samples_per_step: int = 1
    baseline: np.ndarray = field(default_factory=lambda: np.array([-1.0, 1.0, 0.0]))
    target_position: np.ndarray = field(default_factory=lambda: np.array([1.0, 2.0, 2.0]))
    target_velocity: np.ndarray = field(default_factory=lambda: np.array([0.02, 0.1, 0.1]))
    alpha: float = 1.2
    q_star: np.ndarray = field(default_factory=lambda: np.array([-2.0, -2.0, 0.0]))
    rho: float = 1.0 / 24.0
    x0_hat: np.ndarray = field(default_factory=lambda: np.zeros(6))
    P0: np.ndarray = field(default_factory=lambda: np.eye(6))
    steady_state_start: int = 200


def minimal_rotation(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The rotation of least angle taking the direction of ``a`` to that of ``c``."""
    a = a / np.linalg.norm(a)
    c = c / np.linalg.norm(c)
    axis = np.cross(a, c)
    s = float(np.linalg.norm(axis))
    cos = float(np.clip(a @ c, -1.0, 1.0))
    if s < 1e-12:
        if cos > 0.0:
            return np.eye(3)
        # Antiparallel: a half turn about any axis perpendicular to a.
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        n = np.cross(a, helper)
        n /= np.linalg.norm(n)
        return 2.0 * np.outer(n, n) - np.eye(3)
    n = axis / s
    K = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    theta = math.atan2(s, cos)
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def algorithm2_attitudes(scenario: ReferenceScenario) -> np.ndarray:
    """``R(k)`` for k = 0..N−1 under Algorithm 2: ``R(0) = I``, ``R(k+1) = R̄(k)``."""
    b = scenario.baseline
    Rs = np.empty((scenario.steps, 3, 3))
    Rs[0] = np.eye(3)
    for k in range(scenario.steps - 1):
        zeta = np.linalg.norm(b) * np.array(
            [
                math.sin(scenario.rho * k * math.pi),
                math.cos(scenario.rho * k * math.pi),
                0.5 * math.cos(k * math.pi / 6.0),
            ]
        )
        Rs[k + 1] = minimal_rotation(b, zeta)
    return Rs


@dataclass
class RunResult:
    """One closed-loop run: arrays over steps k = 0..N−1."""

    x_true: np.ndarray  # (N, 6) relative state
    x_hat: np.ndarray  # (N, 6) filtered estimate x̂(k|k)
    P: np.ndarray  # (N, 6, 6) filter covariance P(k|k)
    q_s: np.ndarray  # (N, 3) world baseline
    nis: np.ndarray  # (N,)
    gamma_true: np.ndarray  # (N,) variance of the paper's Y noise on the true ranges


def simulate(
    scenario: ReferenceScenario,
    estimator: str,
    seed: int,
    policy: HandoverPolicy | None = None,
    attitudes: np.ndarray | None = None,
    control_from_truth: bool = False,
) -> RunResult:
    """Run the closed loop once with ``estimator`` in ``ESTIMATORS``; seeded, reproducible.

    ``attitudes`` (N×3×3) replaces Algorithm 2. ``control_from_truth`` feeds the true relative
    state to the tracking law (a diagnostic: the geometry then no longer depends on the
    estimation error, so the per-run and averaged bounds coincide).
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    s = scenario
    rng = np.random.default_rng(seed)
    N, t, f = s.steps, s.time_step, s.samples_per_step
    A, B = relative_model_matrices(t)
    Q = process_noise_covariance(s.W, t)
    W_sqrt = np.linalg.cholesky(s.W)
    eta_sqrt = np.sqrt(s.eta)
    Rs = algorithm2_attitudes(s) if attitudes is None else attitudes

    p, v = np.zeros(3), np.zeros(3)
    pt, vt = s.target_position.astype(float), s.target_velocity.astype(float)
    x_hat, P = s.x0_hat.astype(float), s.P0.astype(float)
    raw = None
    if estimator != "kf":
        raw = RawRangeFilter(x_hat, P, A, B, Q, s.eta, f, method=estimator, policy=policy)

    out = RunResult(
        x_true=np.empty((N, 6)),
        x_hat=np.empty((N, 6)),
        P=np.empty((N, 6, 6)),
        q_s=np.empty((N, 3)),
        nis=np.empty(N),
        gamma_true=np.empty(N),
    )
    for k in range(N):
        R = Rs[k]
        q_s = R @ s.baseline
        x = np.concatenate([p - pt, v - vt])
        d = range_measurement(x, q_s)
        samples = d[:, None] + eta_sqrt[:, None] * rng.standard_normal((2, f))
        if raw is None:
            first = samples[:, 0]
            Y, m, Gamma = range_difference_measurement(
                first, s.eta, squared_ranges=(samples**2).mean(axis=1)
            )
            x_hat, P, nis = range_difference_update(x_hat, P, Y, m, Gamma, q_s)
        else:
            raw.update(samples.reshape(-1), q_s)
            x_hat, P, nis = raw.x, raw.P, raw.nis
        out.x_true[k], out.x_hat[k], out.P[k], out.q_s[k], out.nis[k] = x, x_hat, P, q_s, nis
        out.gamma_true[k] = s.eta @ (d * d) + 0.5 * (s.eta @ s.eta)

        x_c = x if control_from_truth else x_hat
        u1 = -(2.0 * s.alpha / t**2) * (R.T @ x_c[:3] - s.q_star) - (2.0 / t) * (R.T @ x_c[3:])
        a_W = R @ u1
        a_T = W_sqrt @ rng.standard_normal(3)
        p, v = p + t * v + 0.5 * t * t * a_W, v + t * a_W
        pt, vt = pt + t * vt + 0.5 * t * t * a_T, vt + t * a_T
        if raw is None:
            x_hat, P = predict(x_hat, P, a_W, A, B, Q)
        else:
            raw.predict(a_W)
            x_hat, P = raw.x, raw.P
    return out


@dataclass
class MonteCarloSummary:
    """Steady-state statistics of an estimator over runs (k ≥ start).

    ``pcrlb_*`` is the proven bound (measurement information averaged over runs,
    :func:`pcrlb_monte_carlo`); ``per_run_bound_*`` the mean of the per-run bounds
    (:func:`pcrlb_per_run_mean`), what a run-by-run efficient estimator attains.
    """

    position_rmse: float
    velocity_rmse: float
    pcrlb_position_rmse: float
    pcrlb_velocity_rmse: float
    per_run_bound_position_rmse: float
    per_run_bound_velocity_rmse: float
    per_run_position_mse: np.ndarray  # (runs,) mean over k ≥ start of |q̂ − q|²
    per_run_velocity_mse: np.ndarray
    per_run_nees: np.ndarray  # (runs,) mean over k ≥ start of eᵀ P⁻¹ e
    runs: list[RunResult]

    @property
    def position_ratio(self) -> float:
        return self.position_rmse / self.pcrlb_position_rmse

    @property
    def velocity_ratio(self) -> float:
        return self.velocity_rmse / self.pcrlb_velocity_rmse

    @property
    def mean_nees(self) -> float:
        return float(self.per_run_nees.mean())

    def ratio_standard_errors(self) -> tuple[float, float]:
        """Standard errors of the two ratios from the between-run spread (delta method:
        ``se(√m̂) ≈ se(m̂)/(2√m̂)``), runs being independent; the bound is treated as exact."""
        out = []
        for mse, bound in (
            (self.per_run_position_mse, self.pcrlb_position_rmse),
            (self.per_run_velocity_mse, self.pcrlb_velocity_rmse),
        ):
            se_mse = mse.std(ddof=1) / math.sqrt(mse.size)
            out.append(se_mse / (2.0 * math.sqrt(mse.mean())) / bound)
        return out[0], out[1]

    def nees_standard_error(self) -> float:
        return float(self.per_run_nees.std(ddof=1) / math.sqrt(self.per_run_nees.size))


def monte_carlo(
    scenario: ReferenceScenario,
    estimator: str,
    runs: int,
    first_seed: int = 0,
    policy: HandoverPolicy | None = None,
    control_from_truth: bool = False,
) -> MonteCarloSummary:
    """``runs`` seeded runs (seeds ``first_seed + i``) and the bounds on their trajectories."""
    s = scenario
    start = s.steady_state_start
    results = [
        simulate(s, estimator, first_seed + i, policy, control_from_truth=control_from_truth)
        for i in range(runs)
    ]
    pos_mse, vel_mse, nees = [], [], []
    for r in results:
        e = r.x_hat[start:] - r.x_true[start:]
        pos_mse.append(np.mean(np.sum(e[:, :3] ** 2, axis=1)))
        vel_mse.append(np.mean(np.sum(e[:, 3:] ** 2, axis=1)))
        Pe = np.linalg.solve(r.P[start:], e[:, :, None])[:, :, 0]
        nees.append(np.mean(np.einsum("ki,ki->k", e, Pe)))
    args = (
        np.stack([r.x_true[:, :3] for r in results]),
        np.stack([r.q_s for r in results]),
        s.P0,
        s.W,
        s.eta,
        s.samples_per_step,
        s.time_step,
    )
    b_pos, b_vel = bound_rmse(pcrlb_monte_carlo(*args), start)
    m_pos, m_vel = bound_rmse(pcrlb_per_run_mean(*args), start)
    pos_mse, vel_mse = np.array(pos_mse), np.array(vel_mse)
    return MonteCarloSummary(
        position_rmse=float(np.sqrt(pos_mse.mean())),
        velocity_rmse=float(np.sqrt(vel_mse.mean())),
        pcrlb_position_rmse=b_pos,
        pcrlb_velocity_rmse=b_vel,
        per_run_bound_position_rmse=m_pos,
        per_run_bound_velocity_rmse=m_vel,
        per_run_position_mse=pos_mse,
        per_run_velocity_mse=vel_mse,
        per_run_nees=np.array(nees),
        runs=results,
    )


def kf_riccati_rmse(summary: MonteCarloSummary, scenario: ReferenceScenario) -> tuple[float, float]:
    """The KF's own bound: its Riccati covariance with Γ on the true ranges, mean over runs."""
    s = scenario
    covs = np.mean(
        [kf_riccati_covariance(r.q_s, s.P0, s.W, r.gamma_true, s.time_step) for r in summary.runs],
        axis=0,
    )
    return bound_rmse(covs, s.steady_state_start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--estimators", nargs="+", default=list(ESTIMATORS), choices=ESTIMATORS)
    parser.add_argument("--samples-per-step", type=int, default=1)
    parser.add_argument(
        "--threshold", type=float, default=HandoverPolicy().position_variance_threshold
    )
    parser.add_argument(
        "--control-from-truth",
        action="store_true",
        help="diagnostic: track the true relative state (geometry independent of the estimate)",
    )
    args = parser.parse_args()
    scenario = ReferenceScenario(samples_per_step=args.samples_per_step)
    policy = HandoverPolicy(position_variance_threshold=args.threshold)
    print(
        f"{args.runs} runs, k >= {scenario.steady_state_start}; ratio = RMSE / PCRLB "
        "(± one standard error); per-run = RMSE / mean of per-run bounds"
    )
    print(
        f"{'estimator':<9} {'pos RMSE':>8} {'PCRLB':>7} {'ratio':>12} {'per-run':>7}  "
        f"{'vel RMSE':>8} {'PCRLB':>7} {'ratio':>12} {'per-run':>7}  {'NEES':>11}  time"
    )
    for name in args.estimators:
        t0 = time.perf_counter()
        m = monte_carlo(
            scenario, name, args.runs, policy=policy, control_from_truth=args.control_from_truth
        )
        se_p, se_v = m.ratio_standard_errors()
        print(
            f"{name:<9} {m.position_rmse:8.4f} {m.pcrlb_position_rmse:7.4f} "
            f"{m.position_ratio:6.3f}±{se_p:.3f} "
            f"{m.position_rmse / m.per_run_bound_position_rmse:7.3f}  "
            f"{m.velocity_rmse:8.4f} {m.pcrlb_velocity_rmse:7.4f} "
            f"{m.velocity_ratio:6.3f}±{se_v:.3f} "
            f"{m.velocity_rmse / m.per_run_bound_velocity_rmse:7.3f}  "
            f"{m.mean_nees:5.2f}±{m.nees_standard_error():.2f}  "
            f"{time.perf_counter() - t0:.1f} s"
        )
        if name == "kf":
            r_pos, r_vel = kf_riccati_rmse(m, scenario)
            print(f"{'':<9} KF Riccati covariance (its own bound): pos {r_pos:.4f} vel {r_vel:.4f}")


if __name__ == "__main__":
    main()
