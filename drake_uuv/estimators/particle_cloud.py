"""The particle cloud a raw-range filter carries where a Gaussian cannot describe the posterior.

A component of :class:`~drake_uuv.estimators.range_filter.RangeFilter`: it declares its own
abstract state, random input and cache entry on the filter that owns it (its *host*), and
steps the clouds of a batch of B runs, N particles each, with the compiled kernels of
:mod:`drake_uuv.models.particle_kernels` (the regularised particle filter of
:mod:`drake_uuv.models.particle_filter`, fused into a few passes over each run's cloud).

The batched API (what the host calls; B runs, N particles)
----------------------------------------------------------
``ParticleCloud(host, parameters, range_covariance, *, batch_size=B)`` declares on the host:

- abstract state (:meth:`ParticleCloud.arrays`, a
  :class:`~drake_uuv.primitives.run_arrays.RunArrays` that Drake's copies share, so a step
  whose clouds do not move carries them for nothing: the host updates it without
  restriction, its outputs published, :mod:`~drake_uuv.estimators.outputs`): the particles
  ``(B, N, 6)`` (run, particle, ``[q, ϑ]``), in the host's stored frame; their log weights
  ``(B, N)``; ``live`` ``(B,)`` (1 where the run's cloud holds a particle phase's particles:
  only those are weighed); with late ranges the window's draws;
- random input ``particle_seed``, ``B`` uniforms: run i's value, from run i's own stream,
  keys all of run i's draws of the step (:func:`~drake_uuv.models.particle_random.cloud_keys`),
  so run i's particles are a function of its seed alone, whatever B and its place;
- the cache entry ``particle posterior``.

Each step the host calls:

- :meth:`ParticleCloud.posterior` ``(context) -> (x, P, nis, log_weights)``: ``(B, 6)``,
  ``(B, 6, 6)``, ``(B,)``, ``(B, N)``: each live run's cloud reweighted by its step's ranges
  (relative frame; NIS NaN without a range; NaN rows for a run not live). Deterministic, no
  random input: the filtered output may depend on it.
- :meth:`ParticleCloud.advance` ``(context, filtered, state, draw=None,
  weigh_draw=False, *, drawn=None, runs=None, write_prediction=True) -> (x, P)`` in the
  periodic update: ``runs`` (``(B,)`` bool, default all) the runs whose cloud moves (the runs
  in the particle phase next step; the others are marked not live, their particles kept);
  ``filtered.status`` (``(B,)`` or one value) VALID where the posterior's weights replace the
  predicted ones; ``draw = (x, P)`` (``(B, 6)``, ``(B, 6, 6)``, relative frame) the Gaussian
  a run entering the particles draws its cloud from, for the runs of ``drawn`` (``(B,)``,
  default every run of ``runs``), weighed by its step's ranges where ``weigh_draw`` (``(B,)``
  or one bool). Returns the predicted clouds' mean and covariance, ``(B, 6)``, ``(B, 6, 6)``,
  stored frame, NaN for the runs not moving; with ``write_prediction`` it also writes the
  moving runs' as the host's prediction (``host.write_prediction(discrete_state, x, P,
  runs=runs)``: the other runs keep what the host wrote). ``state`` is the host's next
  ``State`` (the cloud's arrays and the host's discrete state).

Accessors: :meth:`~ParticleCloud.particles` ``(B, N, 6)`` relative,
:meth:`~ParticleCloud.log_weights` ``(B, N)``, :meth:`~ParticleCloud.set_particles`,
:meth:`~ParticleCloud.live`. Memory: :func:`bytes_per_run` is what a batch holds per run
(the state twice at a step that moves the clouds, the context's and the update's new one, and
the posterior's log weights and weights), so a study can size its batches: at N = 5000,
0.64 MB a run; at N = 20 000, 2.56 MB (B = 100: 256 MB).

What the cloud reads of its host: ``model`` (A, B, W), ``window``, ``error_model``,
``depends_on_measurement()``, ``ranges(context)`` (``z``, ``valid``, ``q_s``, ``exact``,
``covariance(R, x)``), ``prior(context).x``, ``vehicle_motion`` (``state_ports``,
``offset``, ``acceleration``), ``navigation_process_noise(context)`` and
``write_prediction``; each value with a leading run axis, or one run's value, which a batch of
one reads as such (:meth:`ParticleCloud._measurement`).

Late ranges (the host's ping window) are stepped by numpy on each live run's cloud in turn
(:class:`~drake_uuv.estimators.particle_window.LateRangeSteps`): the posterior is
``(x, P, nis, log_weights, None, first, dof)`` of the window and this tick's ranges (the NIS
and its dimensions of the ranges that arrived at the tick: :meth:`ParticleCloud.innovations`),
and the host's periodic update calls :meth:`~LateRangeSteps.advance_window` ``(context,
state, runs, drawn, draw_x, draw_P)`` in place of :meth:`ParticleCloud.advance`.
"""

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, State, ValueProducer

