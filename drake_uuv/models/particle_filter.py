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

``kernel: range_bearing`` applies the same move in range–bearing coordinates about the cloud's
mean direction (:mod:`drake_uuv.models.range_bearing`).

Initialisation
--------------
:func:`initial_particles` draws ``N(x̂, P)``. The scenario's prior ``N(0, I)`` is far from the
truth (``|q| ≈ 3 m``: the truth sits in the prior's 3 % tail and very few particles land on
the two-range circle), so the Drake estimator draws the particles from the paper's linear
KF's Gaussian once a hand-over rule says the KF has converged
(:mod:`drake_uuv.models.handover`): the KF on ``Y = ½(d1² − d2²)`` is exact in its second
moments whatever its prior. The measurements behind this choice are in the estimator's
page ``docs/handover.md``.

Work arrays
-----------
Every step takes an optional :class:`~drake_uuv.models.particle_workspace.Workspace` for its
temporaries (:mod:`drake_uuv.models.particle_workspace`), with the same bits as without.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drake_uuv.models.measurement import batch_ranges
from drake_uuv.models.particle_workspace import STATE_SIZE, Workspace, work_rows
from drake_uuv.models.range_bearing import from_range_bearing, range_bearing_frame, to_range_bearing

#: The regularisation kernel's coordinates (see the module's text).
KERNELS = ("cartesian", "range_bearing")


@dataclass(frozen=True)
class ParticleFilterParameters:
    """Particle count, when to resample, and the regularisation kernel's bandwidth scale."""

    count: int = 5000
    # Resample when the effective sample size falls below this fraction of the count.
    resample_threshold: float = 0.5
    # h = bandwidth_scale × the Gaussian kernel's optimal bandwidth; 0: no regularisation.
    bandwidth_scale: float = 1.0
    # The coordinates the kernel moves particles in: one of KERNELS.
    kernel: str = "cartesian"

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
        if self.kernel not in KERNELS:
            raise ValueError(f"kernel: must be one of {', '.join(KERNELS)}, got {self.kernel!r}")

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


