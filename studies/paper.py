"""The paper's groups: its attitude generators, the noise model of Y, the tracking gain α and
the tracking law, and every estimator against the posterior Cramér–Rao bound.

``attitude_noise``, ``alpha`` and ``tracking`` test the paper's claims (excitation makes the
state observable, Algorithm 2 tracks better than Algorithm 1, the printed Γ, the α interval);
``estimator`` goes beyond it. Every group lists its variants: a new estimator or attitude
generator joins one only when it is added here.
"""

from collections.abc import Sequence

from drake_uuv.scenario import ALPHA_PROVEN_INTERVAL
from drake_uuv.studies import Group, Variant

# The paper's attitude generators, in the order its claims discuss them.
PAPER_ATTITUDES = {"fixed": "attitude=!FixedAttitude", "random": "attitude=!RandomAttitude",
                   "trajectory": "attitude=!TrajectoryAttitude"}  # fmt: skip
# The noise models of Y: the exact mean and variance of the paper's Y, and its printed Γ.
NOISE_MODELS = ("derived", "paper_printed")
# The estimators of the `estimator` group, by row name.
ESTIMATORS = {
    "kf": "estimator=!PaperKf",
    "ekf": "estimator=!Ekf",
    "iekf": "estimator=!Iekf",
    "ukf": "estimator=!Ukf",
    "particle_filter": "estimator=!ParticleFilter",
}
ESTIMATOR_TITLE = "estimator × attitude mode"

# Across and beyond the proven interval (1 − 1/√2, 1 + 1/√2) ≈ (0.293, 1.707); with a perfect
# estimate the tracking error obeys e(k+1) = (1 − α) e(k) + …, bounded for 0 < α < 2.
ALPHAS = (0.05, 0.2, 0.29, 0.5, 1.0, 1.2, 1.5, 1.71, 1.9, 1.98, 2.02, 2.2)


def attitude_noise_variants() -> list[Variant]:
    """The paper's attitude generators × noise model (its claims on excitation and on Γ)."""
    return [
        Variant(
            f"{mode}-{noise}",
            "attitude × noise model",
            (attitude, f"estimator.noise_model={noise}"),
        )
        for mode, attitude in PAPER_ATTITUDES.items()
        for noise in NOISE_MODELS
    ]


def alpha_sweep_variants(alphas: Sequence[float] = ALPHAS) -> list[Variant]:
    """The tracking gain α across and beyond the interval where the paper proves boundedness."""
    return [
        Variant(
            f"alpha-{alpha:g}",
            "tracking gain α",
            (f"tracking.alpha={alpha!r}", "tracking.allow_unproven_alpha=true"),
            "proven" if ALPHA_PROVEN_INTERVAL[0] < alpha < ALPHA_PROVEN_INTERVAL[1] else "unproven",
        )
        for alpha in alphas
    ]


def estimator_attitude_variants() -> list[Variant]:
    """:data:`ESTIMATORS` × the paper's attitude generators, for the RMSE / PCRLB tables
    (:func:`drake_uuv.studies.ratio_tables`)."""
    return [
        Variant(f"{estimator}-{mode}", ESTIMATOR_TITLE, (override, attitude), ratio_table=True)
        for estimator, override in ESTIMATORS.items()
        for mode, attitude in PAPER_ATTITUDES.items()
    ]


def tracking_law_variants() -> list[Variant]:
    """The paper's law and the LQR law, with and without a 7 m/s² acceleration limit (what a
    ~31 kg hovering vehicle with 77.6 N thrusters manages), under Algorithms 2 and 1."""
    return [
        Variant(
            f"{mode}-{law}{tag}",
            "tracking law × attitude mode",
            (PAPER_ATTITUDES[mode], f"tracking=!{tracking}", *extra),
        )
        for mode in ("trajectory", "random")
        for law, tracking in (("paper", "PaperTracking"), ("lqr", "LqrTracking"))
        for tag, extra in (("", ()), ("-limit7", ("tracking.max_acceleration=7",)))
    ]


ATTITUDE_NOISE_GROUP = Group(
    "attitude_noise",
    "the paper's attitude generators × noise model of Y (excitation; Γ)",
    attitude_noise_variants,
    paper=True,
)
ALPHA_GROUP = Group(
    "alpha",
    "the tracking gain α across and beyond the paper's proven interval",
    alpha_sweep_variants,
    paper=True,
)
ESTIMATOR_GROUP = Group(
    "estimator",
    "KF, EKF, IEKF, UKF, particle filter × attitude, against the PCRLB",
    estimator_attitude_variants,
)
TRACKING_GROUP = Group(
    "tracking",
    "the paper's and the LQR law, with and without a 7 m/s² limit, Algorithms 2 and 1",
    tracking_law_variants,
    paper=True,
)
