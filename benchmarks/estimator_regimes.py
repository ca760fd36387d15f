"""Raw-range filters across noise and standoff regimes in a plain numpy closed loop.

The paper's loop (Algorithm 2 attitudes, the paper's tracking law, two sonars, the prior
x̂0 = 0, P0 = I) without Drake, so that hand-over rules, sigma-point parameters and particle
counts can be compared on many seeded runs in seconds. The desired relative position ``q*``
is held in the world frame (``--body-frame``: the paper's body frame). Each estimator but
``kf`` starts as the paper's KF and hands over by :class:`~drake_uuv.models.handover.
HandoverRule` (``--angle``, ``--prior-share``; the particle filter uses no angle test), or
also by the second-order range error against the noise (``--second-order c``). With
``--bridge`` the EKF and UKF carry particles between the prior test and the Gaussian test,
and go back to them when an angle exceeds ``--fallback`` × the tolerance (the rule's
``particle_bridge``, as the Drake filters do by default).

``kf-predicted`` is the paper's KF with the noise variance Γ of ``Y`` from its own prediction
(``E d² = |q̂ ± ½ q_s|² + tr P_qq``) instead of the measured ranges, which give each
measurement a say in its own weight.

Prints, per estimator and rule: position RMSE over k ≥ 200, the mean per-run posterior
Cramér–Rao bound and their ratio, mean NEES, runs that diverged (final error > 10 m), the
median step of the (last) hand-over to the Gaussian filter (−1: some runs never handed over),
how many never did, seconds per run, and the fallbacks to particles over all runs.

    python benchmarks/estimator_regimes.py --sigma 0.5 --body-frame --runs 40
    python benchmarks/estimator_regimes.py --q-star -20 -20 0 --estimators ekf ukf --angle 0.2 0.3
    python benchmarks/estimator_regimes.py --sigma 1 --body-frame --estimators ekf ukf \
        --second-order 1 nan --bridge
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from drake_uuv.models.attitude_plans import trajectory_attitude
from drake_uuv.models.filters import ekf_update, iekf_update, predict, range_difference_update
from drake_uuv.models.handover import HandoverRule, prior_share_predict, prior_share_update
from drake_uuv.models.measurement import range_difference_noise, range_measurement
from drake_uuv.models.motion import double_integrator, process_noise_covariance
from drake_uuv.models.particle_filter import (
    ParticleFilterParameters,
    initial_particles,
    pf_predict,
    pf_update,
    weighted_moments,
)
from drake_uuv.models.pcrlb import bound_rmse, pcrlb_over_runs
from drake_uuv.models.unscented import SigmaPointParameters, ukf_range_update

UPDATES = {"ekf": ekf_update, "iekf": iekf_update, "ukf": ukf_range_update}


@dataclass
class ReferenceScenario:
    """The paper's §IV numbers, as the shipped ``paper`` scenario holds them."""

    time_step: float = 0.5
    steps: int = 500
    W: np.ndarray = field(default_factory=lambda: np.diag([0.004, 0.001, 0.001]))
    eta: np.ndarray = field(default_factory=lambda: np.array([0.01, 0.01]))
    samples_per_step: int = 1
    baseline: np.ndarray = field(default_factory=lambda: np.array([-1.0, 1.0, 0.0]))
    target_position: np.ndarray = field(default_factory=lambda: np.array([1.0, 2.0, 2.0]))
    target_velocity: np.ndarray = field(default_factory=lambda: np.array([0.02, 0.1, 0.1]))
    alpha: float = 1.2
    q_star: np.ndarray = field(default_factory=lambda: np.array([-2.0, -2.0, 0.0]))
    x0_hat: np.ndarray = field(default_factory=lambda: np.zeros(6))
    P0: np.ndarray = field(default_factory=lambda: np.eye(6))
    steady_state_start: int = 200


def algorithm2_attitudes(s: ReferenceScenario) -> np.ndarray:
    """R(0) = I, R(k+1) = Algorithm 2's R̄(k) (the paper's ρ = 1/24, h = ½ cos(kπ/6))."""
    R = [np.eye(3)]
    R += [trajectory_attitude(k, s.baseline, 1 / 24, 0.5, 1 / 6) for k in range(s.steps - 1)]
    return np.stack(R)


def range_difference_measurement(
    z: np.ndarray, variances: np.ndarray, squared_ranges: np.ndarray | None = None
) -> tuple[float, float, float]:
    """The paper's ``(Y, m, Γ)`` from two ranges, the derived moments (d² from mean(z²) − σ²)."""
    squares = z * z if squared_ranges is None else squared_ranges
    m, gamma = range_difference_noise("derived", variances, squares)
    return 0.5 * (z[0] ** 2 - z[1] ** 2), float(m), float(gamma)


