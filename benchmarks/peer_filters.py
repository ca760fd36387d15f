"""A peer on the same data: Stone Soup's UKF and particle filter on logs of ``drake-uuv run``.

Stone Soup (the UK Defence Science and Technology Laboratory's tracking framework, ``pip install
-e '.[peer]'``) filters the ranges, sonar baselines and applied accelerations logged by a
``drake-uuv run`` (``log.npz``), with its own ``UnscentedKalmanPredictor``/``Updater`` and
``ParticlePredictor``/``ParticleUpdater`` (systematic resampling when the effective sample size
falls below half the count, Stone Soup's MCMC move as the regulariser). The models are written
against Stone Soup's interfaces here: the relative constant-velocity transition
``x⁺ = A x + B(a_W − ū)`` with ``Q = B W Bᵀ`` (the known ``B a_W`` added to the prediction)
and the two ranges ``[|q + ½ q_s|, |q − ½ q_s|]`` with ``R = η I``.

Both peers start at step ``--start`` from drake_uuv's own filtered estimate and covariance of
the same log (the scenario's prior is 3 m from the truth; how to start is drake_uuv's
hand-over question, not the peer's), then run alone. Prints, per log, the position RMSE over
k ≥ ``--window`` of drake_uuv's estimate (whichever estimator made the log) and of each peer,
and the RMSE over all logs. ``ranges`` holds the first sample per sonar: use logs with f = 1.

    drake-uuv run --seed 0 --set estimator=Ekf --out out/peer/ekf-0   # … seeds 0..9
    python benchmarks/peer_filters.py out/peer/ekf-*/log.npz --noise-variance 0.01

Both log layouts are read: the current keys (``p_uuv``, ``p_target``, ``q_s``, ``q_hat``,
``P``, ``a_world``) and the renamed ones (``p_WU``, ``p_WT``, ``b_W``, ``x_TU_hat``, ``P_TU``,
``u1_W``).
"""

import argparse
import datetime
import math
import time
from pathlib import Path

import numpy as np
from stonesoup.base import Property
from stonesoup.models.measurement.nonlinear import NonLinearGaussianMeasurement
from stonesoup.models.transition.linear import LinearGaussianTransitionModel
from stonesoup.predictor.kalman import UnscentedKalmanPredictor
from stonesoup.predictor.particle import ParticlePredictor
from stonesoup.regulariser.particle import MCMCRegulariser
from stonesoup.resampler.particle import ESSResampler
from stonesoup.types.array import CovarianceMatrix, StateVector, StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState, ParticleState
from stonesoup.updater.kalman import UnscentedKalmanUpdater
from stonesoup.updater.particle import ParticleUpdater


class RelativeMotion(LinearGaussianTransitionModel):
    """``x⁺ = A x + B(−ū)``, ``ū ~ N(0, W)``: the relative state ``[q, ϑ]`` (q first)."""

    time_step: float = Property(doc="Sampling period t [s]")
    acceleration_covariance: np.ndarray = Property(doc="W, the target's acceleration")

    def _ab(self) -> tuple[np.ndarray, np.ndarray]:
        t = self.time_step
        A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
        return A, np.vstack([0.5 * t * t * np.eye(3), t * np.eye(3)])

    def matrix(self, **kwargs) -> np.ndarray:
        return self._ab()[0]

    def covar(self, **kwargs) -> CovarianceMatrix:
        _, B = self._ab()
        return CovarianceMatrix(B @ np.asarray(self.acceleration_covariance) @ B.T)

    def control_matrix(self) -> np.ndarray:
        return self._ab()[1]


class TwoSonarRanges(NonLinearGaussianMeasurement):
    """The ranges of the two sonars at ``∓½ q_s`` from the vehicle to the target."""

    baseline: np.ndarray = Property(doc="q_s, the world baseline of this step")

    @property
    def ndim_meas(self) -> int:
        return 2

    def function(self, state, noise=False, **kwargs):
        q = np.asarray(state.state_vector, dtype=float)[:3, :]
        half = 0.5 * np.asarray(self.baseline, dtype=float).reshape(3, 1)
        ranges = np.vstack([np.linalg.norm(q + half, axis=0), np.linalg.norm(q - half, axis=0)])
        if noise:
            ranges = ranges + self.rvs(num_samples=ranges.shape[1], **kwargs)
        return StateVector(ranges) if ranges.shape[1] == 1 else StateVectors(ranges)


def _get(log, *names: str) -> np.ndarray:
    for name in names:
        if name in log:
            return np.asarray(log[name], dtype=float)
    raise KeyError(f"log has none of {names}")


def read_log(path: Path) -> dict[str, np.ndarray]:
    """The arrays the peers need, from either log layout."""
    log = np.load(path)
    if "x_TU_hat" in log:
        x_hat = np.asarray(log["x_TU_hat"], dtype=float)
    else:
        x_hat = np.concatenate([_get(log, "q_hat"), _get(log, "v_hat")], axis=1)
    q_true = _get(log, "p_WU", "p_uuv") - _get(log, "p_WT", "p_target")
    return {
        "q_true": q_true,
        "x_hat": x_hat,
        "P": _get(log, "P_TU", "P").reshape(-1, 6, 6),
        "ranges": _get(log, "ranges"),
        "q_s": _get(log, "b_W", "q_s"),
        "a_W": _get(log, "u1_W", "a_world"),
    }


