"""Per-step cost of the Drake diagram against a plain numpy loop of the same math.

The plain loop below calls the same plain functions as the systems (``drake_uuv.models``: the
motion model, the Y-noise model, the KF update and prediction, Algorithm 2's plan and command,
the paper's tracking law), so the ratio measures what the systems framework costs: ports,
caching, events and loggers. Target: the paper run (``simulate``: build, simulation, metrics)
and the simulation alone, each within 1.5× of the plain loop.

    python benchmarks/bench_loop.py [--runs 7] [--steps 500]
"""

import argparse
import dataclasses
import math
import statistics
import time

import numpy as np

from drake_uuv.diagnostics import run_warnings
from drake_uuv.metrics import run_metrics
from drake_uuv.models.attitude_plans import attitude_command, trajectory_attitude
from drake_uuv.models.filters import predict, range_difference_update
from drake_uuv.models.measurement import range_difference_noise
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.so3 import exp_so3
from drake_uuv.models.tracking_laws import paper_gains, paper_tracking_command
from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.simulation import ClosedLoopSimulation, simulate

TARGET_RATIO = 1.5


def plain_loop(scenario: Scenario, seed: int) -> dict[str, np.ndarray]:
    """The paper's closed loop (Algorithm 2) as one numpy loop; returns the error norms."""
    rng = np.random.default_rng(seed)
    t, n = scenario.time_step, scenario.steps
    A, B = double_integrator(t)
    W = np.asarray(scenario.target.acceleration_covariance)
    L, Q = np.linalg.cholesky(W), process_noise_covariance(W, t)
    b = np.asarray(scenario.sonar.baseline)
    eta = np.asarray(scenario.sonar.noise_variances)
    k_p, k_v = paper_gains(t, scenario.tracking.alpha)
    q_star = np.asarray(scenario.tracking.desired_relative_position)
    plan = scenario.attitude
    x_uuv = np.zeros(6)
    x_target = np.concatenate([scenario.target.initial_position, scenario.target.initial_velocity])
    R = np.eye(3)
    x_pred = np.asarray(scenario.estimator.initial_estimate, dtype=float)
    P_pred = np.asarray(scenario.estimator.initial_covariance, dtype=float)
    position_error = np.empty(n)
    for k in range(n):
        # Sensor.
        q_s = R @ b
        q = x_uuv[:3] - x_target[:3]
        d = np.array([math.dist(q, -0.5 * q_s), math.dist(q, 0.5 * q_s)])
        d = d + np.sqrt(eta) * rng.standard_normal(2)
        m, gamma = range_difference_noise(scenario.estimator.noise_model, eta, d * d)
        Y = 0.5 * (d[0] ** 2 - d[1] ** 2)
        # Filter.
        x_hat, P, _ = range_difference_update(x_pred, P_pred, Y, m, gamma, q_s)
        position_error[k] = np.linalg.norm(q - x_hat[:3])
        # Controllers.
        u1 = paper_tracking_command(x_hat, R, q_star, k_p, k_v)
        R_desired = trajectory_attitude(k, b, plan.rho, plan.h_amplitude, plan.h_frequency)
        u2 = attitude_command(R_desired, R, t, plan.max_angular_rate)
        # Plant, target, prediction.
        a_W = R @ u1
        x_uuv = A @ x_uuv + B @ a_W
        R = exp_so3(u2 * t) @ R
        x_target = A @ x_target + B @ (L @ rng.standard_normal(3))
        x_pred, P_pred = predict(x_hat, P, a_W, A, B, Q)
    return {"position_error": position_error}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--steps", type=int, default=500)
    args = parser.parse_args()
    scenario = load_scenario("paper", [f"steps={args.steps}", "steady_state_start=0"])
    n = scenario.steps

    simulation = ClosedLoopSimulation(scenario)
    plain_loop(scenario, 0), simulation.run(0), simulate(scenario)  # warm-up
    times: dict[str, list[float]] = {"plain": [], "simulation": [], "run": [], "simulate": []}
    plain_rmse, diagram_rmse = [], []
    for seed in range(args.runs):  # interleaved: a drift in the machine's speed hits all alike
        tic = time.perf_counter()
        e = plain_loop(scenario, seed)["position_error"]
        times["plain"].append(time.perf_counter() - tic)
        plain_rmse.append(np.sqrt(np.mean(e[n // 2 :] ** 2)))
        tic = time.perf_counter()
        r = simulation.run(seed)
        times["run"].append(time.perf_counter() - tic)
        tic = time.perf_counter()
        run_warnings(r.log, run_metrics(r.log, r.scenario), r.scenario)  # what run() adds
        times["simulation"].append(times["run"][-1] - (time.perf_counter() - tic))
        e = np.linalg.norm(r.log["p_WU"] - r.log["p_WT"] - r.log["x_TU_hat"][:, :3], axis=1)
        diagram_rmse.append(np.sqrt(np.mean(e[n // 2 :] ** 2)))
        tic = time.perf_counter()
        simulate(dataclasses.replace(scenario, random_seed=seed))
        times["simulate"].append(time.perf_counter() - tic)

    low = {key: min(values) for key, values in times.items()}
    mid = {key: statistics.median(values) for key, values in times.items()}
    print(f"paper scenario, {n} steps, {args.runs} interleaved runs, min / median")
    for key, label in (
        ("plain", "plain numpy loop"),
        ("simulation", "diagram, simulation only"),
        ("run", "ClosedLoopSimulation.run (+ metrics, warnings)"),
        ("simulate", "simulate (+ build, metrics, warnings)"),
    ):
        print(
            f"  {label:46s}: {low[key] * 1e3:6.1f} / {mid[key] * 1e3:6.1f} ms"
            f"  ({mid[key] * 1e6 / n:6.1f} us/step)"
        )
    for key, label in (("simulation", "simulation only"), ("simulate", "paper run, simulate")):
        print(
            f"  ratio {label} / plain: {low[key] / low['plain']:.2f}x (min), "
            f"{mid[key] / mid['plain']:.2f}x (median)   (target <= {TARGET_RATIO}x)"
        )
    print(
        f"  same math, independent noise streams: position RMSE (k >= {n // 2}) plain "
        f"{np.mean(plain_rmse):.3f} m, diagram {np.mean(diagram_rmse):.3f} m"
    )


if __name__ == "__main__":
    main()
