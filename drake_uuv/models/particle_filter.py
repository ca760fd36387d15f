"""Regularised particle filter on the raw ranges, as vectorised numpy.

The reference that needs no linearisation and no Gaussian posterior: with many particles its
estimate is the empirical optimum (the posterior mean), which shows where the posterior
Cramér–Rao bound is not attainable. The model is the package's: relative state
``x = [q, ϑ]``, ``x(k+1) = A x(k) + B (a_W(k) − ū(k))``, ``ū ~ N(0, W)``; measurement the
per-sonar sample means ``z`` of the ranges ``h(x) = [|q + ½ q_s|, |q − ½ q_s|]`` with
covariance ``R = diag(η1/f, η2/f)``.

One step, split as a Drake estimator splits it
----------------------------------------------
* :func:`pf_update` (deterministic, the filtered output of step k): weights
  ``wᵢ ∝ wᵢ⁻ N(z; h(xᵢ), R)`` of the predicted particles, the weighted mean and covariance as
  ``x(k|k)``, ``P(k|k)``, and the NIS of ``z`` against the particles' predicted-measurement
  mean and covariance (plus ``R``), for the gate and the consistency checks.
* :func:`pf_predict` (random, the discrete update of step k): if the effective sample size
  ``1/Σwᵢ²`` is below ``resample_threshold · N``, systematic resampling (Kitagawa 1996) with
  one uniform offset, then the regularisation below; then each particle moves by the model
  with its own draw of ``ū``. Randomness comes only from the ``numpy.random.Generator``
  the caller passes (a LeafSystem seeds it from a random input port), so a run is
  reproducible from the diagram's seed.

Regularisation
--------------
After resampling, copies of one particle differ only by the target's acceleration noise,
which is rank 3 (``Q = B W Bᵀ``). Each resampled particle is moved by the shrinkage kernel of
Liu & West (2001): ``xᵢ ← a xᵢ + (1 − a) x̄ + h L εᵢ`` with ``a = √(1 − h²)``, ``x̄``, ``L L ᵀ``
the weighted mean and covariance before resampling and ``εᵢ ~ N(0, I)``. Unlike the plain
Gaussian kernel of the regularised PF (Musso, Oudjane & Le Gland 2001), which adds ``h² P``
to the cloud at every resampling and so acts as extra process noise, the shrinkage keeps the
cloud's mean and covariance. ``h`` is ``bandwidth_scale`` times the Gaussian kernel's optimal
bandwidth ``(4 / ((n + 2) N))^{1/(n+4)}`` (Musso et al., n = 6), or none when the scale is 0.

Initialisation
--------------
:func:`initial_particles` draws ``N(x̂, P)``. The scenario's prior ``N(0, I)`` is far from the
truth (``|q| ≈ 3 m``: the truth sits in the prior's 3 % tail and very few particles land on
the two-range circle), so the Drake estimator draws the particles from the paper's linear
KF's Gaussian once a hand-over rule says the KF has converged
(:mod:`drake_uuv.models.handover`): the KF on ``Y = ½(d1² − d2²)`` is exact in its second
moments whatever its prior. The measurements behind this choice are in the estimator's
page ``docs/handover.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.measurement import batch_ranges

STATE_SIZE = 6


@dataclass(frozen=True)
class ParticleFilterParameters:
    """Particle count, when to resample, and the regularisation kernel's bandwidth scale."""

    count: int = 5000
    # Resample when the effective sample size falls below this fraction of the count.
    resample_threshold: float = 0.5
    # h = bandwidth_scale × the Gaussian kernel's optimal bandwidth; 0: no regularisation.
    bandwidth_scale: float = 1.0

    def __post_init__(self) -> None:
        if isinstance(self.count, bool) or not isinstance(self.count, int | np.integer):
            raise ValueError(f"count: must be an integer, got {self.count!r}")
        if not 10 <= self.count <= 10_000_000:
            raise ValueError(f"count: must be in [10, 1e7], got {self.count!r}")
        if not 0.0 <= self.resample_threshold <= 1.0:
            raise ValueError(
                f"resample_threshold: must be in [0, 1], got {self.resample_threshold!r}"
            )
        if not (math.isfinite(self.bandwidth_scale) and 0.0 <= self.bandwidth_scale):
            raise ValueError(f"bandwidth_scale: must be ≥ 0, got {self.bandwidth_scale!r}")

    @property
    def bandwidth(self) -> float:
        """``h``: the scale times ``(4 / ((n + 2) N))^{1/(n+4)}`` with n = 6 (capped below 1)."""
        n = STATE_SIZE
        optimal = (4.0 / ((n + 2) * self.count)) ** (1.0 / (n + 4))
        return min(self.bandwidth_scale * optimal, 0.99)


