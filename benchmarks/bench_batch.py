"""The cost a run of a study, as one diagram stepping a batch of runs, at several batch sizes.

For each configuration and batch size B it times ``ClosedLoopSimulation(scenario,
log="metrics", batch_size=B).run_batch(seeds)`` (the diagram built beforehand, as a study's
worker keeps it) and prints the wall time per run. For the paper's configuration it also times
a plain batched numpy loop of the same arithmetic written here (the kinematic plant, the
target, the sonars, the paper's KF in Joseph form, Algorithm 2 and the paper's law, each run's
noise drawn from its own stream), interleaved with the diagram so that both see the same
machine, and prints their ratio: what the framework and the systems' generality cost over
the bare arithmetic.

    python benchmarks/bench_batch.py                       # every configuration, B = 1..1000
    python benchmarks/bench_batch.py --configs paper --sizes 1 100 --steps 200
"""

import argparse
import math
import time

import numpy as np
from threadpoolctl import threadpool_limits

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.models.so3 import exp_so3_runs, log_so3_runs, minimal_rotation_runs
from drake_uuv.primitives.run_noise import run_draws

#: Configuration name → (scenario, overrides).
CONFIGS = {
    "paper": ("paper", []),
    "ekf": ("paper", ["estimator=Ekf"]),
    "hovering_auv": ("hovering_auv", []),
    "particle_filter": ("paper", ["estimator=ParticleFilter"]),
    "realistic": ("realistic", []),
}


def time_diagram(scenario, batch_size: int, repeats: int) -> float:
    """Best wall time of ``repeats`` batches [s per run]."""
    simulation = ClosedLoopSimulation(scenario, log="metrics", batch_size=batch_size)
    seeds = np.arange(batch_size) + scenario.random_seed
    simulation.run_batch(seeds)  # warm: compiled kernels, first-call caches
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        simulation.run_batch(seeds)
        best = min(best, time.perf_counter() - start)
    return best / batch_size


def plain_paper_loop(scenario, seeds: np.ndarray) -> np.ndarray:
    """The paper's loop for a batch of runs in plain numpy; returns each run's position RMSE
    from the steady-state start (to check it does the same work)."""
    B, t, N = len(seeds), scenario.time_step, scenario.steps
    b = np.asarray(scenario.sonar.baseline, float)
    eta = np.asarray(scenario.sonar.noise_variances, float)
    L = np.linalg.cholesky(np.asarray(scenario.target.acceleration_covariance, float))
    A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    Bm = np.vstack([0.5 * t * t * np.eye(3), t * np.eye(3)])
    Q = Bm @ np.asarray(scenario.target.acceleration_covariance, float) @ Bm.T
    alpha = scenario.tracking.alpha
    k_p, k_v = 2 * alpha / t**2, 2 / t
    q_star = np.asarray(scenario.tracking.desired_relative_position, float)
    att = scenario.attitude
    p = np.tile(np.asarray(scenario.uuv.initial_position, float), (B, 1))
    v = np.tile(np.asarray(scenario.uuv.initial_velocity, float), (B, 1))
    R = np.tile(np.eye(3), (B, 1, 1))
    pt = np.tile(np.asarray(scenario.target.initial_position, float), (B, 1))
    vt = np.tile(np.asarray(scenario.target.initial_velocity, float), (B, 1))
    x = np.tile(np.asarray(scenario.estimator.initial_estimate, float), (B, 1))
    P = np.tile(np.asarray(scenario.estimator.initial_covariance, float), (B, 1, 1))
    sq = np.zeros(B)
    for k in range(N):
        q_s = R @ b
        q = p - pt
        d = np.stack(
            [np.linalg.norm(q + 0.5 * q_s, axis=1), np.linalg.norm(q - 0.5 * q_s, axis=1)], 1
        )
        d = d + np.sqrt(eta) * run_draws(seeds, "range_noise", k, 2)
        Y = 0.5 * (d[:, 0] ** 2 - d[:, 1] ** 2)
        m = 0.5 * (eta[0] - eta[1])
        gamma = eta[0] * np.maximum(d[:, 0] ** 2 - eta[0], 0) + eta[1] * np.maximum(
            d[:, 1] ** 2 - eta[1], 0
        )
        gamma = gamma + 0.5 * (eta[0] ** 2 + eta[1] ** 2)
        C = np.concatenate([q_s, np.zeros((B, 3))], axis=1)
        PC = (P @ C[:, :, None])[:, :, 0]
        S = (C * PC).sum(1) + gamma
        K = PC / S[:, None]
        x = x + K * (Y - (C * x).sum(1) - m)[:, None]
        I_KC = np.eye(6) - K[:, :, None] * C[:, None, :]
        P = (
            I_KC @ P @ I_KC.transpose(0, 2, 1)
            + gamma[:, None, None] * K[:, :, None] * K[:, None, :]
        )
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
        x = x @ A.T + a_W @ Bm.T
        P = A @ P @ A.T + Q
        p, v = p + t * v + 0.5 * t * t * a_W, v + t * a_W
        pt, vt = pt + t * vt + 0.5 * t * t * a_T, vt + t * a_T
        R = exp_so3_runs(u2 * t) @ R
    return np.sqrt(sq / (N - scenario.steady_state_start))


def time_plain(scenario, batch_size: int, repeats: int) -> float:
    seeds = np.arange(batch_size) + scenario.random_seed
    plain_paper_loop(scenario, seeds)
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        plain_paper_loop(scenario, seeds)
        best = min(best, time.perf_counter() - start)
    return best / batch_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    parser.add_argument("--sizes", nargs="+", type=int, default=[1, 10, 100, 1000])
    parser.add_argument(
        "--steps", type=int, default=None, help="steps a run (default: the scenario's)"
    )
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    print(
        f"{'configuration':<16} {'B':>5} {'diagram ms/run':>15} {'plain ms/run':>13} {'ratio':>6}"
    )
    with threadpool_limits(limits=1, user_api="blas"):
        for name in args.configs:
            base, overrides = CONFIGS[name]
            if args.steps is not None:
                overrides = [
                    *overrides,
                    f"steps={args.steps}",
                    f"steady_state_start={args.steps // 2}",
                ]
            scenario = load_scenario(base, overrides)
            for B in args.sizes:
                try:
                    diagram = time_diagram(scenario, B, args.repeats)
                except Exception as e:  # a configuration whose systems cannot batch yet
                    print(f"{name:<16} {B:>5} {'-':>15}   ({type(e).__name__}: {str(e)[:80]})")
                    continue
                plain = time_plain(scenario, B, args.repeats) if name == "paper" else math.nan
                ratio = diagram / plain if name == "paper" else math.nan
                print(
                    f"{name:<16} {B:>5} {1e3 * diagram:>15.2f} {1e3 * plain:>13.2f} {ratio:>6.2f}"
                )


if __name__ == "__main__":
    main()
