"""Error statistics of runs, computed from their logs.

A run's log maps each signal's name to its values at the N steps (``N×shape``), plus ``k`` and
``time`` (N). A *batch log* holds B runs: each signal ``B×N×shape`` (run i in row i), ``k`` and
``time`` still (N), shared. :func:`batch_metrics` is the one implementation of the metrics,
over a batch (each metric a (B,) array, every reduction along a run's own steps, so run i's
metrics are the same bits as :func:`run_metrics` of its own log); :func:`run_metrics` is a
batch of one. :func:`errors` takes a run's log or a batch log alike (a leading run axis in, a
leading run axis out).

The views between a run's log and a batch log are :mod:`drake_uuv.batch_logs`'; the bounds
along a run's true trajectory (:func:`run_information`, :func:`bound_covariances`,
:func:`extended_bound`, :func:`ping_arrivals`, :func:`bound_errors_on`)
:mod:`drake_uuv.run_bounds`', whose RMSEs are among the metrics. Both are importable from
here too.
"""

import math

import numpy as np
from numba import njit

from drake_uuv.batch_logs import SHARED_KEYS, batch_log, run_log
from drake_uuv.models.pcrlb import bound_rmse_runs, cholesky6, lower_inverse6
from drake_uuv.models.tracking_laws import desired_relative_positions
from drake_uuv.run_bounds import (
    bound_covariances,
    bound_errors_on,
    extended_bound,
    ping_arrivals,
    run_information,
)
from drake_uuv.scenario import Scenario

# The batch logs' views and the bounds, importable from here as before.
__all__ = [
    "METRICS_CHUNK",
    "METRIC_SIGNALS",
    "SHARED_KEYS",
    "attitude_metrics",
    "batch_log",
    "batch_metrics",
    "bound_covariances",
    "bound_errors_on",
    "bound_metrics",
    "errors",
    "extended_bound",
    "metric_signals",
    "model_acceleration_rmse",
    "ping_arrivals",
    "rms_norm",
    "run_information",
    "run_log",
    "run_metrics",
    "smallest_eigenvalues",
    "vehicle_metrics",
]

#: The log's signals that a run's metrics and warnings (:func:`run_metrics`,
#: :func:`drake_uuv.diagnostics.run_warnings`) and a study's per-run arrays (errors, information)
#: read whatever the scenario: the truth, the estimate, the filter's input, the sonar's baseline
#: and returns, and a vehicle's or a filter's own signals (:func:`metric_signals`).
METRIC_SIGNALS = frozenset(
    {
        "p_WU", "v_WU", "R_WB", "p_WT", "v_WT", "x_TU_hat", "P_TU", "u1_W", "b_W",
        "sonar_status", "R_WB_command", "w_WB", "w_WB_command", "saturation_ticks",
        "estimator_phase",
    }
)  # fmt: skip


def metric_signals(scenario: Scenario) -> frozenset[str]:
    """The signals a run of ``scenario`` must log for its metrics and warnings: a run that logs
    only these (``ClosedLoopSimulation(..., log="metrics")``) has the same metrics.
    :data:`METRIC_SIGNALS`, and each ping's time and geometry where the bound is the
    extended one (:func:`bound_errors_on`)."""
    if bound_errors_on(scenario):
        return METRIC_SIGNALS | {"ping_time", "p_TS_W"}
    return METRIC_SIGNALS