def initial_particles(
    x: np.ndarray, P: np.ndarray, count: int, rng: np.random.Generator
) -> np.ndarray:
    """``count`` draws of ``N(x, P)``, as the columns of a (6, count) array, equally weighted."""
    x = np.asarray(x, dtype=float).reshape(STATE_SIZE, 1)
    L = np.linalg.cholesky(np.asarray(P, dtype=float))
    return x + L @ rng.standard_normal((STATE_SIZE, count))


def defensive_draw(
    x: np.ndarray, P: np.ndarray, count: int, rng: np.random.Generator, widening: float
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` draws of ``N(x, κ P)`` (κ = ``widening`` ≥ 1) weighted by ``N(x, P) / N(x, κ P)``:
    a sample of the same ``N(x, P)`` whose tails are populated, so that ranges that fall in
    the tail of ``N(x, P)`` still find particles to weigh. Returns the particles and their
    normalised log weights."""
    x = np.asarray(x, dtype=float).reshape(STATE_SIZE, 1)
    normal = rng.standard_normal((STATE_SIZE, count))
    L = np.linalg.cholesky(np.asarray(P, dtype=float))
    particles = x + math.sqrt(widening) * (L @ normal)
    # The Mahalanobis distance under P is κ |normal|²; under κP it is |normal|².
    log_weights = -0.5 * (widening - 1.0) * np.einsum("ij,ij->j", normal, normal)
    return particles, log_weights - _log_sum_exp(log_weights)


def effective_sample_size(weights: np.ndarray) -> float:
    """``1 / Σ wᵢ²`` of normalised weights: N for equal weights, 1 for one particle."""
    return float(1.0 / np.dot(weights, weights))


def particle_ranges(particles: np.ndarray, q_s: np.ndarray) -> np.ndarray:
    """``[|q + ½ q_s|, |q − ½ q_s|]`` of every particle (columns of ``particles``; shape (2, N))."""
    return batch_ranges(particles[:3], q_s)


def weighted_moments(particles: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean and covariance ``Σ wᵢ (xᵢ − x̄)(xᵢ − x̄)ᵀ`` of the columns.

    ``weights`` must be normalised (sum 1).
    """
    mean = particles @ weights
    centred = particles - mean[:, None]
    cov = (centred * weights) @ centred.T
    return mean, 0.5 * (cov + cov.T)


def reweight(
    particles: np.ndarray,
    log_weights: np.ndarray,
    z: np.ndarray,
    variances: np.ndarray,
    predicted: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Bayes' rule on the particles for ``z = h(x) + v``, ``v ~ N(0, diag(variances))`` (or
    ``N(0, variances)`` when ``variances`` is a covariance matrix).

    ``predicted`` (p×N) holds ``h`` of every particle (column). Returns the posterior's
    weighted mean and covariance, the NIS ``νᵀ S⁻¹ ν`` with ``ν = z − Σ wᵢ⁻ h(xᵢ)`` and ``S``
    the prior-weighted covariance of ``h`` plus the noise (χ² with p degrees of freedom when
    the prediction is right), and the normalised posterior log weights.
    """
    z = np.asarray(z, dtype=float).reshape(-1)
    noise = np.asarray(variances, dtype=float)
    z_hat, S = weighted_moments(predicted, normalised(log_weights))
    S = S + (noise if noise.ndim == 2 else np.diag(noise.reshape(-1)))
    nu = z - z_hat
    nis = float(nu @ np.linalg.solve(S, nu))
    residual = predicted - z[:, None]
    if noise.ndim == 2:  # a full covariance: −½ rᵀ R⁻¹ r through its Cholesky factor
        whitened = np.linalg.solve(np.linalg.cholesky(noise), residual)
        log_posterior = log_weights - 0.5 * np.einsum("ij,ij->j", whitened, whitened)
    else:
        variances = noise.reshape(-1)
        log_posterior = log_weights - (0.5 / variances) @ (residual * residual)
    log_posterior -= _log_sum_exp(log_posterior)
    x, P = weighted_moments(particles, np.exp(log_posterior))
    return x, P, nis, log_posterior


def pf_update(
    particles: np.ndarray,
    log_weights: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    sonars: tuple[int, ...] | np.ndarray = (0, 1),
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The raw-range measurement update: ``(x, P, nis, log_weights)``, deterministic.

    ``particles`` (6×N, one column per particle) and ``log_weights`` (N, normalised or not)
    are the prediction ``p(x(k) | z(0..k−1))``; ``z`` the per-sonar sample means,
    ``R`` their covariance (``diag(η/f)``, plus an error model's), ``sonars`` the ranges used
    (the other entry of ``z`` may then be NaN).
    See :func:`reweight` for the returned values (NIS χ² with ``len(sonars)`` degrees of
    freedom when consistent).
    """
    rows = np.asarray(sonars, dtype=int).reshape(-1)
    if rows.size == 0 or not set(rows.tolist()) <= {0, 1}:
        raise ValueError(f"sonars: must be a non-empty subset of (0, 1), got {sonars!r}")
    z = np.asarray(z, dtype=float).reshape(2)[rows]
    R = np.asarray(R, dtype=float)[np.ix_(rows, rows)]
    # Independent ranges (the sonars' own noise): the diagonal's cheaper likelihood.
    noise = np.diag(R) if np.count_nonzero(R - np.diag(np.diag(R))) == 0 else R
    return reweight(particles, log_weights, z, noise, particle_ranges(particles, q_s)[rows])


def systematic_resample(weights: np.ndarray, u: float) -> np.ndarray:
    """Indices of systematic resampling with offset ``u ∈ [0, 1)`` (Kitagawa 1996).

    The N positions ``(i + u)/N`` are laid against the weights' CDF; particle j is copied once
    per position in ``[cdf_{j−1}, cdf_j)``, i.e. ``⌈N cdf_j − u⌉ − ⌈N cdf_{j−1} − u⌉`` times.
    """
    n = weights.size
    edges = np.ceil(np.cumsum(weights) * n - u)
    edges[-1] = n  # rounding must not lose or add a copy
    counts = np.diff(np.clip(edges, 0, n), prepend=0.0).astype(np.int64)
    return np.repeat(np.arange(n), counts)


def shrinkage_kernel(
    particles: np.ndarray, mean: np.ndarray, cov: np.ndarray, h: float, rng: np.random.Generator
) -> np.ndarray:
    """Liu & West's move ``a xᵢ + (1 − a) x̄ + h L εᵢ``, ``a = √(1 − h²)``, ``L Lᵀ = cov``.

    For an equally weighted cloud with mean ``x̄`` and covariance ``cov`` the result has, in
    expectation, the same mean and covariance (``a² cov + h² cov``). Returns a new array.
    """
    a = math.sqrt(1.0 - h * h)
    moved = a * particles
    moved += ((1.0 - a) * np.asarray(mean, dtype=float))[:, None]
    moved += (h * _cholesky_psd(cov)) @ rng.standard_normal(particles.shape)
    return moved


def pf_predict(
    particles: np.ndarray,
    log_weights: np.ndarray,
    a_W: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
    W: np.ndarray,
    rng: np.random.Generator,
    parameters: ParticleFilterParameters,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Resample if degenerate, regularise, and move the particles to ``k+1``.

    ``log_weights`` are the normalised posterior log weights of step k (from
    :func:`pf_update`); ``a_W`` the applied world acceleration; ``W`` the target's
    acceleration covariance. Returns the predicted particles (6×N), their log weights and
    whether the step resampled.
    """
    n = particles.shape[1]
    particles, log_weights, chosen = resample_regularised(particles, log_weights, rng, parameters)
    # x⁺ = A x + B (a_W − ū): the known acceleration once, the target's per particle.
    noise = np.linalg.cholesky(np.asarray(W, dtype=float)) @ rng.standard_normal((3, n))
    moved = A @ particles
    moved += (B @ np.asarray(a_W, dtype=float).reshape(3))[:, None]
    moved -= B @ noise
    return moved, log_weights, chosen is not None


def resample_regularised(
    particles: np.ndarray,
    log_weights: np.ndarray,
    rng: np.random.Generator,
    parameters: ParticleFilterParameters,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """When the effective sample size is below the threshold: systematic resampling, then the
    shrinkage kernel (equal weights after). Returns the particles, their log weights and the
    chosen ancestors' indices (None when it did not resample), so a particle's own data (its
    path's accelerations) can follow it."""
    weights = np.exp(log_weights)
    n = particles.shape[1]
    if not effective_sample_size(weights) < parameters.resample_threshold * n:
        return particles, log_weights, None
    h = parameters.bandwidth
    if h > 0.0:
        mean, cov = weighted_moments(particles, weights)
    chosen = systematic_resample(weights, float(rng.random()))
    particles = particles[:, chosen]
    log_weights = np.full(n, -math.log(n))
    if h > 0.0:
        particles = shrinkage_kernel(particles, mean, cov, h, rng)
    return particles, log_weights, chosen


def normalised(log_weights: np.ndarray) -> np.ndarray:
    """The weights of log weights, normalised to sum 1."""
    w = np.exp(log_weights - log_weights.max())
    return w / w.sum()


def _log_sum_exp(values: np.ndarray) -> float:
    top = float(values.max())
    return top + math.log(float(np.sum(np.exp(values - top))))


def _cholesky_psd(cov: np.ndarray) -> np.ndarray:
    """A factor ``L Lᵀ = cov`` that tolerates a singular cloud (eigenvalues clipped at 0)."""
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(cov)
        return vectors * np.sqrt(np.clip(values, 0.0, None))


class ParticleFilter:
    """Stateful particle filter, pure numpy (tests and the numpy studies; the LeafSystem keeps
    the particles and log weights as discrete state instead).

    Call :meth:`update` with the step's per-sonar means and baseline, read ``x``/``P``/``nis``,
    then :meth:`predict` with the applied world acceleration.
    """

    def __init__(
        self,
        particles: np.ndarray,
        A: np.ndarray,
        B: np.ndarray,
        W: np.ndarray,
        R: np.ndarray,
        rng: np.random.Generator,
        parameters: ParticleFilterParameters | None = None,
    ) -> None:
        self.particles = np.array(particles, dtype=float)
        n = self.particles.shape[1]
        self.log_weights = np.full(n, -math.log(n))
        self.A, self.B, self.W, self.R = A, B, np.asarray(W, float), np.asarray(R, float)
        self.rng = rng
        self.parameters = parameters or ParticleFilterParameters(count=n)
        self.x, self.P = weighted_moments(self.particles, np.exp(self.log_weights))
        self.nis = math.nan

    def update(self, z: np.ndarray, q_s: np.ndarray, sonars=(0, 1)) -> None:
        self.x, self.P, self.nis, self.log_weights = pf_update(
            self.particles, self.log_weights, z, q_s, self.R, sonars
        )

    def predict(self, a_W: np.ndarray) -> None:
        self.particles, self.log_weights, _ = pf_predict(
            self.particles, self.log_weights, a_W, self.A, self.B, self.W, self.rng, self.parameters
        )
        self.x, self.P = weighted_moments(self.particles, np.exp(self.log_weights))
