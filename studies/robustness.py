"""The ``robustness`` group: does any run get lost?

Every shipped scenario with its own estimator, and the EKF, the UKF and the particle filter in
the paper's regime, at a far standoff, with noisy sonars and in the realistic scenario on both
plants. The kinematic rows run ``--runs`` seeds (1000 on the results pages); the rows on the
hovering UUV a fifth of them (:data:`VEHICLE_SHARE`), since a vehicle run costs several times
a kinematic one.

A run is *lost* when the estimator-health monitor stopped it or its final position error
exceeds :data:`LOST_ERROR` (the paper's divergence threshold); the section lists the seeds.
"""

from drake_uuv.studies import Group, Variant

ROBUSTNESS_TITLE = "robustness: lost runs, worst error and consistency over many seeds"
#: The share of --runs a row on the hovering UUV runs (200 of 1000).
VEHICLE_SHARE = 0.2
#: [m] A run whose final position error exceeds this is lost (the paper's divergence threshold).
LOST_ERROR = 10.0
#: Each shipped scenario, as it ships (its own estimator), and whether it flies the vehicle.
SHIPPED = {
    "paper": False,
    "noisy_sonar": False,
    "far_standoff": False,
    "hovering_auv": True,
    "realistic": True,
}
#: The regimes the raw-range filters are compared in: (scenario, overrides, on the vehicle).
REGIMES: dict[str, tuple[str, tuple[str, ...], bool]] = {
    "paper": ("paper", (), False),
    "far": ("far_standoff", (), False),
    "noisy": ("noisy_sonar", (), False),
    "realistic-auv": ("realistic", (), True),
    "realistic-kinematic": ("realistic", ("plant=KinematicUuv",), False),
}
#: The filters compared in each regime. The realistic scenario's prior (σ = 3 m, 1 m/s) is
#: every filter's there, as its particle filter's.
ESTIMATORS = {"ekf": "estimator=Ekf", "ukf": "estimator=Ukf", "pf": "estimator=ParticleFilter"}


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
            run_fraction=VEHICLE_SHARE if vehicle else 1.0,
        )
        for name, vehicle in SHIPPED.items()
    ]
    for regime, (scenario, overrides, vehicle) in REGIMES.items():
        for estimator, chosen in ESTIMATORS.items():
            own = scenario == "realistic" and estimator == "pf"  # the scenario's own filter
            rows.append(
                Variant(
                    f"robust-{regime}-{estimator}",
                    ROBUSTNESS_TITLE,
                    overrides if own else (*overrides, chosen),
                    f"{regime}, {estimator}",
                    scenario=None if scenario == "paper" else scenario,
                    run_fraction=VEHICLE_SHARE if vehicle else 1.0,
                )
            )
    return rows


ROBUSTNESS_GROUP = Group(
    "robustness",
    "every shipped scenario and EKF, UKF, PF in four regimes: lost runs, worst error, NEES",
    robustness_variants,
)
