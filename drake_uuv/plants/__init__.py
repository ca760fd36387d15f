"""Plants: the vehicle (one system per variant of the plant slot) and the target.

Contract of the plant slot (system ``uuv``), whatever the vehicle model: inputs ``u1_B`` (the
paper's body-frame acceleration command u1 [m/s²]) and ``u2_W`` (its angular velocity command
u2 [rad/s], world frame, so that the paper's attitude step is ``R(k+1) = Exp(u2 t) R(k)``),
both the commands of step k, held over ``[kt, (k+1)t)``; outputs ``p_WU``, ``v_WU`` (the
body origin U, midpoint of the sonars, in the world [m, m/s]) and ``R_WB`` (row-major), the
state at the time of the context. A plant may output more (a real vehicle's thrusts); it
then lists those outputs in an ``extra_signals`` attribute so the run logs them, and a plant
with continuous state may set up the simulator's integrator in a ``configure_simulator``
method. See :mod:`drake_uuv.signals`. Each vehicle is built as
``cls(config, setting=PlantSetting(...))`` (:class:`~drake_uuv.plants.base.PlantSetting`); the
target as ``TargetRandomWalk(config, time_step=t)``.
"""

from drake_uuv.plants.base import PlantSetting
from drake_uuv.plants.factory import make_plant, plant_setting
from drake_uuv.plants.hovering_auv import HoveringAuvPlant
from drake_uuv.plants.kinematic_uuv import KinematicUuvPlant
from drake_uuv.plants.target_random_walk import TargetRandomWalk

__all__ = [
    "HoveringAuvPlant",
    "KinematicUuvPlant",
    "PlantSetting",
    "TargetRandomWalk",
    "make_plant",
    "plant_setting",
]
