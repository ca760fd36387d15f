"""One estimator step (filtered estimate and periodic update) per run, at batch sizes B.

``python benchmarks/bench_estimator_step.py [B ...]``: for the paper's KF, the EKF, the IEKF
and the UKF (Gaussian phase from the first step) and the EKF's linear start, the best time of
one step (an input fixed anew, then ``EvalUniquePeriodicDiscreteUpdate``, which evaluates the
filtered estimate) per batch and per run.
"""

import sys
import time

import numpy as np

from drake_uuv.estimators import make_estimator
from drake_uuv.models.measurement import range_measurement
from drake_uuv.scenario import load_scenario

VARIANTS = {
    "kf": [],
    "ekf": ["estimator=!Ekf", "estimator.handover=threshold", "estimator.linear_start_max_steps=0"],
    "iekf": [
        "estimator=!Iekf",
        "estimator.handover=threshold",
        "estimator.linear_start_max_steps=0",
    ],
    "ukf": ["estimator=!Ukf", "estimator.handover=threshold", "estimator.linear_start_max_steps=0"],
    "ekf-linear": ["estimator=!Ekf", "estimator.particle_bridge=false"],
    # late ranges: both sonars' ranges two ticks after their pings
    "kf-late": ["sonar.ping_offsets=[0.1, 0.3]", "sonar.latency=0.6"],
    "ekf-late": [
        "estimator=!Ekf",
        "estimator.handover=threshold",
        "estimator.linear_start_max_steps=0",
        "sonar.ping_offsets=[0.1, 0.3]",
        "sonar.latency=0.6",
    ],
}


def make(overrides: list[str], batch_size: int):
    scenario = load_scenario("paper", overrides)
    try:
        return make_estimator(scenario, batch_size=batch_size)
    except TypeError:  # before the batch
        assert batch_size == 1
        return make_estimator(scenario)


def step_time(name: str, batch_size: int, repeats: int = 300) -> float:
    system = make(VARIANTS[name], batch_size)
    context = system.CreateDefaultContext()
    B = batch_size
    rng = np.random.default_rng(0)
    q_s = np.array([-1.0, 1.0, 0.0])
    x = np.array([-2.0, -2.0, 0.0, 0.0, 0.0, 0.0])
    d = range_measurement(x, q_s)
    f = system.GetInputPort("range_samples").size() // (2 * B)
    samples = d[:, None] + 0.1 * rng.standard_normal((B, 2, f))
    fixed = {"sonar_status": np.zeros(2 * B), "R_WB_nav": np.tile(np.eye(3).ravel(), B)}
    if system.HasInputPort("u1_W"):
        fixed["u1_W"] = np.zeros(3 * B)
    if system.HasInputPort("ping_time"):  # this tick's arrivals: the pings of two ticks ago
        context.SetTime(10 * 0.5)
        fixed["ping_time"] = np.tile([8 * 0.5 + 0.1, 8 * 0.5 + 0.3], B)
    for port, value in fixed.items():
        system.GetInputPort(port).FixValue(context, value)
    port = system.GetInputPort("range_samples")
    values = [samples.ravel(), (samples + 1e-3).ravel()]
    best = np.inf
    for i in range(repeats):
        port.FixValue(context, values[i % 2])
        start = time.perf_counter()
        system.EvalUniquePeriodicDiscreteUpdate(context)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1]
    for name in VARIANTS:
        for B in sizes:
            t = step_time(name, B, 300 if B < 100 else 30)
            print(f"{name:10s} B={B:5d}: {t * 1e6:9.1f} µs a step, {t / B * 1e6:8.2f} µs a run")


if __name__ == "__main__":
    main()