def errors(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """Per-step errors: estimation (position, velocity), tracking, and NEES.

    - ``position``/``velocity`` (N×3): true minus filtered relative position/velocity.
    - ``tracking`` (N×3): ``q − R q*``, the offset from the desired relative position.
    - ``nees`` (N): ``eᵀ P⁻¹ e`` for the 6-D estimation error ``e``.

    A batch log gives each with a leading run axis (B×N×3, B×N).
    """
    q = log["p_WU"] - log["p_WT"]
    velocity = log["v_WU"] - log["v_WT"]
    e = np.concatenate([q, velocity], axis=-1) - log["x_TU_hat"]
    tracking = scenario.tracking
    return {
        "position": e[..., :3],
        "velocity": e[..., 3:],
        "tracking": q
        - desired_relative_positions(
            log["R_WB"], tracking.desired_relative_position, tracking.reference_frame
        ),
        "nees": _nees(e, log["P_TU"]),
        "relative_velocity": velocity,
    }


def _nees(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``eᵀ P⁻¹ e`` per step (any leading axes); ``inf`` where ``P`` is not finite and
    numerically positive definite (its smallest eigenvalue above ``6 ε`` times its largest):
    a covariance that lost definiteness, or so ill-conditioned that ``P⁻¹`` is rounding,
    claims no consistent error (without this a diverged filter's NEES could come out
    negative).

    Each step alone: a compiled loop factors ``P = L Lᵀ`` and, where ``1/tr(P⁻¹) > 12 ε tr(P)``
    (then ``λ_min ≥ 1/tr(P⁻¹) > 12 ε tr(P) ≥ 12 ε λ_max``: surely positive definite enough),
    gives ``|L⁻¹ e|²``; the rare rest (no factor, or too close to the limit to tell) is
    decided by the eigenvalues themselves and solved by LU, as the rule states it."""
    shape = e.shape[:-1]
    e = np.ascontiguousarray(e, dtype=float).reshape(-1, 6)
    P = np.ascontiguousarray(P, dtype=float).reshape(-1, 6, 6)
    nees = np.empty(len(e))
    undecided = np.zeros(len(e), dtype=np.bool_)
    _nees_kernel(e, P, nees, undecided)
    if undecided.any():
        (rest,) = np.nonzero(undecided)
        values = np.linalg.eigvalsh(P[rest])
        ok = values[:, 0] > 6 * np.finfo(float).eps * values[:, -1]
        nees[rest] = np.inf
        good = rest[ok]
        solved = np.linalg.solve(P[good], e[good, :, np.newaxis])[:, :, 0]
        nees[good] = np.einsum("ki,ki->k", e[good], solved)
    return nees.reshape(shape)


@njit(cache=True)
def _nees_kernel(e: np.ndarray, P: np.ndarray, nees: np.ndarray, undecided: np.ndarray) -> None:
    eps = 2.220446049250313e-16
    L = np.empty((6, 6))
    L_inv = np.empty((6, 6))
    d_inv = np.empty(6)
    for n in range(P.shape[0]):
        finite = True
        for i in range(6):
            for j in range(6):
                if not math.isfinite(P[n, i, j]):
                    finite = False
        if not finite:
            nees[n] = np.inf
            continue
        if not cholesky6(P[n], L, d_inv):
            undecided[n] = True
            continue
        lower_inverse6(L, d_inv, L_inv)
        trace_inverse = 0.0
        trace = 0.0
        for j in range(6):
            trace += P[n, j, j]
        value = 0.0
        for i in range(6):
            y = 0.0
            for j in range(i + 1):
                trace_inverse += L_inv[i, j] * L_inv[i, j]
                y += L_inv[i, j] * e[n, j]
            value += y * y
        if not 1.0 / trace_inverse > 12.0 * eps * trace:
            undecided[n] = True
            continue
        nees[n] = value


def rms_norm(values: np.ndarray) -> float:
    """``√(mean over rows of |row|²)``."""
    return float(_rms_runs(np.asarray(values, dtype=float)[np.newaxis])[0])


def _rms_runs(values: np.ndarray) -> np.ndarray:
    """:func:`rms_norm` of each run (B×n×d → B), along its own rows."""
    return np.sqrt(np.mean(np.sum(values * values, axis=-1), axis=-1))


#: Runs whose metrics are computed at once: the batch goes by chunks of runs, each chunk's
#: arrays (6×6 per step and run, several of them) a few tens of MB at most.
METRICS_CHUNK = 64


def batch_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """The metrics of :func:`run_metrics` for each run of a batch log, each a (B,) array.

    ``log``: each signal ``B×N×shape`` (run i in row i), ``k`` and ``time`` (N) shared
    (:data:`SHARED_KEYS`). It reads the signals of :func:`metric_signals`: ``p_WU``,
    ``v_WU``, ``p_WT``, ``v_WT``, ``x_TU_hat``, ``u1_W``, ``b_W`` (B×N×3), ``R_WB`` (B×N×3×3),
    ``P_TU`` (B×N×6×6), and if logged ``sonar_status`` (B×N×2, VALID or not; all valid when
    absent), a vehicle's ``R_WB_command`` (B×N×3×3), ``w_WB``, ``w_WB_command`` (B×N×3),
    ``saturation_ticks`` (B×N×4), and with the extended bound ``ping_time`` (B×N×2),
    ``p_TS_W`` (B×N×6). Every reduction runs along one run's steps: run i's metrics are the
    same bits as :func:`run_metrics` of run i's own log, whatever B and its place. A run
    with NaN or inf in its log has NaN or inf metrics and leaves the others.

    Vectorised over runs (compiled loops for the bounds' recursions, the extended bound's
    included, the NEES and the excitation's eigenvalues), by chunks of :data:`METRICS_CHUNK`
    runs.
    """
    if np.ndim(log["p_WU"]) != 3 or len(log["p_WU"]) == 0:
        raise ValueError(f"log: p_WU must have shape (B ≥ 1, N, 3), got {np.shape(log['p_WU'])}")
    chunks = [
        _chunk_metrics(
            {
                name: value if name in SHARED_KEYS else value[start : start + METRICS_CHUNK]
                for name, value in log.items()
            },
            scenario,
        )
        for start in range(0, len(log["p_WU"]), METRICS_CHUNK)
    ]
    return {name: np.concatenate([chunk[name] for chunk in chunks]) for name in chunks[0]}


def run_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """Steady-state metrics over k ≥ ``scenario.steady_state_start`` of one run's log
    (:func:`batch_metrics` of a batch of one).

    - ``position_rmse``, ``velocity_rmse``: RMS of |true − filtered| relative position [m] and
      velocity [m/s]; ``tracking_rmse``: RMS of |q − R q*| [m]; ``nees_mean``: mean NEES (≈ 6
      for a consistent filter); ``final_position_error``: |position error| at the last step.
    - ``relative_speed_mean``/``_peak``: mean and largest |ϑ| = |v − v̄|, the true relative
      speed [m/s]; ``acceleration_mean``/``_peak``: mean and largest |R u1|, the commanded
      (after any limit, i.e. applied) world acceleration [m/s²]. These measure what the
      tracking law asks of the vehicle.
    - ``model_acceleration_rmse``: RMS of |(v(k+1) − v(k))/t − R u1(k)| [m/s²], how far the
      vehicle's motion is from the commanded acceleration that the filter takes as known
      (0 for the paper's kinematic vehicle).
    - How the attitude moved and excited the baseline: :func:`attitude_metrics`.
    - For a vehicle that logs its attitude target and thrusts (``!HoveringAuv``):
      :func:`vehicle_metrics`.
    - ``pcrlb_position_rmse``, ``pcrlb_velocity_rmse``: √(mean over the window of the trace
      of the position/velocity block) of the PCRLB along this run's true trajectory, and
      ``kf_riccati_position_rmse``, ``kf_riccati_velocity_rmse`` the same of the paper's KF's
      Riccati covariance (:func:`bound_covariances`): compare with the RMSEs. With
      navigation errors or sonar timing (:func:`bound_errors_on`) the PCRLB is the extended
      bound (:func:`extended_bound`), and ``pcrlb_floor_position_rmse``,
      ``pcrlb_floor_velocity_rmse`` are its floors' part (√ mean of the floors' traces):
      the error the biases leave whatever the ranges' number and noise.
    """
    return {
        name: float(value[0]) for name, value in batch_metrics(batch_log(log), scenario).items()
    }


def _chunk_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    """:func:`batch_metrics` of a few runs at once (a failed run's inf and NaN go quietly)."""
    start = scenario.steady_state_start
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        e = errors(log, scenario)
        speed = np.linalg.norm(e["relative_velocity"][:, start:], axis=-1)
        acceleration = np.linalg.norm(log["u1_W"][:, start:], axis=-1)
        return {
            "position_rmse": _rms_runs(e["position"][:, start:]),
            "velocity_rmse": _rms_runs(e["velocity"][:, start:]),
            "tracking_rmse": _rms_runs(e["tracking"][:, start:]),
            "nees_mean": np.mean(e["nees"][:, start:], axis=-1),
            "final_position_error": np.linalg.norm(e["position"][:, -1], axis=-1),
            "relative_speed_mean": np.mean(speed, axis=-1),
            "relative_speed_peak": np.max(speed, axis=-1),
            "acceleration_mean": np.mean(acceleration, axis=-1),
            "acceleration_peak": np.max(acceleration, axis=-1),
            "model_acceleration_rmse": _model_acceleration_rmse_runs(log, scenario),
            **_attitude_metrics_runs(log, scenario),
            **_vehicle_metrics_runs(log, scenario),
            **_bound_metrics_runs(log, scenario),
        }


def attitude_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """Rotation per step, excitation and reference acceleration over the whole run.

    - ``rotation_mean``, ``rotation_peak`` [rad]: the angle of ``R(k+1) R(k)ᵀ`` over
      k = 0..N−2 (a rotation budget applies from the first step, so no window).
    - ``excitation_min`` [m²]: the smallest eigenvalue of ``Σ q_s q_sᵀ`` over every window
      of ``analysis.pe_window`` steps (paper eq. 10), the minimum over the run.
    - ``reference_acceleration_mean``, ``reference_acceleration_peak`` [m/s²]:
      ``|r(k+1) − 2 r(k) + r(k−1)| / t²`` of the desired relative position ``r = R_WF q*``,
      the acceleration that following it exactly asks of the vehicle.
    """
    batch = _attitude_metrics_runs(batch_log(log), scenario)
    return {name: float(value[0]) for name, value in batch.items()}


def _attitude_metrics_runs(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    R = log["R_WB"]
    runs, steps = R.shape[:2]
    nan = np.full(runs, np.nan)
    # The angle of R(k+1)ᵀ R(k) (the same as of R(k+1) R(k)ᵀ): cos from the trace, sin from
    # the skew part (arccos loses precision near 0).
    relative = np.swapaxes(R[:, 1:], -1, -2) @ R[:, :-1]
    cos = (np.trace(relative, axis1=-2, axis2=-1) - 1.0) / 2.0
    skew = relative - np.swapaxes(relative, -1, -2)
    sin = 0.5 * np.sqrt(0.5 * np.sum(skew * skew, axis=(-2, -1)))
    angles = np.arctan2(sin, cos)
    window = scenario.analysis.pe_window
    if window <= steps:
        excitation = np.empty(runs)
        _excitation_kernel(np.ascontiguousarray(log["b_W"], dtype=float), window, excitation)
    else:
        excitation = nan
    t = scenario.tracking
    reference = desired_relative_positions(R, t.desired_relative_position, t.reference_frame)
    second = reference[:, 2:] - 2.0 * reference[:, 1:-1] + reference[:, :-2]
    acceleration = np.linalg.norm(second, axis=-1) / scenario.time_step**2
    some = steps > 1
    more = steps > 2
    return {
        "rotation_mean": np.mean(angles, axis=-1) if some else nan,
        "rotation_peak": np.max(angles, axis=-1) if some else nan,
        "excitation_min": excitation,
        "reference_acceleration_mean": np.mean(acceleration, axis=-1) if more else nan,
        "reference_acceleration_peak": np.max(acceleration, axis=-1) if more else nan,
    }


def smallest_eigenvalues(S: np.ndarray) -> np.ndarray:
    """The smallest eigenvalue of each symmetric 3×3 matrix of ``S`` (…×3×3 → …), each alone
    (a compiled cyclic Jacobi iteration: accurate to rounding of the matrix's norm)."""
    S = np.ascontiguousarray(S, dtype=float)
    out = np.empty(S.shape[:-2])
    _smallest_eigenvalues_kernel(S.reshape(-1, 3, 3), out.reshape(-1))
    return out


@njit(cache=True)
def _smallest_eigenvalues_kernel(S: np.ndarray, out: np.ndarray) -> None:
    a = np.empty((3, 3))
    for n in range(S.shape[0]):
        a[:, :] = S[n]
        out[n] = _smallest_eigenvalue3(a)


@njit(cache=True)
def _excitation_kernel(q_s: np.ndarray, window: int, out: np.ndarray) -> None:
    """Each run's smallest eigenvalue of ``Σ q_s q_sᵀ`` over every window of ``window``
    steps, the minimum over the run (NaN if any is): window sums as differences of the
    running sums (``C(k + w) − C(k)``, ``C(k + 1) = C(k) + q_s q_sᵀ``)."""
    runs, steps = q_s.shape[0], q_s.shape[1]
    cumulative = np.empty((steps + 1, 3, 3))
    a = np.empty((3, 3))
    for r in range(runs):
        cumulative[0] = 0.0
        for k in range(steps):
            for i in range(3):
                for j in range(3):
                    cumulative[k + 1, i, j] = cumulative[k, i, j] + q_s[r, k, i] * q_s[r, k, j]
        lowest = np.inf
        for k in range(steps - window + 1):
            for i in range(3):
                for j in range(3):
                    a[i, j] = cumulative[k + window, i, j] - cumulative[k, i, j]
            value = _smallest_eigenvalue3(a)
            if not value >= lowest:  # smaller, or NaN (which stays)
                lowest = value
            if lowest != lowest:
                break
        out[r] = lowest


@njit(cache=True)
def _smallest_eigenvalue3(a: np.ndarray) -> float:
    """The smallest eigenvalue of the symmetric 3×3 ``a`` (overwritten) by cyclic Jacobi
    rotations until no off-diagonal entry counts beside its diagonal."""
    for _ in range(60):
        rotated = False
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = a[p, q]
            if not abs(apq) > 1e-18 * (abs(a[p, p]) + abs(a[q, q])):
                continue
            rotated = True
            theta = (a[q, q] - a[p, p]) / (2.0 * apq)
            t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
            if theta < 0.0:
                t = -t
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            tau = s / (1.0 + c)
            a[p, p] -= t * apq
            a[q, q] += t * apq
            a[p, q] = a[q, p] = 0.0
            r = 3 - p - q
            g, h = a[r, p], a[r, q]
            a[r, p] = a[p, r] = g - s * (h + g * tau)
            a[r, q] = a[q, r] = h + s * (g - h * tau)
        if not rotated:
            break
    return min(a[0, 0], min(a[1, 1], a[2, 2]))


def model_acceleration_rmse(log: dict[str, np.ndarray], scenario: Scenario) -> float:
    """RMS over the window of |(v(k+1) − v(k))/t − u1_W(k)| [m/s²] (see :func:`run_metrics`)."""
    return float(_model_acceleration_rmse_runs(batch_log(log), scenario)[0])


def _model_acceleration_rmse_runs(log: dict[str, np.ndarray], scenario: Scenario) -> np.ndarray:
    start = scenario.steady_state_start
    achieved = np.diff(log["v_WU"][:, start:], axis=1) / scenario.time_step
    if achieved.shape[1] == 0:
        return np.zeros(len(achieved))
    return _rms_runs(achieved - log["u1_W"][:, start:-1])


def vehicle_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """What the outer loop's commands cost a vehicle that logs its attitude target
    (``R_WB_command``), achieved rate (``w_WB``) and saturation counts (``saturation_ticks``),
    over the steady-state window; empty for a vehicle that logs none of them.

    - ``attitude_error_mean``/``_peak`` [rad]: |Log(R_cmd R_WBᵀ)| at the outer ticks, the
      attitude reached against the one commanded for that tick.
    - ``angular_rate_mean``/``_peak`` [rad/s]: |ω_WB| reached; ``angular_rate_error_mean``:
      mean |ω_WB − u2| at the ticks.
    - ``thrust_saturated_fraction``: the fraction of the controller's ticks whose wrench the
      thrust allocation scaled down (some thruster at its limit), force or moment.
    """
    batch = _vehicle_metrics_runs(batch_log(log), scenario)
    return {name: float(value[0]) for name, value in batch.items()}


def _vehicle_metrics_runs(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    if "R_WB_command" not in log:
        return {}
    start = scenario.steady_state_start
    R, R_cmd = log["R_WB"][:, start:], log["R_WB_command"][:, start:]
    # The rotation angle of R_cmd Rᵀ from its trace, clipped for rounding.
    cos_angle = 0.5 * (np.einsum("bkij,bkij->bk", R_cmd, R) - 1.0)
    error = np.arccos(np.clip(cos_angle, -1.0, 1.0))
    rate = np.linalg.norm(log["w_WB"][:, start:], axis=-1)
    rate_error = np.linalg.norm(log["w_WB"][:, start:] - log["w_WB_command"][:, start:], axis=-1)
    out = {
        "attitude_error_mean": np.mean(error, axis=-1),
        "attitude_error_peak": np.max(error, axis=-1),
        "angular_rate_mean": np.mean(rate, axis=-1),
        "angular_rate_peak": np.max(rate, axis=-1),
        "angular_rate_error_mean": np.mean(rate_error, axis=-1),
    }
    if "saturation_ticks" in log:
        counts = log["saturation_ticks"][:, -1] - log["saturation_ticks"][:, start]
        out["thrust_saturated_fraction"] = counts[:, 3] / np.maximum(counts[:, 0], 1.0)
    return out


def bound_metrics(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, float]:
    """The steady-state RMSEs of :func:`bound_covariances` (see :func:`run_metrics`):
    ``<name>_position_rmse`` and ``<name>_velocity_rmse`` for each of its covariances."""
    batch = _bound_metrics_runs(batch_log(log), scenario)
    return {name: float(value[0]) for name, value in batch.items()}


def _bound_metrics_runs(log: dict[str, np.ndarray], scenario: Scenario) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    with np.errstate(all="ignore"):
        for name, covs in bound_covariances(log, scenario).items():
            position, velocity = bound_rmse_runs(covs, scenario.steady_state_start)
            out[f"{name}_position_rmse"] = position
            out[f"{name}_velocity_rmse"] = velocity
    return out
