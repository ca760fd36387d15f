"""A run that breaks its own assumptions says so: each warning's cause, from synthetic logs
and metrics, the NEES band from χ² and the autocorrelation time, and the CLI's output."""

import json

import numpy as np
import pytest

from drake_uuv.cli import main
from drake_uuv.diagnostics import nees_band, run_nees_band, run_warnings
from drake_uuv.models.handover import Phase
from drake_uuv.models.statistics import chi2_ppf, integrated_autocorrelation_time
from drake_uuv.scenario import load_scenario

STEPS = 60


def _log(nees_scale: float = 1.0, phase: float | None = None, seed: int = 0) -> dict:
    """A log whose errors have the covariance P·nees_scale (NEES ≈ 6·nees_scale per step)."""
    rng = np.random.default_rng(seed)
    P = np.tile(np.eye(6), (STEPS, 1, 1))
    e = rng.standard_normal((STEPS, 6)) * np.sqrt(nees_scale)
    log = {
        "p_WU": np.zeros((STEPS, 3)), "v_WU": np.zeros((STEPS, 3)),
        "p_WT": -e[:, :3], "v_WT": -e[:, 3:],  # q − q̂ = e with x̂ = 0
        "x_TU_hat": np.zeros((STEPS, 6)), "P_TU": P,
        "R_WB": np.tile(np.eye(3), (STEPS, 1, 1)), "b_W": np.tile([1.0, 0, 0], (STEPS, 1)),
    }  # fmt: skip
    if phase is not None:
        log["estimator_phase"] = np.tile([phase, 0.0], (STEPS, 1))
    return log


SCENARIO = load_scenario("paper", [f"steps={STEPS}", "steady_state_start=10"])


def _codes(log: dict, **metrics) -> list[str]:
    values = {"nees_mean": 6.0, "tracking_rmse": 1.0, **metrics}
    return [w.code for w in run_warnings(log, values, SCENARIO)]


def test_a_sound_run_has_no_warning():
    assert _codes(_log(), nees_mean=6.0) == []


@pytest.mark.parametrize(
    "metrics, log, code",
    [
        (dict(thrust_saturated_fraction=0.8), _log(), "saturation"),
        (dict(nees_mean=60.0), _log(), "nees"),
        (dict(nees_mean=0.6), _log(), "nees"),
        (dict(tracking_rmse=25.0), _log(), "tracking"),
        (dict(tracking_rmse=float("nan")), _log(), "tracking"),
        ({}, _log(phase=float(Phase.LINEAR)), "linear_start"),
    ],
)
def test_each_broken_assumption_is_named(metrics, log, code):
    assert _codes(log, **metrics) == [code]


def test_a_filter_that_left_its_start_is_not_warned_of():
    log = _log(phase=float(Phase.LINEAR))
    log["estimator_phase"][-1, 0] = float(Phase.RANGE)
    assert _codes(log) == []


def test_the_band_is_chi_square_of_the_effective_samples():
    low, high = nees_band(50)
    assert low == pytest.approx(chi2_ppf(0.0005, 300) / 50)
    assert high == pytest.approx(chi2_ppf(0.9995, 300) / 50)
    white = 6.0 + np.random.default_rng(1).standard_normal(400)
    assert run_nees_band(white)[2] == pytest.approx(400, rel=0.25)


@pytest.mark.parametrize("phi", [0.0, 0.5, 0.9])
def test_the_autocorrelation_time_of_an_ar1_series(phi):
    """τ = (1 + φ)/(1 − φ) for x(k+1) = φ x(k) + w; n = 200000, within 10 %."""
    rng = np.random.default_rng(2)
    n = 200_000
    w = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = w[0]
    for k in range(1, n):
        x[k] = phi * x[k - 1] + w[k]
    assert integrated_autocorrelation_time(x) == pytest.approx((1 + phi) / (1 - phi), rel=0.1)


@pytest.mark.slow
def test_the_papers_commands_on_the_vehicle_warn_of_saturation(tmp_path, capsys):
    out = tmp_path / "vehicle"
    assert main(["run", "--set", "plant=HoveringAuv", "--set", "steps=80",
                 "--set", "steady_state_start=40", "--out", str(out)]) == 0  # fmt: skip
    printed = capsys.readouterr().out.splitlines()
    assert any(line.startswith("WARNING: thrusters saturated") for line in printed)
    assert "use --scenario hovering_auv" in "\n".join(printed)
    codes = [w["code"] for w in json.loads((out / "metrics.json").read_text())["warnings"]]
    assert "saturation" in codes
