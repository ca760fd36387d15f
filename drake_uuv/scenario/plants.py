"""The plant slot's variants: the vehicle model, one dataclass each, chosen by its tag.

The vehicle's initial state is the scenario's ``uuv`` section, common to every plant. The
factory that builds the system of each variant is :func:`drake_uuv.plants.make_plant`.
"""

from dataclasses import dataclass


@dataclass
class KinematicUuv:
    """The paper's vehicle (its eqs. 1–2): a world-frame double integrator driven by
    ``R u1`` whose attitude takes any commanded value in one step. No parameters."""

    def validate(self, name: str) -> None:
        pass


#: The plant slot. The first member is the default of an untagged section.
PlantConfig = KinematicUuv
