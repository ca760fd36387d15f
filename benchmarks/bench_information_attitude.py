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

from drake_uuv.attitude.information_seeking import InformationSeekingAttitude
from drake_uuv.models.information_planner import InformationSeekingPlanner
from drake_uuv.models.so3 import exp_so3

T = 0.5
B = np.array([-1.0, 1.0, 0.0])
W = np.diag([0.004, 0.001, 0.001])
ETA = np.array([0.01, 0.01])
Q_STAR = np.array([-2.0, -2.0, 0.0])
VARIANTS = {
    "kf (range_difference, cap)": {},
    "ekf (ranges, cap, hold)": {"measurement_model": "ranges"},
    "ekf (ranges, ball, reference lag 1: H=2)": {
        "measurement_model": "ranges",
        "position_prediction": "reference",
        "reference_lag": 1,
    },
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


def time_system(planner: InformationSeekingPlanner, data: list) -> float:
    system = InformationSeekingAttitude(planner)
    context = system.CreateDefaultContext()
    ports = [system.GetInputPort(name) for name in ("R_WB", "x_TU_hat", "P_TU")]
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
    for name, options in VARIANTS.items():
        planner = InformationSeekingPlanner(
            T, B, W, ETA, desired_relative_position=Q_STAR, **options
        )
        candidates = len(planner.candidate_rotations(np.eye(3)))
        plan = statistics.median(time_planner(planner, data, history) for _ in range(args.repeats))
        step = statistics.median(time_system(planner, data) for _ in range(args.repeats))
        print(
            f"{name}: {candidates} candidates, scored horizon {planner.scored_horizon}; "
            f"plan {plan * 1e6:.0f} µs, system step {step * 1e6:.0f} µs"
        )


if __name__ == "__main__":
    main()