@dataclass
class StartedFilter:
    """A linear-KF start handing over to a range update (``ekf``, ``iekf``, ``ukf``, ``pf``)."""

    kind: str
    x: np.ndarray
    P: np.ndarray
    A: np.ndarray
    B: np.ndarray
    W: np.ndarray
    eta: np.ndarray
    f: int
    rule: HandoverRule
    rng: np.random.Generator
    pf: ParticleFilterParameters = field(default_factory=ParticleFilterParameters)
    pf_init: str = "linear"  # linear | prior
    bridge: bool = False  # ekf/ukf: particles between the linear start and the Gaussian
    linear: bool = True
    bridging: bool = False
    fallbacks: int = 0
    steps: int = 0
    handover_step: int = -1
    particles: np.ndarray | None = None
    log_weights: np.ndarray | None = None
    nis: float = math.nan

    def __post_init__(self) -> None:
        self.Q = self.B @ self.W @ self.B.T
        self.R = np.diag(self.eta / self.f)
        self.noise_std = np.sqrt(self.eta / self.f)
        self.S = np.array(self.P, dtype=float)
        if not self.rule.linear_start:
            self.linear = False
            self.handover_step = 0
            if self.kind == "pf":
                self._draw(self.x, self.P)

    def _draw(self, x: np.ndarray, P: np.ndarray) -> None:
        self.particles = initial_particles(x, P, self.pf.count, self.rng)
        self.log_weights = np.full(self.pf.count, -math.log(self.pf.count))

    def update(self, samples: np.ndarray, q_s: np.ndarray, k: int) -> None:
        z = samples.mean(axis=1)
        if self.linear:
            Y, m, G = range_difference_measurement(z, self.eta / self.f)
            self.x, self.P, self.nis = range_difference_update(self.x, self.P, Y, m, G, q_s)
            self.S = prior_share_update(self.S, self.P, q_s, G)
            self.steps += 1
            if self.rule.handover_due(
                self.P,
                self.steps,
                x=self.x,
                q_s=q_s,
                prior_covariance=self.S,
                noise_std=self.noise_std,
            ):
                self.linear = False
                self.handover_step = k
                if self.kind == "pf":
                    self._draw(self.x, self.P)
            elif self.bridge and self.rule.prior_forgotten(self.P, self.steps, self.S):
                self.linear = False
                self.bridging = True
                self._draw(self.x, self.P)
            return
        if self.bridging:
            self.x, self.P, self.nis, self.log_weights = pf_update(
                self.particles, self.log_weights, z, q_s, self.R
            )
            if self.rule.gaussian_holds(self.x, self.P, q_s, self.noise_std):
                self.bridging = False
                self.particles = None
                self.handover_step = k
            return
        if self.kind == "pf":
            self.x, self.P, self.nis, self.log_weights = pf_update(
                self.particles, self.log_weights, z, q_s, self.R
            )
        else:
            x_prior, P_prior = self.x, self.P
            self.x, self.P, self.nis = UPDATES[self.kind](self.x, self.P, z, q_s, self.R)
            if self.bridge and self.rule.fallback_due(self.x, self.P, q_s):
                self.bridging = True
                self.fallbacks += 1
                self._draw(self.x, self.P)
            elif self.bridge and self.rule.lost(self.nis):
                # As the Drake filters: redraw from the widened prior, weighed by these ranges.
                self.bridging = True
                self.fallbacks += 1
                self._draw(x_prior, P_prior * (self.nis / 2.0))
                *_, self.log_weights = pf_update(self.particles, self.log_weights, z, q_s, self.R)

    def predict(self, a_W: np.ndarray) -> None:
        if (self.kind == "pf" or self.bridging) and self.particles is not None:
            self.particles, self.log_weights, _ = pf_predict(
                self.particles, self.log_weights, a_W, self.A, self.B, self.W, self.rng, self.pf
            )
            self.x, self.P = weighted_moments(self.particles, np.exp(self.log_weights))
        else:
            self.x, self.P = predict(self.x, self.P, a_W, self.A, self.B, self.Q)
            if self.linear:
                self.S = prior_share_predict(self.S, self.A)


