"""Per-step cost of the information-seeking attitude planner, alone and as a Drake system.

For each planned-for model it prints the number of candidates, the cost of one
``InformationSeekingPlanner.plan`` call, and the cost of one step of the
``InformationSeekingAttitude`` system (new inputs, ``u2_W`` and ``R_WB_plan`` evaluated —
two plans — and the discrete update), each the median of ``--repeats`` timings.

    python benchmarks/bench_information_attitude.py [--steps 200] [--repeats 5]
"""

import argparse
import statistics
import time

import numpy as np

from drake_uuv.attitude import make_attitude_generator
from drake_uuv.models.information_planner import InformationSeekingPlanner
from drake_uuv.models.so3 import exp_so3
from drake_uuv.scenario import Scenario, load_scenario

PLANNER = "attitude=!InformationSeeking"
EKF = ["estimator=!Ekf", "estimator.linear_start_max_steps=0"]  # ranges from the start
#: The paper scenario's overrides of each planned-for model.
VARIANTS = {
    "kf (range_difference, cap)": [PLANNER],
    "ekf (ranges, cap, hold)": [f"{PLANNER} {{position_prediction: hold}}", *EKF],
    "ekf (ranges, ball, reference lag 1: H=2)": [PLANNER, *EKF],
}


def inputs(steps: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(0)
    out = []
    for _ in range(steps):
        M = rng.normal(size=(6, 6))
        out.append((rng.normal(size=6), M @ M.T + 0.01 * np.eye(6), exp_so3(rng.normal(size=3))))
    return out


def time_planner(planner: InformationSeekingPlanner, data: list, history: np.ndarray) -> float:
    start = time.perf_counter()
    for x, P, R in data:
        planner.plan(x, P, R, history, R)
    return (time.perf_counter() - start) / len(data)


def time_system(scenario: Scenario, data: list) -> float:
    system = make_attitude_generator(scenario)
    context = system.CreateDefaultContext()
    ports = [system.GetInputPort(name) for name in ("R_WB_nav", "x_TU_hat", "P_TU")]
    rate, plan = system.GetOutputPort("u2_W"), system.GetOutputPort("R_WB_plan")
    start = time.perf_counter()
    for x, P, R in data:
        ports[0].FixValue(context, R.ravel())
        ports[1].FixValue(context, x)
        ports[2].FixValue(context, P.ravel())
        rate.Eval(context)
        plan.Eval(context)
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
    return (time.perf_counter() - start) / len(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    data = inputs(args.steps)
    history = np.random.default_rng(1).normal(size=(22, 3))
    for name, overrides in VARIANTS.items():
        scenario = load_scenario("paper", overrides)
        planner = make_attitude_generator(scenario).planner
        candidates = len(planner.candidate_rotations(np.eye(3)))
        plan = statistics.median(time_planner(planner, data, history) for _ in range(args.repeats))
        step = statistics.median(time_system(scenario, data) for _ in range(args.repeats))
        print(
            f"{name}: {candidates} candidates, scored horizon {planner.scored_horizon}; "
            f"plan {plan * 1e6:.0f} µs, system step {step * 1e6:.0f} µs"
        )


if __name__ == "__main__":
    main()
