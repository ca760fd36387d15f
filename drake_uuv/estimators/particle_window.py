"""The particle cloud's steps with late ranges (the host's ping window), for a batch of runs.

A base of :class:`~drake_uuv.estimators.particle_cloud.ParticleCloud`: with late ranges each
run's cloud at the window's anchor is stepped through the window's steps, each range weighed
at its ping time along each particle's path, by numpy on the run's cloud (6×N views of its
state), with a ``numpy.random.Generator`` seeded by the run's uniform of the step. Each
particle keeps its target acceleration (and with modelled navigation errors its draw of their
noise) over each window step, replayed as the window's steps are.

The runs of a batch are stepped one after the other, each by numpy over its own 5000-20 000
particles (a Python loop over runs: its cost is a few microseconds a run against
milliseconds of work), and only the runs whose cloud is live (the posterior) or moving (the
periodic update) do any work. A run's numbers depend on its own state, inputs and uniform
alone; a run whose numbers fail (a factor or a solve of NaN) gets NaN and the others go on.
"""

import functools
import math
from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import Context, State
from threadpoolctl import ThreadpoolController

from drake_uuv.estimators.ping_window import StepBatch
from drake_uuv.estimators.timed_step import instant_ranges, instants
from drake_uuv.models.particle_filter import STATE_SIZE, defensive_draw, resample_regularised
from drake_uuv.models.particle_window_kernels import (
    moments,
    move_into,
    move_resampled_into,
    prior_mean,
    weigh,
)
from drake_uuv.models.timing import transition
from drake_uuv.primitives.batch import per_run
from drake_uuv.primitives.run_arrays import kept_rows

# The uniform draw of the random port becomes a generator seed with this many bits (a double
# in [0, 1) carries 53).
_SEED_BITS = 53


# A cloud drawn at the window's anchor is weighed at once by the window's ranges, which the
# Gaussian it is drawn from never saw as raw ranges: where they fall in its tail (a linear
# start is loose along the line of sight), N(x, P)'s own draws leave a handful of particles
# with weight. Drawing from N(x, 2P), weighted back to N(x, P), populates the tail at a cost
# of about half the effective sample size (realistic scenario, seed 9: 3 particles of 5000
# kept their weight and the run stopped; with the widening it ran to the end).
_HANDOVER_WIDENING = 2.0

_blas: list | None = None


def _on_one_blas_thread(method: Callable) -> Callable:
    """Runs ``method`` with BLAS on one thread (the late-range steps' numpy products). The
    cloud's products (6×N by N, 6×6 by 6×N, N by N) are split over threads by OpenBLAS from
    about 10⁴ elements on, and waking the threads costs more than the product, the more so on
    a busy machine: the realistic run (20 000 particles) took 13 s of CPU with the default
    threads against 3 s with one. The BLAS libraries are found once and their thread counts
    read and set directly (about 3 µs a call, where ``ThreadpoolController.limit`` inspects
    every library each time, 20 µs)."""

    @functools.wraps(method)
    def on_one_thread(*args, **kwargs):
        global _blas
        if _blas is None:  # after numpy's import, so that it finds numpy's BLAS
            _blas = ThreadpoolController().select(user_api="blas").lib_controllers
        changed = [(blas, n) for blas in _blas if (n := blas.num_threads) != 1]
        for blas, _ in changed:
            blas.set_num_threads(1)
        try:
            return method(*args, **kwargs)
        finally:
            for blas, n in changed:
                blas.set_num_threads(n)

    return on_one_thread