from drake_uuv.estimators.base import FilteredEstimate, RelativeStateEstimator
from drake_uuv.estimators.particle_window import LateRangeSteps
from drake_uuv.models.measurement import VALID
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_advance import cloud_advance
from drake_uuv.models.particle_filter import (
    STATE_SIZE,
    ParticleFilterParameters,
    Workspace,
)
from drake_uuv.models.particle_kernels import cloud_posterior, psd_factors
from drake_uuv.models.particle_random import cloud_keys
from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.primitives.random_input import declare_random_input
from drake_uuv.primitives.run_arrays import RunArrays, kept_rows


def bytes_per_run(count: int, window: int = 0, navigation_noise: bool = False) -> int:
    """The bytes a batch holds per run for a cloud of ``count`` particles, at a step that moves
    it: its state (particles, log weights, live flag; with late ranges each window step's
    accelerations and, with ``navigation_noise``, navigation noise) twice, the context's and
    the periodic update's new one, and the posterior's log weights and weights (the cache).
    The kernels' work arrays (about 12 N doubles) are the batch's, not per run."""
    state = count * (STATE_SIZE + 1) + 1 + window * count * (3 + (6 if navigation_noise else 0))
    return 8 * (2 * state + 2 * count)


@dataclass(frozen=True)
class CloudMeasurement:
    """A step's ranges as the kernels read them, each with a leading run axis: the per-sonar
    means ``z`` (B×2), which sonars returned ``used`` (B×2), the world baseline ``q_s`` (B×3),
    the ranges' covariance ``R`` (B×2×2, with the error model's at the prior), the stored
    frame's ``offset`` (B×6)."""

    z: np.ndarray
    used: np.ndarray
    q_s: np.ndarray
    R: np.ndarray
    offset: np.ndarray


def _runs(value: object, batch_size: int, *shape: int) -> np.ndarray:
    """A host's value as a new ``(B, *shape)`` array of doubles: a batch's, or one value for
    every run (the kernels take contiguous arrays of one kind, so each compiles once)."""
    array = np.asarray(value, dtype=float)
    if array.size == batch_size * math.prod(shape):
        return array.reshape(batch_size, *shape).copy()
    return np.broadcast_to(array.reshape(-1, *shape), (batch_size, *shape)).copy()


def _mask(value: object, batch_size: int) -> np.ndarray:
    """A per-run flag (or one flag for every run) as a new ``(B,)`` bool array."""
    array = np.asarray(value, dtype=bool).reshape(-1)
    return array.copy() if array.size == batch_size else np.full(batch_size, array[0])


