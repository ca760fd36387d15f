"""Attitude generators: the paper's Algorithms 1 and 2 and an information-seeking planner.

Contract of the slot (system ``attitude_generator``): input ``R_WB_nav`` (the navigated
attitude), and any other signal it needs by name (a random ``rotation_noise`` for Algorithm 1,
the filtered estimate for the information-seeking planner); outputs ``u2_W`` (the paper's u2,
world frame, so that ``R(k+1) = Exp(u2 t) R(k)``) and ``R_WB_plan`` (the planned ``R(k+1)``,
``R(k+2)``). See :mod:`drake_uuv.signals`. Each system is built as
``cls(config, setting=AttitudeSetting(...), batch_size=B)``
(:class:`~drake_uuv.attitude.base.AttitudeSetting`) and steps B runs, every port and state
holding them row-major (:mod:`drake_uuv.primitives.batch`).
"""

from drake_uuv.attitude.base import AttitudeGenerator, AttitudeSetting
from drake_uuv.attitude.factory import attitude_setting, make_attitude_generator
from drake_uuv.attitude.fixed_attitude import FixedAttitudeGenerator
from drake_uuv.attitude.information_seeking import InformationSeekingAttitude
from drake_uuv.attitude.random_attitude import RandomAttitudeGenerator
from drake_uuv.attitude.trajectory_attitude import TrajectoryAttitudeGenerator

__all__ = [
    "AttitudeGenerator",
    "AttitudeSetting",
    "FixedAttitudeGenerator",
    "InformationSeekingAttitude",
    "RandomAttitudeGenerator",
    "TrajectoryAttitudeGenerator",
    "attitude_setting",
    "make_attitude_generator",
]