def run(
    s: ReferenceScenario,
    kind: str,
    seed: int,
    rule: HandoverRule,
    pf: ParticleFilterParameters,
    world_frame: bool,
    attitudes: np.ndarray,
    bridge: bool = False,
) -> dict:
    rng = np.random.default_rng(seed)
    filter_rng = np.random.default_rng([seed, 1])
    N, t, f = s.steps, s.time_step, s.samples_per_step
    A, B = double_integrator(t)
    Q = process_noise_covariance(s.W, t)
    W_sqrt = np.linalg.cholesky(s.W)
    eta_sqrt = np.sqrt(s.eta)
    p, v = np.zeros(3), np.zeros(3)
    pt, vt = s.target_position.astype(float), s.target_velocity.astype(float)
    x_hat, P = s.x0_hat.astype(float), s.P0.astype(float)
    filt = None
    if not kind.startswith("kf"):
        filt = StartedFilter(
            kind, x_hat, P, A, B, s.W, s.eta, f, rule, filter_rng, pf, bridge=bridge
        )
    x_true = np.empty((N, 6))
    est = np.empty((N, 6))
    covs = np.empty((N, 6, 6))
    q_s_all = np.empty((N, 3))
    for k in range(N):
        R = attitudes[k]
        q_s = R @ s.baseline
        x = np.concatenate([p - pt, v - vt])
        d = range_measurement(x, q_s)
        samples = d[:, None] + eta_sqrt[:, None] * rng.standard_normal((2, f))
        if filt is None:
            squared = (samples**2).mean(axis=1)
            if kind == "kf-predicted":  # Γ from the prediction: E z² = |q̂ ± ½q_s|² + tr P_qq + η
                q, half = x_hat[:3], 0.5 * q_s
                spread = np.trace(P[:3, :3])
                squared = np.array([(q + half) @ (q + half), (q - half) @ (q - half)]) + spread
                squared = squared + s.eta
            Y, m, G = range_difference_measurement(samples[:, 0], s.eta, squared_ranges=squared)
            x_hat, P, _ = range_difference_update(x_hat, P, Y, m, G, q_s)
        else:
            filt.update(samples, q_s, k)
            x_hat, P = filt.x, filt.P
        x_true[k], est[k], covs[k], q_s_all[k] = x, x_hat, P, q_s
        q_ref = s.q_star if world_frame else R @ s.q_star
        a_W = -(2.0 * s.alpha / t**2) * (x_hat[:3] - q_ref) - (2.0 / t) * x_hat[3:]
        a_T = W_sqrt @ rng.standard_normal(3)
        p, v = p + t * v + 0.5 * t * t * a_W, v + t * a_W
        pt, vt = pt + t * vt + 0.5 * t * t * a_T, vt + t * a_T
        if filt is None:
            x_hat, P = predict(x_hat, P, a_W, A, B, Q)
        else:
            filt.predict(a_W)
    return {
        "x_true": x_true,
        "x_hat": est,
        "P": covs,
        "q_s": q_s_all,
        "handover": -1 if filt is None else filt.handover_step,
        "fallbacks": 0 if filt is None else filt.fallbacks,
    }


