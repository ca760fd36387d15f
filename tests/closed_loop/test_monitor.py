"""The run monitor stops a broken estimator with a message that says which check and when."""

import math

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.cli import main
from drake_uuv.monitor import SimulationFailure
from tests.closed_loop.user_systems import ConstantEstimator

SHORT = ["steps=80", "steady_state_start=0"]
#: A healthy-looking estimate: near q*, a consistent covariance and NIS.
X = np.array([-2.0, -2.0, 0.0, 0.0, 0.0, 0.0])
P = 0.1 * np.eye(6)


class BrokenEstimator(ConstantEstimator):
    """A constant estimate with NIS 0.5, sabotaged from step ``at`` on by ``how``."""

    def __init__(self, how: str, at: int) -> None:
        super().__init__(X, P)
        self._how, self._at = how, at

    def estimate(self, context):
        if round(context.get_time() / 0.5) < self._at:
            return X, P, 0.5
        if self._how == "indefinite":
            broken = P.copy()
            broken[0, 0] = -1.0
            return X, broken, 0.5
        if self._how == "asymmetric":
            broken = P.copy()
            broken[0, 1] += 0.5
            return X, broken, 0.5
        if self._how == "nan":
            return np.full(6, math.nan), P, 0.5
        if self._how == "innovations":
            return X, P, 1e4
        raise ValueError(self._how)


@pytest.fixture
def broken(monkeypatch):
    def use(how: str, at: int) -> None:
        # The builder's estimator, for runs that take no systems (the command line).
        monkeypatch.setattr(
            "drake_uuv.diagram.make_estimator", lambda scenario, **_: BrokenEstimator(how, at)
        )

    return use


@pytest.mark.parametrize(
    "how, message, step",
    [
        ("indefinite", r"covariance P is not positive definite \(eigenvalue -1", 30),
        ("asymmetric", r"covariance P is not symmetric", 30),
        ("nan", r"estimator output is not finite", 30),
        ("innovations", r"innovations blew up: median NIS 5e\+03 over the last 20 updates", 39),
    ],
)
def test_monitor_stops_the_run_and_says_which_and_when(how, message, step) -> None:
    estimator = BrokenEstimator(how, 30)
    simulation = ClosedLoopSimulation(
        load_scenario("paper", SHORT), systems={"estimator": estimator}
    )
    with pytest.raises(SimulationFailure, match=message) as info:
        simulation.run()
    assert f"at step k={step} (t={step * 0.5:g} s)" in str(info.value)
    assert str(info.value).startswith("seed 0: run stopped: ")
    # The failure is the monitor's record, not text read back from the Simulator's error.
    assert str(info.value) == f"seed 0: run stopped: {simulation.monitor.failure}"
    assert isinstance(info.value.__cause__, RuntimeError)
    # The next run starts afresh.
    simulation.monitor.reset()
    assert simulation.monitor.failure is None


def test_other_simulator_errors_are_not_taken_for_the_monitors() -> None:
    """An error the monitor did not record passes through unchanged, whatever its text."""

    class Failing(ConstantEstimator):
        def estimate(self, context):
            if context.get_time() > 5.0:
                raise RuntimeError("estimator exploded (not the monitor's finding)")
            return X, P, 0.5

    simulation = ClosedLoopSimulation(
        load_scenario("paper", SHORT), systems={"estimator": Failing(X, P)}
    )
    with pytest.raises(RuntimeError, match="not the monitor's finding") as info:
        simulation.run()
    assert not isinstance(info.value, SimulationFailure)
    assert simulation.monitor.failure is None


def test_a_factorisation_that_fails_inside_an_update_stops_the_run_with_its_step() -> None:
    """A UKF's sigma points or a gain factorise P inside the update, before the monitor sees
    the step: the run stops as a failure, not with numpy's traceback."""

    class Factorising(ConstantEstimator):
        def estimate(self, context):
            if context.get_time() >= 12.0:
                np.linalg.cholesky(-np.eye(2))
            return X, P, 0.5

    simulation = ClosedLoopSimulation(
        load_scenario("paper", SHORT), systems={"estimator": Factorising(X, P)}
    )
    with pytest.raises(SimulationFailure) as info:
        simulation.run()
    assert str(info.value) == (
        "seed 0: run stopped: a covariance or innovation matrix could not be factorised "
        "(Matrix is not positive definite) in the update after step k=24 (t=12 s)"
    )
    assert isinstance(info.value.__cause__, np.linalg.LinAlgError)


def test_cli_reports_a_stopped_run_in_one_line(broken, capsys, tmp_path) -> None:
    broken("indefinite", 10)
    assert main(["run", "--out", str(tmp_path), *sum((["--set", s] for s in SHORT), [])]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not positive definite" in err and "k=10" in err
    assert not (tmp_path / "log.npz").exists()


@pytest.mark.slow
def test_healthy_runs_are_not_stopped() -> None:
    # A fixed attitude diverges, but consistently: the monitor must let it run.
    for tag in ("FixedAttitude", "RandomAttitude", "TrajectoryAttitude"):
        result = ClosedLoopSimulation(load_scenario("paper", [f"attitude=!{tag}"])).run()
        assert result.steps == 500
