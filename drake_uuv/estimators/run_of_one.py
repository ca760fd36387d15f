"""A batch-of-one estimator seen as one run: the particle cloud's view with late ranges.

With late ranges a :class:`~drake_uuv.estimators.range_filter.RangeFilter` that may carry
particles steps one run (batch size 1), and its
:class:`~drake_uuv.estimators.particle_cloud.ParticleCloud` reads that run without the run
axis: :class:`RunOfOne` is the filter as the cloud reads it (its ranges, prior, vehicle
motion, navigation process noise and ping window, each of run 0), everything else the
filter's own. These wrap a system, never a configuration.
"""

import numpy as np
from pydrake.systems.framework import Context

from drake_uuv.estimators.base import RelativeStateEstimator
from drake_uuv.estimators.contract import Estimate, Ranges


class RunOfOne:
    """The host as the particle cloud reads it while the cloud steps one run: the filter
    itself, its batch of one seen without the run axis (ranges, prior, vehicle motion and
    the navigation's process noise); everything else, declarations included, is the
    filter's."""

    def __init__(self, host: RelativeStateEstimator) -> None:
        object.__setattr__(self, "_host", host)
        object.__setattr__(self, "vehicle_motion", _MotionOfOne(host.vehicle_motion))

    def __getattr__(self, name: str):
        return getattr(self._host, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._host, name, value)

    @property
    def window(self):
        window = self._host.window
        return None if window is None else _WindowOfOne(window)

    def ranges(self, context: Context) -> Ranges:
        return self._host.ranges(context).run(0)

    def prior(self, context: Context) -> Estimate:
        prior = self._host.prior(context)
        return Estimate(prior.x[0], prior.P[0])

    def navigation_process_noise(self, context: Context) -> np.ndarray | None:
        Q = self._host.navigation_process_noise(context)
        return None if Q is None else Q[0]


class _MotionOfOne:
    """A vehicle-motion strategy's values of run 0, without the run axis."""

    def __init__(self, motion) -> None:
        self._motion = motion

    @property
    def state_ports(self):
        return self._motion.state_ports

    def offset(self, context: Context) -> np.ndarray:
        return self._motion.offset(context)[0]

    def acceleration(self, context: Context) -> np.ndarray:
        return self._motion.acceleration(context)[0]


class _WindowOfOne:
    """The ping window's steps of run 0, without the run axis (the particle cloud's view)."""

    def __init__(self, window) -> None:
        self._window = window

    def __getattr__(self, name: str):
        return getattr(self._window, name)

    def steps(self, context: Context, samples: np.ndarray, status: np.ndarray):
        steps, current = self._window.steps(
            context, samples[np.newaxis], np.asarray(status)[np.newaxis]
        )
        return [step.run(0) for step in steps], current[0]
