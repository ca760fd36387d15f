"""The attitude groups: Algorithm 2 against the information-seeking planner at equal rotation
per step, on the paper's kinematic plant (``attitude``) and on the hovering UUV at the rate it
can follow (``attitude_vehicle``)."""

from collections.abc import Sequence

from drake_uuv.scenario import load_scenario
from drake_uuv.studies import Group, Variant

from .shares import with_shares
from .vehicle import VEHICLE_ANGULAR_RATE, VEHICLE_LOOP, followable_target

# Rotation budgets [rad per step] of the attitude group: a quarter and a half of Algorithm 2's
# mean rotation per step in the paper scenario (0.381 rad), and about all of it.
ATTITUDE_BUDGETS = (0.1, 0.2, 0.39)
ATTITUDE_TITLE = "attitude: Algorithm 2 against the information-seeking planner, equal rotation"
ATTITUDE_VEHICLE_TITLE = "attitude on the hovering UUV: equal rotation within its rate limit"
# The estimators of the attitude group, by row name.
ATTITUDE_ESTIMATORS = {"kf": "estimator=!PaperKf", "ekf": "estimator=!Ekf"}


def attitude_budget_variants(budgets: Sequence[float] = ATTITUDE_BUDGETS) -> list[Variant]:
    """Algorithm 2 unlimited, then for each budget B [rad per step] Algorithm 2 rate-limited to
    B (``attitude.max_angular_rate = B / t``, so no step turns more than B) and the
    information-seeking planner with ``max_angle_per_step = B``: under the paper's KF and the
    raw-range EKF. Same seeds for all, so the rows pair run by run.

    ``t`` is the paper scenario's ``time_step`` (0.5 s); a base override of the time step
    would change the rate-limited rows' budget, not the planner's.
    """
    t = load_scenario("paper").time_step
    rows = []
    for name, chosen in ATTITUDE_ESTIMATORS.items():
        rows.append(
            Variant(
                f"{name}-alg2",
                ATTITUDE_TITLE,
                (chosen, "attitude=!TrajectoryAttitude"),
                "unlimited",
            )
        )
        for budget in budgets:
            note = f"{budget:g} rad/step"
            rows += [
                Variant(
                    f"{name}-alg2-{budget:g}",
                    ATTITUDE_TITLE,
                    (
                        chosen,
                        "attitude=!TrajectoryAttitude",
                        f"attitude.max_angular_rate={budget / t!r}",
                    ),
                    note,
                ),
                Variant(
                    f"{name}-info-{budget:g}",
                    ATTITUDE_TITLE,
                    (chosen, f"attitude=!InformationSeeking {{max_angle_per_step: {budget!r}}}"),
                    note,
                ),
            ]
    return rows


def attitude_vehicle_variants() -> list[Variant]:
    """Algorithm 2 rate-limited to :data:`~.vehicle.VEHICLE_ANGULAR_RATE` against the planner
    with the same rotation per step (``rate · t``), under the paper's KF and
    :data:`~.vehicle.VEHICLE_LOOP`, on the 8-thruster hovering UUV (``!HoveringAuv``) and, for
    reference, the paper's kinematic plant, with the paper's target slowed to one the vehicle
    can follow: W scaled by :func:`~.vehicle.followable_target` for an RMS speed of
    :data:`~.vehicle.VEHICLE_SPEED_BUDGET` at the last step (three digits), both in the target
    and in the filter. ``t`` and W are the paper scenario's (0.5 s)."""
    paper = load_scenario("paper")
    t = paper.time_step
    budget = VEHICLE_ANGULAR_RATE * t
    note = f"{budget:g} rad/step"
    scale, target = followable_target(paper)
    attitudes = {
        "alg2": ("attitude=!TrajectoryAttitude", f"attitude.max_angular_rate={budget / t!r}"),
        "info": (f"attitude=!InformationSeeking {{max_angle_per_step: {budget!r}}}",),
    }
    return with_shares(
        [
            Variant(
                f"{plant}-{kind}-{budget:g}",
                ATTITUDE_VEHICLE_TITLE,
                ("estimator=!PaperKf", *VEHICLE_LOOP, target, *chosen, *extra),
                f"{note}, W × {scale:g}",
            )
            for plant, extra in (("kinematic", ()), ("auv", ("plant=!HoveringAuv",)))
            for kind, chosen in attitudes.items()
        ]
    )


ATTITUDE_GROUP = Group(
    "attitude",
    "Algorithm 2 against the information-seeking planner, equal rotation, KF and EKF",
    attitude_budget_variants,
)
ATTITUDE_VEHICLE_GROUP = Group(
    "attitude_vehicle",
    f"the same on the hovering UUV at {VEHICLE_ANGULAR_RATE:g} rad/s, a target it can follow",
    attitude_vehicle_variants,
)