def study(s, kind, runs, rule, pf, world_frame, first_seed=0, bridge=False) -> dict:
    attitudes = algorithm2_attitudes(s)
    t0 = time.perf_counter()
    results = [
        run(s, kind, first_seed + i, rule, pf, world_frame, attitudes, bridge and kind != "pf")
        for i in range(runs)
    ]
    wall = (time.perf_counter() - t0) / runs
    start = s.steady_state_start
    mse, nees, final, handovers = [], [], [], []
    for r in results:
        e = r["x_hat"] - r["x_true"]
        mse.append(np.mean(np.sum(e[start:, :3] ** 2, axis=1)))
        with np.errstate(all="ignore"):
            try:
                ne = np.einsum(
                    "ki,ki->k",
                    e[start:],
                    np.linalg.solve(r["P"][start:], e[start:, :, None])[:, :, 0],
                )
            except np.linalg.LinAlgError:
                ne = np.array([np.inf])
        nees.append(np.mean(ne))
        final.append(np.linalg.norm(e[-1, :3]))
        handovers.append(r["handover"])
    bound = pcrlb_over_runs(
        np.stack([r["x_true"][:, :3] for r in results]),
        np.stack([r["q_s"] for r in results]),
        s.P0,
        s.W,
        s.eta,
        s.samples_per_step,
        s.time_step,
    ).per_run_mean
    b_pos, _ = bound_rmse(bound, start)
    mse = np.array(mse)
    ok = np.isfinite(mse)
    rmse = float(np.sqrt(np.mean(mse[ok]))) if ok.any() else math.nan
    final = np.array(final)
    return {
        "rmse": rmse,
        "bound": b_pos,
        "ratio": rmse / b_pos,
        "nees": float(np.mean(np.array(nees)[ok])),
        "diverged": int(np.sum(~(final <= 10.0))),
        "handover": float(np.median(handovers)),
        "never": int(np.sum(np.array(handovers) < 0)) if not kind.startswith("kf") else 0,
        "wall": wall,
        "fallbacks": int(sum(r["fallbacks"] for r in results)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--sigma", type=float, default=0.1)
    parser.add_argument("--q-star", type=float, nargs=3, default=[-2.0, -2.0, 0.0])
    parser.add_argument("--body-frame", action="store_true")
    parser.add_argument("--estimators", nargs="+", default=["kf", "ekf", "ukf", "pf"])
    parser.add_argument(
        "--second-order",
        type=float,
        nargs="+",
        default=[math.nan],
        help="also require tr(P⊥)/(2d) <= c sigma/sqrt(f) (nan: not tested)",
    )
    parser.add_argument("--prior-share", type=float, nargs="+", default=[0.1])
    parser.add_argument("--angle", type=float, nargs="+", default=[0.25], help="nan: none")
    parser.add_argument("--min-linear-steps", type=int, default=1)
    parser.add_argument("--no-linear-start", action="store_true")
    parser.add_argument(
        "--bridge",
        action="store_true",
        help="ekf/ukf: particles from the prior-share test until the full rule holds",
    )
    parser.add_argument(
        "--fallback",
        type=float,
        default=1.2,
        help="with --bridge: back to particles when an angle exceeds this x the tolerance",
    )
    parser.add_argument("--count", type=int, default=5000)
    parser.add_argument("--bandwidth-scale", type=float, default=1.0)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument(
        "--ukf",
        type=float,
        nargs=3,
        default=[1.0, 2.0, math.nan],
        metavar=("ALPHA", "BETA", "KAPPA"),
        help="kappa nan: 3 - n",
    )
    args = parser.parse_args()
    alpha, beta, kappa = args.ukf
    sigma = SigmaPointParameters(alpha, beta, None if math.isnan(kappa) else kappa)
    UPDATES["ukf"] = lambda *a: ukf_range_update(*a, parameters=sigma)
    s = ReferenceScenario(steps=args.steps)
    s = replace(s, eta=np.full(2, args.sigma**2), q_star=np.array(args.q_star))
    pf = ParticleFilterParameters(count=args.count, bandwidth_scale=args.bandwidth_scale)
    print(
        f"sigma {args.sigma} m, q* {args.q_star} ({'body' if args.body_frame else 'world'}), "
        f"{args.runs} runs; count {args.count}, bandwidth scale {args.bandwidth_scale}"
    )
    print(
        f"{'est':<5} {'2nd':>5} {'share':>5} {'angle':>5} {'RMSE':>7} {'bound':>7} {'ratio':>6} "
        f"{'NEES':>7} {'div':>3} {'handover':>8} {'never':>5} {'s/run':>6} {'back':>4}"
    )
    for kind in args.estimators:
        angles = [math.nan] if kind == "pf" else args.angle
        combos = [(t, e, a) for t in args.second_order for e in args.prior_share for a in angles]
        if kind.startswith("kf"):  # no hand-over to vary
            combos = [(math.nan, math.nan, math.nan)]
        for tol, share, angle in combos:
            rule = (
                None
                if kind.startswith("kf")
                else HandoverRule(
                    angle_tolerance=None if math.isnan(angle) else angle,
                    prior_share=share,
                    min_linear_steps=args.min_linear_steps,
                    max_linear_steps=0 if args.no_linear_start else None,
                    second_order_tolerance=None if math.isnan(tol) else tol,
                    particle_bridge=args.bridge and kind != "pf",
                    fallback_factor=args.fallback,
                )
            )
            r = study(s, kind, args.runs, rule, pf, not args.body_frame, bridge=args.bridge)
            print(
                f"{kind:<5} {tol:5.2f} {share:5.2f} {angle:5.2f} {r['rmse']:7.3f} "
                f"{r['bound']:7.3f} {r['ratio']:6.2f} {r['nees']:7.2f} {r['diverged']:3d} "
                f"{r['handover']:8.0f} {r['never']:5d} {r['wall']:6.3f} {r['fallbacks']:4d}",
                flush=True,
            )


if __name__ == "__main__":
    main()
