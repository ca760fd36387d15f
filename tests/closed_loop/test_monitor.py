"""The run monitor stops a broken estimator with a message that says which check and when."""

import functools

import numpy as np
import pytest

from drake_uuv import ClosedLoopSimulation, load_scenario
from drake_uuv.cli import main
from drake_uuv.estimators import RangeDifferenceKalmanFilter
from drake_uuv.estimators.base import EstimatorSetting, MeasurementUpdate
from drake_uuv.estimators.factory import ESTIMATORS
from drake_uuv.monitor import SimulationFailure
from drake_uuv.scenario import PaperKf

SHORT = ["steps=80", "steady_state_start=0"]


class BrokenFilter(RangeDifferenceKalmanFilter):
    """The paper's KF, sabotaged from step ``at`` on by ``how``."""

    def __init__(self, config: PaperKf, *, setting: EstimatorSetting, how: str, at: int) -> None:
        super().__init__(config, setting=setting)
        self._how, self._at = how, at

    def measurement_update(self, context, prior, ranges):
        update = super().measurement_update(context, prior, ranges)
        if round(context.get_time() / 0.5) < self._at:
            return update
        if self._how == "indefinite":
            P = update.P.copy()
            P[0, 0] = -1.0
            return MeasurementUpdate(update.x, P, update.nis, 1)
        if self._how == "asymmetric":
            P = update.P.copy()
            P[0, 1] += 0.5
            return MeasurementUpdate(update.x, P, update.nis, 1)
        if self._how == "nan":
            return MeasurementUpdate(np.full(6, np.nan), update.P, update.nis, 1)
        if self._how == "innovations":
            return MeasurementUpdate(update.x, update.P, 1e4, 1)
        raise ValueError(self._how)


@pytest.fixture
def broken(monkeypatch):
    def use(how: str, at: int) -> None:
        # The estimator slot's factory builds the sabotaged filter for the paper's KF.
        monkeypatch.setitem(ESTIMATORS, PaperKf, functools.partial(BrokenFilter, how=how, at=at))

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
def test_monitor_stops_the_run_and_says_which_and_when(broken, how, message, step) -> None:
    broken(how, 30)
    simulation = ClosedLoopSimulation(load_scenario("paper", SHORT))
    with pytest.raises(SimulationFailure, match=message) as info:
        simulation.run()
    assert f"at step k={step} (t={step * 0.5:g} s)" in str(info.value)
    assert str(info.value).startswith("seed 0: run stopped: ")


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