def shifted(state, offset: np.ndarray):
    """``state`` with its mean (or every particle) moved by ``offset`` (the known ``B a_W``)."""
    if isinstance(state, ParticleState):
        state.state_vector = StateVectors(np.asarray(state.state_vector) + offset[:, None])
        return state
    state.state_vector = StateVector(np.asarray(state.state_vector) + offset[:, None])
    return state


def run_peer(kind: str, log: dict, args: argparse.Namespace, seed: int) -> np.ndarray:
    """Filtered positions from step ``args.start`` on (rows ``start..N−1``)."""
    W = np.diag(args.acceleration_covariance)
    motion = RelativeMotion(time_step=args.time_step, acceleration_covariance=W)
    B = motion.control_matrix()
    R = CovarianceMatrix(args.noise_variance * np.eye(2))
    t0 = datetime.datetime(2026, 1, 1)
    k0 = args.start
    x0, P0 = log["x_hat"][k0], log["P"][k0]
    if kind == "ukf":
        predictor = UnscentedKalmanPredictor(motion)
        updater = UnscentedKalmanUpdater(measurement_model=None)
        state = GaussianState(StateVector(x0), CovarianceMatrix(P0), timestamp=t0)
    else:
        rng = np.random.default_rng(seed)
        predictor = ParticlePredictor(motion)
        updater = ParticleUpdater(
            measurement_model=None,
            resampler=ESSResampler(),
            regulariser=MCMCRegulariser(transition_model=motion),
        )
        particles = rng.multivariate_normal(x0, P0, size=args.count).T
        log_w = np.full(args.count, -math.log(args.count))
        state = ParticleState(StateVectors(particles), log_weight=log_w, timestamp=t0)
    out = [np.asarray(state.state_vector if kind == "ukf" else state.mean).ravel()[:3]]
    for k in range(k0 + 1, len(log["ranges"])):
        timestamp = t0 + datetime.timedelta(seconds=(k - k0) * args.time_step)
        prediction = shifted(predictor.predict(state, timestamp=timestamp), B @ log["a_W"][k - 1])
        model = TwoSonarRanges(
            ndim_state=6, mapping=(0, 1, 2), noise_covar=R, baseline=log["q_s"][k]
        )
        detection = Detection(
            StateVector(log["ranges"][k]), timestamp=timestamp, measurement_model=model
        )
        state = updater.update(SingleHypothesis(prediction, detection))
        mean = state.state_vector if kind == "ukf" else state.mean
        out.append(np.asarray(mean, dtype=float).ravel()[:3])
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", nargs="+", type=Path, help="log.npz files of drake-uuv run")
    parser.add_argument("--noise-variance", type=float, default=0.01, help="η [m²]")
    parser.add_argument(
        "--acceleration-covariance", type=float, nargs=3, default=[0.004, 0.001, 0.001]
    )
    parser.add_argument("--time-step", type=float, default=0.5)
    parser.add_argument("--start", type=int, default=50, help="step the peers start from")
    parser.add_argument("--window", type=int, default=200, help="first step of the RMSE")
    parser.add_argument("--count", type=int, default=5000, help="Stone Soup's particle count")
    parser.add_argument("--peers", nargs="+", default=["ukf", "pf"], choices=["ukf", "pf"])
    args = parser.parse_args()
    total = {"drake_uuv": [], **{p: [] for p in args.peers}}
    seconds = {p: 0.0 for p in args.peers}
    print(f"{'log':<40} {'drake_uuv':>9} " + " ".join(f"{p:>9}" for p in args.peers))
    for index, path in enumerate(args.logs):
        log = read_log(path)
        window = slice(args.window, None)
        errors = {"drake_uuv": log["x_hat"][:, :3] - log["q_true"]}
        for peer in args.peers:
            start = time.perf_counter()
            estimate = run_peer(peer, log, args, seed=index)
            seconds[peer] += time.perf_counter() - start
            full = np.full_like(log["q_true"], np.nan)
            full[args.start :] = estimate
            errors[peer] = full - log["q_true"]
        row = []
        for name, e in errors.items():
            mse = float(np.mean(np.sum(e[window] ** 2, axis=1)))
            total[name].append(mse)
            row.append(f"{math.sqrt(mse):9.4f}")
        print(f"{str(path)[-40:]:<40} " + " ".join(row), flush=True)
    print(
        f"{'RMSE over ' + str(len(args.logs)) + ' logs':<40} "
        + " ".join(f"{math.sqrt(np.mean(v)):9.4f}" for v in total.values())
    )
    print(
        "peer seconds per log: "
        + ", ".join(f"{p} {s / len(args.logs):.1f}" for p, s in seconds.items())
    )


if __name__ == "__main__":
    main()
