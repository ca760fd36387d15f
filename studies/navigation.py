"""The ``navigation`` group: does the loop survive real navigation and sonar timing?

Two parts:

* **each error source alone, and all of them together**, on the paper's kinematic plant and
  target, × the paper's KF, the EKF, the UKF and the particle filter, each with its error
  model on (``modelled``) and off (``ideal``: it believes navigation and timing perfect), ×
  the paper's tracking law and a damped world-frame LQR law (≤ 3 m/s²). Every filter
  predicts with the vehicle's navigated state (``vehicle_motion: navigation``): a real vehicle
  knows its motion from its DVL, not from its commands;
* **the realistic scenario** (``drake_uuv/scenarios/realistic.yaml``: the hovering UUV's
  flyable loop on a target it can follow, with every error together) on the hovering UUV and
  on the paper's kinematic plant, × the four estimators × the two error models. These rows
  carry the acceptance; each runs its share of ``--runs`` (:mod:`.shares`).

The error figures are commercial-grade ones, cited in ``realistic.yaml`` and
``drake_uuv/scenario/navigation.py``.
"""

from drake_uuv.studies import Group, Variant

from .shares import with_shares

NAVIGATION_TITLE = "navigation: each error source alone and all together × estimator × law"
REALISTIC_TITLE = "realistic: the hovering UUV's flyable loop with every error, two plants"


def _inertial(**figures: object) -> str:
    """``navigation=InertialNavigation {...}`` with every figure zero but ``figures``."""
    fields = {"attitude_noise_deg": [0.0, 0.0, 0.0], "heading_bias_deg": 0.0,
              "velocity_noise": 0.0, "velocity_bias": 0.0, **figures}  # fmt: skip
    return (
        "navigation=InertialNavigation {"
        + ", ".join(f"{name}: {value}" for name, value in fields.items())
        + "}"
    )


#: Each error source alone (name → note, --set overrides), then all of them.
SOURCES: dict[str, tuple[str, tuple[str, ...]]] = {
    "ideal": ("no error", ()),
    "ahrs": ("AHRS noise 0.5°/0.5°/2°", (_inertial(attitude_noise_deg=[0.5, 0.5, 2.0]),)),
    "compass": ("compass bias 2°", (_inertial(heading_bias_deg=2.0),)),
    "dvl": (
        "DVL 1 cm/s, bias 0.5 cm/s",
        (_inertial(velocity_noise=0.01, velocity_bias=0.005),),
    ),
    "pings": ("sonar 2 pings 0.25 s late", ("sonar.ping_offsets=[0.0, 0.25]",)),
    "latency": ("ranges 0.2 s late", ("sonar.latency=0.2",)),
    "sound": ("sound speed 0.5 % off", ("sonar.sound_speed_error=0.005",)),
    "all": (
        "all of them",
        (
            "navigation=InertialNavigation",
            "sonar.ping_offsets=[0.0, 0.25]",
            "sonar.latency=0.2",
            "sonar.sound_speed_error=0.005",
        ),
    ),
}
ESTIMATORS = {
    "kf": "estimator=PaperKf",
    "ekf": "estimator=Ekf",
    "ukf": "estimator=Ukf",
    "pf": "estimator=ParticleFilter",
}
ERROR_MODELS = ("modelled", "ideal")
LAWS = {
    "paper": (),  # the paper's law, q* in the body frame
    "lqr": (
        "tracking=LqrTracking",
        "tracking.reference_frame=world",
        "tracking.max_acceleration=3",
    ),
}
PLANTS = {"auv": "plant=HoveringAuv", "kinematic": "plant=KinematicUuv"}


def source_variants() -> list[Variant]:
    """Every source of :data:`SOURCES` × estimator × error model × law, named
    ``<law>-<source>-<estimator>-<model>`` (the error-free row has one model)."""
    rows = []
    for law, law_overrides in LAWS.items():
        for source, (note, overrides) in SOURCES.items():
            for estimator, chosen in ESTIMATORS.items():
                for model in ERROR_MODELS[:1] if source == "ideal" else ERROR_MODELS:
                    rows.append(
                        Variant(
                            f"{law}-{source}-{estimator}-{model}",
                            NAVIGATION_TITLE,
                            (
                                *law_overrides,
                                *overrides,
                                chosen,
                                "estimator.vehicle_motion=navigation",
                                f"estimator.error_model={model}",
                            ),  # fmt: skip
                            f"{law} law, {note}, {model}",
                        )
                    )
    return rows


#: The realistic scenario's prior (σ = 3 m per position axis, 1 m/s per velocity axis), given
#: to the estimators that replace its particle filter so that every row starts alike.
REALISTIC_PRIOR = (
    "estimator.initial_covariance="
    "[[9,0,0,0,0,0],[0,9,0,0,0,0],[0,0,9,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]"
)


def realistic_variants() -> list[Variant]:
    """The realistic scenario on each plant × estimator × error model, named
    ``realistic-<plant>-<estimator>-<model>`` (``pf``: the scenario's own particle filter)."""
    rows = []
    for plant, chosen_plant in PLANTS.items():
        for estimator, chosen in ESTIMATORS.items():
            own = estimator == "pf"
            for model in ERROR_MODELS:
                overrides = () if own else (chosen, REALISTIC_PRIOR)
                rows.append(
                    Variant(
                        f"realistic-{plant}-{estimator}-{model}",
                        REALISTIC_TITLE,
                        (
                            chosen_plant,
                            *overrides,
                            "estimator.vehicle_motion=navigation",
                            f"estimator.error_model={model}",
                        ),  # fmt: skip
                        f"{plant}, {model}",
                        scenario="realistic",
                    )
                )
    return with_shares(rows)


def navigation_variants() -> list[Variant]:
    return [*source_variants(), *realistic_variants()]


NAVIGATION_GROUP = Group(
    "navigation",
    "AHRS, compass, DVL, ping offsets, latency, sound speed × KF, EKF, UKF, PF × error model",
    navigation_variants,
)