def particle_ranges(
    particles: np.ndarray, q_s: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """``[|q + ½ q_s|, |q − ½ q_s|]`` of every particle (columns of ``particles``; shape (2, N),
    in ``out`` when given)."""
    return batch_ranges(particles[:3], q_s, out)


def weighted_moments(
    particles: np.ndarray, weights: np.ndarray, work: Workspace | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean and covariance ``Σ wᵢ (xᵢ − x̄)(xᵢ − x̄)ᵀ`` of the columns.

    ``weights`` must be normalised (sum 1). With ``work``, its arrays 0 and 1 hold the
    centred and the weighted columns (``particles`` must not be one of them).
    """
    rows, count = particles.shape
    mean = particles @ weights
    centred = np.subtract(particles, mean[:, None], out=work_rows(work, 0, rows, count))
    weighted = np.multiply(centred, weights, out=work_rows(work, 1, rows, count))
    cov = weighted @ centred.T
    return mean, 0.5 * (cov + cov.T)


def weigh(
    log_weights: np.ndarray,
    z: np.ndarray,
    variances: np.ndarray,
    predicted: np.ndarray,
    work: Workspace | None = None,
    weights: np.ndarray | None = None,
) -> tuple[float, np.ndarray]:
    """:func:`reweight`'s NIS and normalised posterior log weights, without the posterior's
    moments (for a step that only carries the weights on). ``weights``:
    ``normalised(log_weights)``, when the caller has them."""
    z = np.asarray(z, dtype=float).reshape(-1)
    noise = np.asarray(variances, dtype=float)
    prior = normalised(log_weights) if weights is None else weights
    z_hat, S = weighted_moments(predicted, prior, work)
    S = S + (noise if noise.ndim == 2 else np.diag(noise.reshape(-1)))
    nu = z - z_hat
    nis = float(nu @ np.linalg.solve(S, nu))
    rows, count = predicted.shape
    residual = np.subtract(predicted, z[:, None], out=work_rows(work, 0, rows, count))
    if noise.ndim == 2:  # a full covariance: −½ rᵀ R⁻¹ r through its Cholesky factor
        whitened = np.linalg.solve(np.linalg.cholesky(noise), residual)
        log_posterior = log_weights - 0.5 * np.einsum("ij,ij->j", whitened, whitened)
    else:
        squared = np.multiply(residual, residual, out=residual)
        log_posterior = log_weights - (0.5 / noise.reshape(-1)) @ squared
    log_posterior -= _log_sum_exp(log_posterior)
    return nis, tempered(log_weights, log_posterior)


#: The fewest particles' worth a measurement update may leave with weight: below it the update
#: tempers the likelihood (:func:`tempered`).
TEMPERING_FLOOR = 20.0


def _log_effective_size(log_weights: np.ndarray) -> float:
    return effective_sample_size(normalised(log_weights))


def tempered(log_weights: np.ndarray, log_posterior: np.ndarray) -> np.ndarray:
    """The posterior log weights (normalised) of Bayes' rule ``log_posterior``, or, where it
    keeps fewer than :data:`TEMPERING_FLOOR` particles' worth and the prior ``log_weights``
    keeps at least that many, the prior times the likelihood to the largest power ``λ < 1``
    that keeps that many (bisection, 40 halvings). A cloud drawn from a loose Gaussian and
    weighed by precise ranges keeps its spread instead of a handful of particles; the ranges'
    information it does not take now, the next ticks' ranges carry (one stage of Oudjane &
    Musso's progressive correction, "Progressive correction for regularized particle
    filters", FUSION 2000). Particles of zero prior weight keep none."""
    if _log_effective_size(log_weights) < TEMPERING_FLOOR or not (
        _log_effective_size(log_posterior) < TEMPERING_FLOOR
    ):
        return log_posterior
    alive = log_weights > -np.inf
    likelihood = np.where(alive, log_posterior - np.where(alive, log_weights, 0.0), 0.0)

    def powered(power: float) -> np.ndarray:
        return np.where(alive, log_weights + power * likelihood, -np.inf)

    low, high = 0.0, 1.0
    for _ in range(40):
        middle = 0.5 * (low + high)
        if _log_effective_size(powered(middle)) >= TEMPERING_FLOOR:
            low = middle
        else:
            high = middle
    out = powered(low)
    return out - _log_sum_exp(out)


def reweight(
    particles: np.ndarray,
    log_weights: np.ndarray,
    z: np.ndarray,
    variances: np.ndarray,
    predicted: np.ndarray,
    work: Workspace | None = None,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Bayes' rule on the particles for ``z = h(x) + v``, ``v ~ N(0, diag(variances))`` (or
    ``N(0, variances)`` when ``variances`` is a covariance matrix).

    ``predicted`` (p×N) holds ``h`` of every particle (column). Returns the posterior's
    weighted mean and covariance, the NIS ``νᵀ S⁻¹ ν`` with ``ν = z − Σ wᵢ⁻ h(xᵢ)`` and ``S``
    the prior-weighted covariance of ``h`` plus the noise (χ² with p degrees of freedom when
    the prediction is right), and the normalised posterior log weights.
    """
    nis, log_posterior = weigh(log_weights, z, variances, predicted, work)
    x, P = weighted_moments(particles, np.exp(log_posterior), work)
    return x, P, nis, log_posterior


def range_terms(
    particles: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    sonars: tuple[int, ...] | np.ndarray,
    work: Workspace | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(z, noise, h)`` of the sonars used: their means, their noise (the variances when
    the covariance is diagonal) and every particle's predicted ranges; :func:`weigh` of them
    is :func:`pf_update` without the posterior's moments."""
    rows = np.asarray(sonars, dtype=int).reshape(-1).tolist()
    if not rows or not set(rows) <= {0, 1}:
        raise ValueError(f"sonars: must be a non-empty subset of (0, 1), got {sonars!r}")
    both = rows == [0, 1]
    z = np.asarray(z, dtype=float).reshape(2)[rows]
    R = np.asarray(R, dtype=float)
    R = R if both else R[np.ix_(rows, rows)]
    # Independent ranges (the sonars' own noise): the diagonal's cheaper likelihood.
    independent = R.shape == (1, 1) or (R[0, 1] == 0.0 and R[1, 0] == 0.0)
    noise = np.diag(R) if independent else R
    # Work array 3: weigh uses 0 and 1, and the particles may be in 2 (a window's step).
    predicted = particle_ranges(particles, q_s, work_rows(work, 3, 2, particles.shape[1]))
    return z, noise, predicted if both else predicted[rows]


def pf_update(
    particles: np.ndarray,
    log_weights: np.ndarray,
    z: np.ndarray,
    q_s: np.ndarray,
    R: np.ndarray,
    sonars: tuple[int, ...] | np.ndarray = (0, 1),
    work: Workspace | None = None,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The raw-range measurement update: ``(x, P, nis, log_weights)``, deterministic.

    ``particles`` (6×N, one column per particle) and ``log_weights`` (N, normalised or not)
    are the prediction ``p(x(k) | z(0..k−1))``; ``z`` the per-sonar sample means,
    ``R`` their covariance (``diag(η/f)``, plus an error model's), ``sonars`` the ranges used
    (the other entry of ``z`` may then be NaN).
    See :func:`reweight` for the returned values (NIS χ² with ``len(sonars)`` degrees of
    freedom when consistent).
    """
    terms = range_terms(particles, z, q_s, R, sonars, work)
    return reweight(particles, log_weights, *terms, work)


def systematic_resample(weights: np.ndarray, u: float) -> np.ndarray:
    """Indices of systematic resampling with offset ``u ∈ [0, 1)`` (Kitagawa 1996).

    The N positions ``(i + u)/N`` are laid against the weights' CDF; particle j is copied once
    per position in ``[cdf_{j−1}, cdf_j)``, i.e. ``⌈N cdf_j − u⌉ − ⌈N cdf_{j−1} − u⌉`` times.
    """
    n = weights.size
    edges = np.cumsum(weights)
    edges *= n
    edges -= u
    np.ceil(edges, out=edges)
    edges[-1] = n  # rounding must not lose or add a copy
    np.clip(edges, 0, n, out=edges)
    counts = np.empty(n, dtype=np.int64)  # the differences of whole numbers: exact
    counts[0] = edges[0]
    np.subtract(edges[1:], edges[:-1], out=counts[1:], casting="unsafe")
    return np.repeat(np.arange(n), counts)


def shrinkage_kernel(
    particles: np.ndarray,
    mean: np.ndarray,
    cov: np.ndarray,
    h: float,
    rng: np.random.Generator,
    work: Workspace | None = None,
) -> np.ndarray:
    """Liu & West's move ``a xᵢ + (1 − a) x̄ + h L εᵢ``, ``a = √(1 − h²)``, ``L Lᵀ = cov``.

    For an equally weighted cloud with mean ``x̄`` and covariance ``cov`` the result has, in
    expectation, the same mean and covariance (``a² cov + h² cov``). Returns a new array, or
    with ``work`` its array 2 (``particles`` may be that array: it then moves in place).
    """
    rows, count = particles.shape
    a = math.sqrt(1.0 - h * h)
    moved = np.multiply(particles, a, out=work_rows(work, 2, rows, count))
    moved += ((1.0 - a) * np.asarray(mean, dtype=float))[:, None]
    draws = rng.standard_normal(out=work_rows(work, 3, rows, count))
    moved += np.matmul(h * _cholesky_psd(cov), draws, out=work_rows(work, 1, rows, count))
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
    *,
    weights: np.ndarray | None = None,
    moments: tuple[np.ndarray, np.ndarray] | None = None,
    work: Workspace | None = None,
    out: np.ndarray | None = None,
    W_factor: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Resample if degenerate, regularise, and move the particles to ``k+1``.

    ``log_weights`` are the normalised posterior log weights of step k (from
    :func:`pf_update`); ``a_W`` the applied world acceleration; ``W`` the target's
    acceleration covariance. Returns the predicted particles (6×N; in ``out`` when given),
    their log weights and whether the step resampled. ``weights``, ``moments``: see
    :func:`resample_regularised`; ``W_factor``: ``W``'s Cholesky factor, when the caller
    keeps it.
    """
    n = particles.shape[1]
    particles, log_weights, chosen = resample_regularised(
        particles, log_weights, rng, parameters, weights=weights, moments=moments, work=work
    )
    # x⁺ = A x + B (a_W − ū): the known acceleration once, the target's per particle.
    draws = rng.standard_normal(out=work_rows(work, 3, 3, n))
    L = np.linalg.cholesky(np.asarray(W, dtype=float)) if W_factor is None else W_factor
    noise = np.matmul(L, draws, out=work_rows(work, 1, 3, n))
    moved = np.matmul(A, particles, out=np.empty((STATE_SIZE, n)) if out is None else out)
    moved += (B @ np.asarray(a_W, dtype=float).reshape(3))[:, None]
    moved -= np.matmul(B, noise, out=work_rows(work, 0, STATE_SIZE, n))
    return moved, log_weights, chosen is not None


def resample_regularised(
    particles: np.ndarray,
    log_weights: np.ndarray,
    rng: np.random.Generator,
    parameters: ParticleFilterParameters,
    *,
    weights: np.ndarray | None = None,
    moments: tuple[np.ndarray, np.ndarray] | None = None,
    work: Workspace | None = None,
    offset: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """When the effective sample size is below the threshold: systematic resampling, then the
    shrinkage kernel (equal weights after; with ``kernel: range_bearing`` about the vehicle,
    the particles being relative states less ``offset``, 6, default zero). Returns the
    particles, their log weights and the chosen ancestors' indices (None when it did not
    resample), so a particle's own data (its path's accelerations) can follow it.

    A caller that has them passes ``weights`` (``exp(log_weights)``) and ``moments``
    (:func:`weighted_moments` of those weights): the same numbers, not computed again.
    """
    if weights is None:
        weights = np.exp(log_weights)
    rows, n = particles.shape
    if not effective_sample_size(weights) < parameters.resample_threshold * n:
        return particles, log_weights, None
    h = parameters.bandwidth
    frame = None
    if h > 0.0 and parameters.kernel == "range_bearing":
        frame = range_bearing_frame(particles, weights, offset)
    if frame is not None:  # the kernel's coordinates, and their moments
        local = to_range_bearing(particles, frame, offset)
        moments = weighted_moments(local, weights)
    elif h > 0.0 and moments is None:
        moments = weighted_moments(particles, weights, work)
    chosen = systematic_resample(weights, float(rng.random()))
    log_weights = np.full(n, -math.log(n))
    if frame is not None:  # the chosen particles' own coordinates, moved and mapped back
        moved = shrinkage_kernel(local[:, chosen], *moments, h, rng)
        return from_range_bearing(moved, frame, offset), log_weights, chosen
    # "clip": the indices are in range, and numpy buffers ``out`` under the default "raise".
    particles = np.take(particles, chosen, axis=1, out=work_rows(work, 2, rows, n), mode="clip")
    if h > 0.0:
        particles = shrinkage_kernel(particles, *moments, h, rng, work)
    return particles, log_weights, chosen


def normalised(log_weights: np.ndarray) -> np.ndarray:
    """The weights of log weights, normalised to sum 1."""
    top = log_weights.max()
    if top == log_weights.min() and math.isfinite(top):  # equal (after a resampling)
        return np.full(log_weights.size, 1.0 / log_weights.size)  # exp(0) / N, the same bits
    w = np.exp(log_weights - top)
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
