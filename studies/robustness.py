"""The ``robustness`` group: does any run get lost?

Every shipped scenario with its own estimator, and the EKF, the UKF and the particle filter
(each as it defaults and with its consistency option) in the paper's regime, under the LQR
world-frame law, at a far standoff, with noisy sonars and in the realistic scenario on both
plants. The kinematic rows run ``--runs`` seeds (1000 on the results pages); the rows on the
hovering UUV a fifth of them and those with a 20 000-particle filter a tenth (:mod:`.shares`),
since their runs cost several and a hundred times a kinematic one.

A run is *lost* when the estimator-health monitor stopped it or its final position error
exceeds :data:`LOST_ERROR` (the paper's divergence threshold); the section lists the seeds.
"""

from drake_uuv.studies import Group, Variant

from .navigation import LAWS
from .shares import with_shares

ROBUSTNESS_TITLE = "robustness: lost runs, worst error and consistency over many seeds"
#: [m] A run whose final position error exceeds this is lost (the paper's divergence threshold).
LOST_ERROR = 10.0
#: Each shipped scenario, as it ships (its own estimator).
SHIPPED = ("paper", "noisy_sonar", "far_standoff", "hovering_auv", "realistic")
#: The regimes the raw-range filters are compared in: (scenario, overrides).
REGIMES: dict[str, tuple[str, tuple[str, ...]]] = {
    "paper": ("paper", ()),
    # The paper's loop under the navigation study's damped LQR law with q* fixed in the world
    # (≤ 3 m/s²), the law under which the textbook EKF is overconfident.
    "lqr": ("paper", LAWS["lqr"]),
    "far": ("far_standoff", ()),
    "noisy": ("noisy_sonar", ()),
    "realistic-auv": ("realistic", ()),
    "realistic-kinematic": ("realistic", ("plant=KinematicUuv",)),
}
#: The filters compared in each regime. The realistic scenario's prior (σ = 3 m, 1 m/s) is
#: every filter's there, as its particle filter's. ``ekf2`` is the EKF with the ranges'
#: second-order terms, their variance counted over 7 updates (``Ekf.second_order``); ``ukf2``
#: the UKF with its linearisation error's variance counted over 4 (``Ukf``'s docstring).
ESTIMATORS: dict[str, tuple[str, ...]] = {
    "ekf": ("estimator=Ekf",),
    "ekf2": (
        "estimator=Ekf",
        "estimator.second_order=full",
        "estimator.linearisation_correlation=7",
    ),
    "ukf": ("estimator=Ukf",),
    "ukf2": ("estimator=Ukf", "estimator.linearisation_correlation=4"),
    "pf": ("estimator=ParticleFilter",),
    "pf2": ("estimator=ParticleFilter", "estimator.particle_kernel=range_bearing"),
}
#: Rows only some regimes run: ``pf2`` (the particle filter's regularisation kernel in
#: range-bearing coordinates) where it is not the scenario's own (``far_standoff`` ships it).
ONLY_IN: dict[str, tuple[str, ...]] = {
    "pf2": ("paper", "lqr", "noisy", "realistic-auv", "realistic-kinematic")
}


def robustness_variants() -> list[Variant]:
    """``robust-<scenario>`` for each shipped scenario as it ships, then
    ``robust-<regime>-<estimator>`` (names unique among all groups' rows)."""
    rows = [
        Variant(
            f"robust-{name}",
            ROBUSTNESS_TITLE,
            (),
            f"{name}.yaml as shipped",
            scenario=name,
        )
        for name in SHIPPED
    ]
    for regime, (scenario, overrides) in REGIMES.items():
        for estimator, chosen in ESTIMATORS.items():
            if regime not in ONLY_IN.get(estimator, (regime,)):
                continue
            own = scenario == "realistic" and estimator == "pf"  # the scenario's own filter
            rows.append(
                Variant(
                    f"robust-{regime}-{estimator}",
                    ROBUSTNESS_TITLE,
                    overrides if own else (*overrides, *chosen),
                    f"{regime}, {estimator}",
                    scenario=None if scenario == "paper" else scenario,
                )
            )
    return with_shares(rows)


ROBUSTNESS_GROUP = Group(
    "robustness",
    "every shipped scenario and EKF, UKF, PF in six regimes: lost runs, worst error, NEES",
    robustness_variants,
)
