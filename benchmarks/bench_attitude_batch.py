"""Cost of a step of each attitude generator, for one run and per run of a batch.

A step: new inputs fixed (``R_WB_nav``, and ``rotation_noise``, ``x_TU_hat``, ``P_TU`` where
the system has them), ``u2_W`` and ``R_WB_plan`` evaluated and, for a system with state, its
discrete update; the time advances one period, so Algorithm 2 computes a new ``R̄(k)``. Each
figure is the fastest of ``--repeats`` timings of ``--steps`` steps.

    python benchmarks/bench_attitude_batch.py [--batch 1 1000] [--steps 100] [--repeats 3]
"""

import argparse
import time

import numpy as np

from drake_uuv.attitude import make_attitude_generator
from drake_uuv.models.so3 import exp_so3_runs
from drake_uuv.scenario import load_scenario

PLANNER = "attitude=!InformationSeeking"
EKF = ["estimator=!Ekf", "estimator.linear_start_max_steps=0"]  # ranges from the start
#: Each generator's overrides of the paper scenario.
VARIANTS = {
    "fixed": ["attitude=!FixedAttitude"],
    "random (Algorithm 1)": ["attitude=!RandomAttitude"],
    "random, rate limit": ["attitude=!RandomAttitude {max_angular_rate: 0.5}"],
    "trajectory (Algorithm 2)": ["attitude=!TrajectoryAttitude"],
    "trajectory, rate limit": ["attitude=!TrajectoryAttitude {max_angular_rate: 0.5}"],
    "planner: kf (cap)": [PLANNER],
    "planner: ekf (cap, hold)": [f"{PLANNER} {{position_prediction: hold}}", *EKF],
    "planner: ekf (ball, reference, H=2)": [PLANNER, *EKF],
}


def step_inputs(batch: int, steps: int, seed: int = 0) -> list[dict[str, np.ndarray]]:
    """Random inputs of each step, every port's batch flattened row-major."""
    rng = np.random.default_rng(seed)
    data = []
    for _ in range(steps):
        M = rng.normal(size=(batch, 6, 6))
        data.append({
            "R_WB_nav": exp_so3_runs(rng.normal(size=(batch, 3))).ravel(),
            "x_TU_hat": 2.0 * rng.normal(size=6 * batch),
            "P_TU": (M @ M.transpose(0, 2, 1) + 0.01 * np.eye(6)).ravel(),
            "rotation_noise": rng.normal(size=4 * batch),
        })  # fmt: skip
    return data


def time_steps(overrides: list[str], batch: int, data: list[dict[str, np.ndarray]]) -> float:
    """Seconds per step of the generator of ``overrides`` stepping ``batch`` runs."""
    scenario = load_scenario("paper", overrides)
    system = make_attitude_generator(scenario, batch_size=batch)
    context = system.CreateDefaultContext()
    ports = [system.get_input_port(i) for i in range(system.num_input_ports())]
    rate, plan = system.GetOutputPort("u2_W"), system.GetOutputPort("R_WB_plan")
    stateful = context.num_discrete_state_groups() > 0
    start = time.perf_counter()
    for k, values in enumerate(data):
        context.SetTime(k * scenario.time_step)
        for port in ports:
            port.FixValue(context, values[port.get_name()])
        rate.Eval(context)
        plan.Eval(context)
        if stateful:
            context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
    return (time.perf_counter() - start) / len(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 1000])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    for batch in args.batch:
        for name, overrides in VARIANTS.items():
            steps = max(3, args.steps // batch) if name.startswith("planner") else args.steps
            data = step_inputs(batch, steps)
            time_steps(overrides, batch, data[:2])  # compiled kernels loaded, caches warm
            best = min(time_steps(overrides, batch, data) for _ in range(args.repeats))
            print(
                f"B={batch:5d}  {name:38s} {best * 1e6:10.1f} µs a step, "
                f"{best * 1e6 / batch:8.2f} µs a run"
            )


if __name__ == "__main__":
    main()