class LateRangeSteps:
    """The late-range steps of :class:`~drake_uuv.estimators.particle_cloud.ParticleCloud`
    (which declares the state they read: the particles, log weights, the window's per-particle
    accelerations and navigation noise, and the work arrays), each run's in turn."""

    def accelerations(self, context: Context) -> np.ndarray:
        """Each run's particles' target acceleration over each window step (B×D×3×N)."""
        return self.arrays(context).accelerations

    def jitter(self, context: Context) -> np.ndarray | None:
        """Each run's particles' draw of the navigation's process noise over each window step
        (B×D×6×N; None without modelled navigation errors or late ranges)."""
        return self.arrays(context).jitter if self._jittered else None

    @staticmethod
    def _jitter_root(Q: np.ndarray | None) -> np.ndarray | None:
        """A root of one run's ``Q_nav``, what the modelled navigation errors add over the
        step from this tick (the Gaussian filters add it to their Q); None when they add
        nothing."""
        if Q is None:
            return None
        # Q_nav has rank 3 (an acceleration's, or the position's walk): a symmetric root.
        values, vectors = np.linalg.eigh(Q)
        return vectors * np.sqrt(np.clip(values, 0.0, None))

    def _draw_jitter(
        self, root: np.ndarray | None, rng: np.random.Generator, out: np.ndarray | None = None
    ) -> np.ndarray | None:
        """Per particle, a draw of ``N(0, Q_nav)`` from its ``root`` (zero without one, in
        ``out``; None without ``out``)."""
        if root is None:
            if out is not None:
                out[...] = 0.0
            return out
        return np.matmul(root, rng.standard_normal((6, self._parameters.count)), out=out)

    def _window_steps(self, context: Context) -> list[StepBatch]:
        host = self._host
        samples = host.GetInputPort("range_samples").Eval(context)
        status = host.GetInputPort("sonar_status").Eval(context)
        B = self.batch_size
        steps, _ = self._window.steps(
            context, samples.reshape(B, 2, -1), per_run(np.asarray(status), B)
        )
        return steps

    def _step(
        self,
        particles: np.ndarray,
        log_weights: np.ndarray,
        u: np.ndarray,
        step,
        out: np.ndarray,
        jitter: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, list[tuple[float, int]]]:
        """One run's stored-frame particles (N×6) at a step's tick (plus their ``jitter``
        (6×N, or 0×N), the navigation's process noise), reweighted by its arrived ranges at
        their ping times along each particle's path (accelerations ``u``, 3×N), and moved to
        the next tick (in ``out``); with the ``(NIS, dimensions)`` of each instant that holds
        a range arriving at this tick."""
        host = self._host
        t = host.time_step
        navigated = host.error_model.navigated_motion
        a = np.zeros(3) if navigated else step.acceleration
        moved, mean = self._moved, np.empty(STATE_SIZE)
        prior, posterior = self._weights
        new_nis = []
        for instant in instants(step, paired=False):
            _, B = transition(instant.tau)
            c = B @ a
            if navigated:
                c = c + step.vehicle(instant.tau, t)
            move_into(particles, jitter, u, float(instant.tau), c, moved)
            q_s = step.attitude(instant.tau, t) @ host.baseline
            ranges = instant_ranges(host, instant, q_s, step)
            # The prior's mean, for the error model's noise there.
            prior_mean(moved, self._no_offset, log_weights, prior, mean)
            R = self._R if ranges.exact else ranges.covariance(self._R, mean)
            weighed = np.empty(log_weights.shape)
            nis = weigh(
                moved, self._no_offset, log_weights, prior, ranges.z, ranges.valid, q_s, R,
                self._ranges_work, weighed, posterior,
            )  # fmt: skip
            log_weights = weighed
            if np.any(step.new[instant.sonars]):
                new_nis.append((nis, int(np.count_nonzero(ranges.valid))))
        _, B = transition(t)
        move_into(particles, jitter, u, float(t), B @ a, out)
        return out, log_weights, new_nis

    def _window_posterior(self, context: Context) -> tuple:
        """``(x, P, nis, log_weights, None, first, dof)`` at this tick ((B, 6), (B, 6, 6),
        (B), (B, N), relative frame): each live run's cloud at the anchor stepped through the
        window, then this tick's ranges (NaN rows for the others); ``first`` (B) each run's
        first step's log weights, acceleration and navigated start state when its ranges have
        all arrived (the periodic update resamples with them), else None. ``nis`` and ``dof``
        (B) are of the ranges that arrived at this tick, each counted once (the window's
        instants that hold one, and this tick's own): NaN and 0 when none did."""
        host = self._host
        B, n = self.batch_size, self._parameters.count
        x, P = np.full((B, 6), np.nan), np.full((B, 6, 6), np.nan)
        nis, dof, log_weights = np.full(B, np.nan), np.zeros(B), np.full((B, n), np.nan)
        first: list = [None] * B
        live = self.live(context)
        if live.any():
            steps = self._window_steps(context)
            offset = host.vehicle_motion.offset(context)
            ranges = host.ranges(context)
            particles = self._stored_runs(context)
            prior = self._log_weights_runs(context)
            u = self.accelerations(context)
            jitter = self.jitter(context)
            for r in np.flatnonzero(live):
                with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                    try:
                        nis[r], dof[r], log_weights[r], first[r] = self._run_posterior(
                            context, [step.run(r) for step in steps], particles[r], prior[r],
                            u[r], None if jitter is None else jitter[r], offset[r],
                            ranges.run(r), x[r], P[r],
                        )  # fmt: skip
                    except np.linalg.LinAlgError:  # a failed run: NaN, the others go on
                        x[r], P[r], first[r] = np.nan, np.nan, None
        return x, P, nis, log_weights, None, first, dof

    def _run_posterior(
        self,
        context: Context,
        steps: list,
        particles: np.ndarray,
        log_weights: np.ndarray,
        u: np.ndarray,
        jitter: np.ndarray | None,
        offset: np.ndarray,
        ranges,
        x: np.ndarray,
        P: np.ndarray,
    ) -> tuple:
        """One run's ``(nis, dof, log_weights, first)`` (see :meth:`_window_posterior`), its
        posterior's mean and covariance in ``x`` and ``P``. ``particles`` N×6 (stored
        frame), ``u`` D×3×N, ``jitter`` D×6×N or None."""
        j = self._window.tick(context)
        D = self._window.schedule.window
        nis_total, first = [], None
        for i, step in enumerate(steps):
            slot = step.step - (j - D)
            particles, log_weights, new_nis = self._step(
                particles, log_weights, u[slot], step, self._steps[i % 2],
                self._no_jitter if jitter is None else jitter[slot],
            )  # fmt: skip
            nis_total += new_nis
            if first is None and j >= D:
                first = (log_weights, step.acceleration, step.start)
        prior, posterior = self._weights
        if ranges.valid.any():  # this tick's own pings (no latency, at the tick)
            mean = np.empty(STATE_SIZE)
            prior_mean(particles, offset, log_weights, prior, mean)
            R = self._R if ranges.exact else ranges.covariance(self._R, mean)
            weighed = np.empty(log_weights.shape)
            nis = weigh(
                particles, offset, log_weights, prior, ranges.z, ranges.valid, ranges.q_s, R,
                self._ranges_work, weighed, posterior,
            )  # fmt: skip
            log_weights = weighed
            nis_total.append((nis, int(np.count_nonzero(ranges.valid))))
        moments(particles, offset, log_weights, posterior, x, P)
        if not nis_total:
            return math.nan, 0, log_weights, first
        values, dimensions = zip(*nis_total, strict=True)
        return float(sum(values)), sum(dimensions), log_weights, first

    @_on_one_blas_thread
    def advance_window(
        self,
        context: Context,
        state: State,
        runs: np.ndarray,
        drawn: np.ndarray,
        draw_x: np.ndarray,
        draw_P: np.ndarray,
    ) -> None:
        """The periodic update with late ranges of the runs in ``runs`` (B): each one's
        anchor's cloud moved one step on (its oldest step's ranges weighed, resampled and
        regularised, moved by each particle's own acceleration), or, for the runs of
        ``drawn`` (B), drawn from ``N(draw_x, draw_P)`` ((B, 6), (B, 6, 6), stored frame, at
        the new anchor); a new acceleration per particle for the window's newest step. The
        moving runs' clouds become live, the others not (their particles kept); the moving
        runs' predictions are written."""
        host = self._host
        B = self.batch_size
        before = self.arrays(context)
        moving = np.asarray(runs, dtype=bool).reshape(B)
        if not moving.any():
            self._write(state, before.replaced(live=np.zeros(B)))
            return
        drawn = np.asarray(drawn, dtype=bool).reshape(B) & moving
        seeds = np.asarray(self._seed_port.Eval(context), dtype=float)
        # New arrays: the runs not moving keep theirs, the moving ones' are written below.
        kept = ~moving
        out, out_log_weights = (
            kept_rows(before.particles, kept),
            kept_rows(before.log_weights, kept),
        )
        u_next = kept_rows(before.accelerations, kept)
        jitter_next = Q = None
        if self._jittered:
            jitter_next = kept_rows(before.jitter, kept)
            Q = host.navigation_process_noise(context)
        moved = moving & ~drawn
        if moved.any():
            particles = self._stored_runs(context)
            log_weights = self._log_weights_runs(context)
            u = self.accelerations(context)
            jitter = self.jitter(context)
            first = self._posterior.Eval(context)[5]
        x, P = np.full((B, 6), np.nan), np.full((B, 6, 6), np.nan)
        for r in np.flatnonzero(moving):
            rng = np.random.default_rng(int(seeds[r] * 2.0**_SEED_BITS))
            root = None
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                try:
                    if Q is not None:
                        root = self._jitter_root(Q[r])
                    if drawn[r]:
                        weights = self._draw_run(
                            draw_x[r], draw_P[r], rng, root, out[r].T, u_next[r],
                            None if jitter_next is None else jitter_next[r],
                        )  # fmt: skip
                    else:
                        weights = self._move_run(
                            particles[r].T, log_weights[r], u[r],
                            None if jitter is None else jitter[r], first[r], rng, root,
                            out[r].T, u_next[r], None if jitter_next is None else jitter_next[r],
                        )  # fmt: skip
                    out_log_weights[r] = weights
                    moments(out[r], self._no_offset, weights, self._weights[0], x[r], P[r])
                except np.linalg.LinAlgError:  # a failed run: NaN, the others go on
                    out[r] = np.nan
                    out_log_weights[r] = np.nan
                    u_next[r] = before.accelerations[r]  # its draws as they were
                    if jitter_next is not None:
                        jitter_next[r] = before.jitter[r]
        host.write_prediction(state.get_mutable_discrete_state(), x, P, runs=moving)
        arrays = {"particles": out, "log_weights": out_log_weights, "accelerations": u_next}
        if jitter_next is not None:
            arrays["jitter"] = jitter_next
        self._write(state, before.replaced(live=moving.astype(float), **arrays))

    def _draw_run(
        self,
        x: np.ndarray,
        P: np.ndarray,
        rng: np.random.Generator,
        root: np.ndarray | None,
        out: np.ndarray,
        u_next: np.ndarray,
        jitter_next: np.ndarray | None,
    ) -> np.ndarray:
        """One run's cloud drawn from ``N(x, P)`` into ``out`` (6×N) with each window step's
        accelerations and navigation noise; returns its log weights."""
        count = self._parameters.count
        particles, log_weights = defensive_draw(x, P, count, rng, _HANDOVER_WIDENING)
        out[...] = particles
        for k in range(self._window.schedule.window):
            np.matmul(self._W_factor, rng.standard_normal((3, count)), out=u_next[k])
            if jitter_next is not None:
                self._draw_jitter(root, rng, jitter_next[k])
        return log_weights

    def _move_run(
        self,
        particles: np.ndarray,
        log_weights: np.ndarray,
        u: np.ndarray,
        jitter: np.ndarray | None,
        first: tuple | None,
        rng: np.random.Generator,
        root: np.ndarray | None,
        out: np.ndarray,
        u_next: np.ndarray,
        jitter_next: np.ndarray | None,
    ) -> np.ndarray:
        """One run's anchor cloud (6×N) moved one step on into ``out``, its window's slots
        shifted into ``u_next`` and ``jitter_next`` with a new newest step; returns its log
        weights."""
        host, work = self._host, self._work
        chosen = None
        if first is None:
            out[...] = particles
        else:  # the oldest step's ranges have all arrived: the posterior weighed them
            weighed, acceleration, start = first
            # The range-bearing kernel's centre is the vehicle at the anchor: with navigated
            # motion the stored frame is the relative state less the navigated state there
            # (else the relative state itself).
            anchor = start if host.error_model.navigated_motion else None
            particles, log_weights, chosen = resample_regularised(
                particles, weighed, rng, self._parameters, work=work, offset=anchor
            )
            # Each particle's path follows its ancestor: its acceleration and its draw of
            # the navigation's noise.
            a = np.zeros(3) if host.error_model.navigated_motion else acceleration
            _, B = transition(host.time_step)
            move_resampled_into(
                particles, self._no_ancestors if chosen is None else chosen,
                self._no_jitter if jitter is None else jitter[0], u[0],
                float(host.time_step), B @ a, out.T,
            )  # fmt: skip
        _shift_window(u, chosen, u_next)
        np.matmul(self._W_factor, rng.standard_normal(out=work[3][:3]), out=u_next[-1])
        if jitter is not None:
            _shift_window(jitter, chosen, jitter_next)
            self._draw_jitter(root, rng, jitter_next[-1])
        return log_weights


def _shift_window(slots: np.ndarray, chosen: np.ndarray | None, out: np.ndarray) -> None:
    """The window's per-particle slots (D×·×N) moved one step on into ``out[:-1]``, each
    particle's following it through a resampling (``chosen``)."""
    if chosen is None:
        out[:-1] = slots[1:]
    else:
        np.take(slots[1:], chosen, axis=2, out=out[:-1], mode="clip")
