"""The ``regimes`` group: the estimators across range noise and standoff.

σ = 0.1, 0.5 and 1 m of range noise at the paper's standoff, and 2.8, 14 and 28 m of standoff
with q* fixed in the world, × the paper's KF, the raw-range EKF, UKF and particle filter, and
the particle filter with four times its default count as the reference.
"""

from drake_uuv.studies import Group, Variant

from .shares import with_shares

REGIMES_TITLE = "regimes: range noise and standoff × estimator"
# The regimes of the estimators' study: name → (note, --set overrides). σ at the paper's
# standoff (q* = [−2, −2, 0] in the body frame, |q*| ≈ 2.8 m); standoff at σ = 0.1 m with q*
# fixed in the world frame (in the body frame it spins with Algorithm 2's turning).
REGIMES: dict[str, tuple[str, tuple[str, ...]]] = {
    "paper": ("σ = 0.1 m, paper (2.8 m body)", ("sonar.noise_variances=[0.01, 0.01]",)),
    "sigma0.5": ("σ = 0.5 m, paper standoff", ("sonar.noise_variances=[0.25, 0.25]",)),
    "sigma1": ("σ = 1 m, paper standoff", ("sonar.noise_variances=[1.0, 1.0]",)),
    **{
        f"world{name}": (
            f"σ = 0.1 m, {name} m world",
            (
                "sonar.noise_variances=[0.01, 0.01]",
                "tracking.reference_frame=world",
                f"tracking.desired_relative_position=[{side}, {side}, 0.0]",
            ),
        )
        for name, side in (("2.8", -2.0), ("14", -10.0), ("28", -20.0))
    },
}
# The estimators of the regime study: the paper's KF, the raw-range EKF, UKF and particle
# filter (each handing over from the KF by the default rule), and the particle filter with
# four times its default count as the large-count reference (the empirical optimum).
REGIME_ESTIMATORS = {
    "kf": "estimator=!PaperKf",
    "ekf": "estimator=!Ekf",
    "ukf": "estimator=!Ukf",
    "pf": "estimator=!ParticleFilter",
    "pf20000": "estimator=!ParticleFilter {particle_count: 20000}",
}


def regime_variants() -> list[Variant]:
    """Every regime of :data:`REGIMES` × :data:`REGIME_ESTIMATORS`, named
    ``<regime>-<estimator>`` (``sigma0.5-pf``, ``world28-pf20000``)."""
    return with_shares(
        [
            Variant(f"{regime}-{estimator}", REGIMES_TITLE, (*overrides, override), note)
            for regime, (note, overrides) in REGIMES.items()
            for estimator, override in REGIME_ESTIMATORS.items()
        ]
    )


REGIMES_GROUP = Group(
    "regimes",
    "range noise 0.1–1 m and standoff 2.8–28 m × KF, EKF, UKF, particle filters",
    regime_variants,
)