class ParticleCloud(LateRangeSteps):
    """N weighted particles of the relative state for each of B runs, declared on ``host``.

    The filtered estimate of a particle step is each run's weighted mean and covariance of the
    predicted particles reweighted by the ranges' likelihood (:meth:`posterior`, a cache entry,
    deterministic in the inputs and the state); :meth:`advance`, called from the host's
    periodic update, resamples (systematic, when the effective sample size falls below the
    threshold), regularises and moves each particle by the model with its own target
    acceleration, and gives the predicted clouds' means and covariances. Randomness enters
    only through the host's random input port ``particle_seed`` (one uniform per run and step,
    read only in the periodic update), which keys the run's counter-based draws: a run is
    reproducible from its seed, alone or in any batch. See the module notes for the API.

    Abstract state on the host (:meth:`arrays`, per run): the predicted particles (N×6,
    particle-major) and their log weights (N), in the host's stored frame (see
    :mod:`~drake_uuv.estimators.vehicle_motion`: with ``vehicle_motion: navigation`` the
    particles are the target's, negated), and the run's ``live`` flag.
    """

    def __init__(
        self,
        host: RelativeStateEstimator,
        parameters: ParticleFilterParameters,
        range_covariance: np.ndarray,
        *,
        batch_size: int = 1,
    ) -> None:
        if not isinstance(parameters, ParticleFilterParameters):
            raise ValueError(f"parameters: must be ParticleFilterParameters, got {parameters!r}")
        self.batch_size = B = batch_size_field(batch_size)
        self._host = host
        # A host that does not step batches yet reads one run's values (shapes only).
        host_batch = getattr(host, "batch_size", None)
        self._one_run_host = host_batch is None
        if host_batch is not None and host_batch != B:
            raise ValueError(f"batch_size: must be the host's ({host_batch}), got {B}")
        A, Bu, W = host.model
        self._time_step = float(A[0, 3])
        expected = double_integrator(self._time_step)
        if not (np.array_equal(A, expected[0]) and np.array_equal(Bu, expected[1])):
            raise ValueError(
                f"model: must be a double integrator, got A = {np.asarray(A).tolist()}"
            )
        self._W_factor = np.linalg.cholesky(np.asarray(W, dtype=float))
        self._parameters = parameters
        self._R = np.asarray(range_covariance, dtype=float)
        # Writable like every other array the kernels take: one compiled signature each.
        self._R_runs = np.broadcast_to(self._R, (B, 2, 2)).copy()
        self._no_z, self._no_q_s = np.zeros((B, 2)), np.zeros((B, 3))
        self._no_used = np.zeros((B, 2), dtype=bool)
        n = parameters.count
        self._seed_port = declare_random_input(
            host, "particle_seed", 1, RandomDistribution.kUniform, batch_size=B
        )
        self._window = host.window
        self._jittered = self._window is not None and host.error_model.active
        # One abstract state, never written in place (RunArrays): a step whose clouds do not
        # move (a Gaussian filter's bridge, idle in most of its steps) carries them at no cost,
        # where a discrete state would be copied whole twice a step.
        self._cloud_index = host.DeclareAbstractState(AbstractValue.Make(self._initial_arrays()))
        if self._window is not None:
            # The late-range steps' work arrays: numpy's for the periodic update (6×N), the
            # kernels' (particle-major) for the window's steps.
            self._work = Workspace(n, arrays=4)
            self._steps = np.empty((2, n, STATE_SIZE))  # the window steps' particles in turn
            self._moved = np.empty((n, STATE_SIZE))  # at an instant's ping time
            self._weights = np.empty((2, n))  # the prior's and the posterior's
            self._ranges_work = np.empty((n, 2))
            self._no_jitter = np.zeros((0, n))
            self._no_ancestors = np.zeros(0, dtype=np.int64)
            self._no_offset = np.zeros(STATE_SIZE)
        # The posterior, shared by the filtered output and the periodic update: (x, P, nis,
        # log weights, weights, and with late ranges each run's first step's (log weights,
        # acceleration) once the window is full and the NIS's dimensions, else None each).
        self._posterior = host.DeclareCacheEntry(
            "particle posterior",
            ValueProducer(
                allocate=AbstractValue.Make(
                    (
                        np.zeros((B, 6)),
                        np.zeros((B, 6, 6)),
                        np.zeros(B),
                        np.zeros((B, n)),
                        np.zeros((B, n)),
                        None,
                        None,
                    )
                ).Clone,
                calc=self._calc_posterior,
            ),
            host.depends_on_measurement(),
        )

    def _initial_arrays(self) -> RunArrays:
        """The cloud's state at the start (see :meth:`arrays`): no run live."""
        B, n = self.batch_size, self._parameters.count
        arrays = {
            "particles": np.zeros((B, n, STATE_SIZE)),
            "log_weights": np.full((B, n), -math.log(n)),
            "live": np.zeros(B),
        }
        if self._window is not None:  # each particle's target acceleration over each step
            D = self._window.schedule.window
            arrays["accelerations"] = np.zeros((B, D, 3, n))
        # With modelled navigation errors, each particle's own draw of what they add over each
        # window step (D×6×N): replayed as the window's steps are, like the accelerations.
        if self._jittered:
            arrays["jitter"] = np.zeros((B, D, 6, n))
        return RunArrays(**arrays)

    @property
    def parameters(self) -> ParticleFilterParameters:
        return self._parameters

    # ------------------------------------------------------------------------ the state

    def arrays(self, context: Context) -> RunArrays:
        """The cloud's state: ``particles`` ``(B, N, 6)`` (stored frame), ``log_weights``
        ``(B, N)``, ``live`` ``(B,)`` and, with late ranges, ``accelerations`` ``(B, D, 3, N)``
        and (with modelled navigation errors) ``jitter`` ``(B, D, 6, N)``; read-only."""
        return context.get_abstract_state(self._cloud_index).get_value()

    @property
    def state_index(self) -> int:
        """The host's abstract state that holds the cloud's :meth:`arrays`."""
        return self._cloud_index

    def _write(self, state: State, arrays: RunArrays) -> None:
        state.get_mutable_abstract_state().get_mutable_value(self._cloud_index).set_value(arrays)

    def _stored_runs(self, context: Context) -> np.ndarray:
        """The predicted particles as stored, ``(B, N, 6)`` (a read-only view of the state)."""
        return self.arrays(context).particles

    def _log_weights_runs(self, context: Context) -> np.ndarray:
        return self.arrays(context).log_weights

    def particles(self, context: Context) -> np.ndarray:
        """The predicted particles of this step, ``(B, N, 6)`` relative states ``Υ``."""
        offset = _runs(self._host.vehicle_motion.offset(context), self.batch_size, STATE_SIZE)
        return self._stored_runs(context) + offset[:, np.newaxis, :]

    def log_weights(self, context: Context) -> np.ndarray:
        """The predicted particles' log weights, ``(B, N)``."""
        return self._log_weights_runs(context)

    def live(self, context: Context) -> np.ndarray:
        """Which runs' clouds hold a particle phase's particles, ``(B,)`` bool."""
        return self.arrays(context).live != 0.0

    def set_particles(
        self, context: Context, particles: np.ndarray, log_weights: np.ndarray
    ) -> None:
        """Sets this step's predicted particles (relative states, ``(B, N, 6)``; one run's
        ``(N, 6)`` for a batch of one) and log weights (``(B, N)`` or ``(N,)``); the runs
        become live."""
        B, n = self.batch_size, self._parameters.count
        particles = np.asarray(particles, dtype=float).reshape(B, n, STATE_SIZE)
        offset = _runs(self._host.vehicle_motion.offset(context), B, STATE_SIZE)
        arrays = self.arrays(context).replaced(
            particles=particles - offset[:, None, :],
            log_weights=np.array(log_weights, dtype=float).reshape(B, n),
            live=np.ones(B),
        )
        context.SetAbstractState(self._cloud_index, arrays)

    # ------------------------------------------------------------------------ each step

    def _measurement(self, context: Context, R: np.ndarray | None = None) -> CloudMeasurement:
        """This step's ranges, per run (``R``: the ranges' covariance for every run; default
        the sonars' plus the error model's at the prior)."""
        host, B = self._host, self.batch_size
        ranges = host.ranges(context)
        if R is None:
            R = self._R_runs
            if not ranges.exact:
                R = _runs(ranges.covariance(self._R, host.prior(context).x), B, 2, 2)
        valid = np.asarray(ranges.valid, dtype=bool).reshape(B, 2).copy()
        return CloudMeasurement(
            z=_runs(ranges.z, B, 2),
            used=valid,
            q_s=_runs(ranges.q_s, B, 3),
            R=R,
            offset=_runs(host.vehicle_motion.offset(context), B, STATE_SIZE),
        )

    def posterior(self, context: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(x, P, nis, log_weights)`` of this step's ranges, each run's (see the module
        notes; with late ranges, of the window's and this tick's ranges)."""
        x, P, nis, log_weights, *_ = self._posterior.Eval(context)
        if self._one_run_host:
            return x[0], P[0], float(nis[0]), log_weights[0]
        return x, P, nis, log_weights

    def innovations(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        """With late ranges, each run's ``(nis, dof)`` (B each) of the ranges that arrived at
        this tick, each weighed once along the window (NaN and 0 where none did, or for a run
        not live): what the host's divergence test reads."""
        if self._window is None:
            raise ValueError("innovations: only with late ranges (the host's ping window)")
        _, _, nis, _, _, _, dof = self._posterior.Eval(context)
        return nis, dof

    def _calc_posterior(self, context: Context, value: AbstractValue) -> None:
        if self._window is not None:
            value.set_value(self._window_posterior(context))
            return
        m = self._measurement(context)
        # Written in place: the cache entry owns its arrays (B·N each, allocated once per
        # context; a fresh pair each step would fault in and zero their pages every step).
        x, P, nis, log_posterior, weights, *_ = value.get_mutable_value()
        cloud_posterior(
            self._stored_runs(context), self._log_weights_runs(context), m.offset, m.z, m.used,
            m.q_s, m.R, self.live(context), x, P, nis, log_posterior, weights,
        )  # fmt: skip

    def advance(
        self,
        context: Context,
        filtered: FilteredEstimate,
        state: State,
        draw: tuple[np.ndarray, np.ndarray] | None = None,
        weigh_draw: bool | np.ndarray = False,
        *,
        drawn: np.ndarray | None = None,
        runs: np.ndarray | None = None,
        write_prediction: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The periodic update of the runs in ``runs``: each run's particles of this step
        (drawn from ``N(draw)`` for the runs of ``drawn``, weighed by this step's ranges where
        ``weigh_draw``; else reweighted by this step's ranges where ``filtered`` applied an
        update), resampled, regularised and predicted. Returns the predicted clouds' means
        and covariances (stored frame; NaN for runs not moving), written as the host's
        prediction with ``write_prediction``. Shapes: see the module notes."""
        host, B, n = self._host, self.batch_size, self._parameters.count
        moving = np.ones(B, dtype=bool) if runs is None else _mask(runs, B)
        if draw is None:
            drawn = np.zeros(B, dtype=bool)
            draw_x, draw_P = np.zeros((B, 6)), np.zeros((B, 6, 6))
        else:
            drawn = moving if drawn is None else _mask(drawn, B) & moving
            draw_x, draw_P = _runs(draw[0], B, STATE_SIZE), _runs(draw[1], B, 6, 6)
        weighed = _mask(weigh_draw, B) & drawn
        reweigh = _mask(np.asarray(filtered.status) == VALID, B) & moving & ~drawn
        if reweigh.any():  # this step's ranges reweight those runs' clouds
            posterior = self._posterior.Eval(context)
        else:  # not read
            posterior = (np.empty((B, 6)), np.empty((B, 6, 6)), None, *np.empty((2, B, n)))
        if weighed.any():  # a draw is weighed by this step's ranges with the sonars' R
            m = self._measurement(context, self._R_runs)
        else:  # only the offset is read
            offset = _runs(host.vehicle_motion.offset(context), B, STATE_SIZE)
            m = CloudMeasurement(self._no_z, self._no_used, self._no_q_s, self._R_runs, offset)
        keys = cloud_keys(np.array(self._seed_port.Eval(context), dtype=float))
        acceleration = _runs(host.vehicle_motion.acceleration(context), B, 3)
        Q_nav = host.navigation_process_noise(context)
        if Q_nav is None:
            jitter = np.zeros((B, 6, 6))
        else:  # the modelled navigation errors' process noise, a factor per run
            jitter = psd_factors(_runs(Q_nav, B, 6, 6))
        before = self.arrays(context)
        # The runs not moving keep their particles: the kernel writes the moving ones' whole.
        out = kept_rows(before.particles, ~moving)
        out_log_weights = kept_rows(before.log_weights, ~moving)
        x, P = np.empty((B, 6)), np.empty((B, 6, 6))
        cloud_advance(
            before.particles, before.log_weights, reweigh,
            posterior[3], posterior[4], posterior[0], posterior[1], keys, moving, drawn, draw_x,
            draw_P, weighed, m.offset, m.z, m.used, m.q_s, m.R, self._time_step, acceleration,
            self._W_factor, jitter, self._parameters.resample_threshold,
            self._parameters.bandwidth, self._parameters.kernel == "range_bearing", out,
            out_log_weights, x, P,
        )  # fmt: skip
        self._write(
            state,
            before.replaced(particles=out, log_weights=out_log_weights, live=moving.astype(float)),
        )
        if write_prediction:
            discrete_state = state.get_mutable_discrete_state()
            if self._one_run_host:
                host.write_prediction(discrete_state, x[0], P[0])
            else:  # the moving runs' rows only: the others keep the host's own
                host.write_prediction(discrete_state, x, P, runs=moving)
        return x, P
