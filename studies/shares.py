"""How many of a comparison's ``--runs`` each row runs, by what one of its runs costs.

A row on the hovering UUV runs a fifth of them and a row with a particle filter of 20 000
particles a tenth (200 and 100 of the results pages' 1000), since their runs cost several
times and a hundred times a kinematic run. A Gaussian filter whose hand-over may bridge on as
many particles runs them all: it carries them in few runs, and the robustness study needs its
thousand seeds. Every row runs the first seeds of the same sequence,
so two rows' common runs are paired by seed.
"""

import dataclasses
from collections.abc import Sequence

from drake_uuv.scenario import Scenario, load_scenario
from drake_uuv.scenario.estimators import ParticleFilter
from drake_uuv.scenario.plants import KinematicUuv
from drake_uuv.studies import Variant

#: The share of --runs a row on a vehicle plant (not the kinematic one) runs: 200 of 1000.
VEHICLE_SHARE = 0.2
#: The share of --runs a row with a particle filter of :data:`LARGE_CLOUD` particles runs.
LARGE_CLOUD_SHARE = 0.1
LARGE_CLOUD = 20_000


def run_share(scenario: Scenario) -> float:
    """The share of --runs a row of ``scenario`` runs (see the module notes)."""
    share = 1.0 if isinstance(scenario.plant, KinematicUuv) else VEHICLE_SHARE
    estimator = scenario.estimator
    if isinstance(estimator, ParticleFilter) and estimator.particle_count >= LARGE_CLOUD:
        share = min(share, LARGE_CLOUD_SHARE)
    return share


def with_shares(variants: Sequence[Variant], base: str = "paper") -> list[Variant]:
    """``variants`` with each row's :func:`run_share` as its ``run_fraction`` (its scenario:
    its own or ``base``, with its overrides)."""
    return [
        dataclasses.replace(
            v, run_fraction=run_share(load_scenario(v.scenario or base, list(v.overrides)))
        )
        for v in variants
    ]
