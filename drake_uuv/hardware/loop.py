"""The loop's two halves over LCM: in one process in lockstep, or each in its own.

Each step k, in this order (:mod:`.channels` lists what each channel carries):

1. the vehicle half publishes its channels at ``t_k`` (its state of step k);
2. the onboard half receives them, computes the step's estimate and commands and publishes;
3. the vehicle half receives the commands;
4. both halves step their ``Simulator`` to ``t_{k+1}``: the vehicle's plant applies the
   commands, the estimator predicts.

Before the first step the vehicle sends its state at initialization, which the onboard half
initializes from (the estimator's frame of the vehicle's navigated motion), as in one diagram.
Every signal is then computed from the same inputs as in :func:`drake_uuv.make_uuv_diagram`'s
diagram, and each half's noise from the same per-run sources: the run's log and metrics are
the single diagram's, bit for bit. The estimator-health monitor does not watch these runs.
"""

import math
import time
from collections.abc import Callable

import numpy as np
from drake import lcmt_scope
from pydrake.lcm import DrakeLcm

from drake_uuv.diagnostics import run_warnings
from drake_uuv.diagram import make_systems
from drake_uuv.hardware.channels import INITIALIZED, READY, check_url
from drake_uuv.hardware.halves import Half, LcmTimeout
from drake_uuv.metrics import run_metrics
from drake_uuv.models.tracking_laws import closed_loop_eigenvalues
from drake_uuv.primitives.threads import on_one_blas_thread
from drake_uuv.scenario import Scenario
from drake_uuv.signals import Signal, logged_signals
from drake_uuv.simulation import SimulationResult

__all__ = ["LcmTimeout", "run_lcm", "run_onboard", "run_vehicle"]


def _halves(
    scenario: Scenario, lcm: DrakeLcm, sides: tuple[str, ...], timeout: float
) -> tuple[dict[str, Half], list[Signal]]:
    systems = make_systems(scenario)
    signals = logged_signals(systems)
    halves = {
        side: Half(
            side,
            systems,
            lcm,
            time_step=scenario.time_step,
            signals=signals,
            seed=scenario.random_seed,
            timeout=timeout,
        )  # fmt: skip
        for side in sides
    }
    return halves, signals


def _log(rows: list[dict[str, np.ndarray]], signals: list[Signal], t: float) -> dict:
    """Per-step samples as a run's log: each signal ``(N, *shape)``, ``k`` and ``time``."""
    N = len(rows)
    log: dict[str, np.ndarray] = {"k": np.arange(N), "time": np.arange(N) * t}
    for signal in signals:
        if signal.name not in rows[0]:
            continue
        data = np.array([row[signal.name] for row in rows])
        shape = signal.shape if all(n > 0 for n in signal.shape) else (-1,)
        data = data.reshape(N, *shape)
        log[signal.name] = data.astype(np.int8) if signal.integer else data
    return log


@on_one_blas_thread  # as ClosedLoopSimulation steps: the same bits
def run_lcm(scenario: Scenario, url: str = "memq://", timeout: float = 10.0) -> SimulationResult:
    """Runs ``scenario`` (seeded by its ``random_seed``) as its two halves over LCM at ``url``,
    in this process, in lockstep: the result of :meth:`ClosedLoopSimulation.run`, bit for bit
    (its ``wall_time_s`` aside)."""
    start = time.perf_counter()
    halves, signals = _halves(scenario, DrakeLcm(check_url(url)), ("vehicle", "onboard"), timeout)
    vehicle, onboard = halves["vehicle"], halves["onboard"]
    vehicle.publish()  # the state at initialization
    onboard.receive(None)
    onboard.initialize()
    vehicle.initialize()
    rows = []
    for k in range(scenario.steps):
        if k:
            vehicle.advance(k)
            onboard.advance(k)
        vehicle.publish()
        onboard.receive(k)
        onboard.publish()
        vehicle.receive(k)
        rows.append({**vehicle.sample(), **onboard.sample()})
    log = _log(rows, signals, scenario.time_step)
    metrics = run_metrics(log, scenario)
    gain = getattr(onboard.systems["tracking_controller"], "gain", None)
    metrics.update(
        tracking_spectral_radius=math.nan
        if gain is None
        else float(np.max(np.abs(closed_loop_eigenvalues(scenario.time_step, gain)))),
        steps=float(scenario.steps),
        seed=float(scenario.random_seed),
        wall_time_s=time.perf_counter() - start,
    )
    warnings = run_warnings(log, metrics, scenario)
    return SimulationResult(scenario=scenario, log=log, metrics=metrics, warnings=warnings)


@on_one_blas_thread  # as ClosedLoopSimulation steps: the same bits
def run_vehicle(
    scenario: Scenario, url: str, timeout: float = 30.0, progress: Callable | None = None
) -> dict[str, np.ndarray]:
    """The vehicle half alone over ``url``: waits for the onboard half's ready message, sends
    its first messages, waits for the onboard half to have initialized from them, then steps
    with it. Returns its log (the truth, the navigation, the sonars)."""
    lcm = DrakeLcm(check_url(url))
    halves, signals = _halves(scenario, lcm, ("vehicle",), timeout)
    vehicle = halves["vehicle"]
    heard: dict[str, bool] = {READY: False, INITIALIZED: False}
    for channel in heard:
        lcm.Subscribe(channel, lambda data, channel=channel: heard.__setitem__(channel, True))

    def wait_for(channel: str) -> None:
        deadline = time.monotonic() + timeout
        while not heard[channel]:
            if time.monotonic() > deadline:
                raise LcmTimeout(f"vehicle: no onboard half on {channel} within {timeout:g} s")
            lcm.HandleSubscriptions(50)

    wait_for(READY)
    vehicle.publish()
    vehicle.initialize()
    wait_for(INITIALIZED)  # step 0's messages only once the first ones are latched
    rows = []
    for k in range(scenario.steps):
        if k:
            vehicle.advance(k)
        vehicle.publish()
        vehicle.receive(k)
        rows.append(vehicle.sample())
    return _log(rows, signals, scenario.time_step)


@on_one_blas_thread  # as ClosedLoopSimulation steps: the same bits
def run_onboard(scenario: Scenario, url: str, timeout: float = 30.0) -> dict[str, np.ndarray]:
    """The onboard half alone over ``url``: says it is ready (``DRAKE_UUV_READY``, again
    until the vehicle answers), initializes from the vehicle's first messages, says so
    (``DRAKE_UUV_INITIALIZED``, again until step 0's messages come) and answers each step.
    Returns its log (the estimate, the commands, and what it received)."""
    lcm = DrakeLcm(check_url(url))
    halves, signals = _halves(scenario, lcm, ("onboard",), timeout)
    onboard = halves["onboard"]
    last = [0.0]

    def announcer(channel: str) -> Callable[[], None]:
        def announce() -> None:  # again every 0.1 s until the vehicle's next message
            if time.monotonic() - last[0] > 0.1:
                lcm.Publish(channel, lcmt_scope().encode())
                last[0] = time.monotonic()

        return announce

    onboard.receive(None, waiting=announcer(READY))
    onboard.initialize()
    rows = []
    for k in range(scenario.steps):
        if k:
            onboard.advance(k)
        onboard.receive(k, waiting=None if k else announcer(INITIALIZED))
        onboard.publish()
        rows.append(onboard.sample(received=True))
    return _log(rows, signals, scenario.time_step)
