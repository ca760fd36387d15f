"""Plants: the vehicle and the target."""

from drake_uuv.plants.target_random_walk import TargetRandomWalk
from drake_uuv.plants.uuv_plant import UuvPlant

__all__ = ["TargetRandomWalk", "UuvPlant"]
