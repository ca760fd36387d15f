"""A minimal batched host for the particle cloud: every value the cloud reads of its host is an
input port, so that one batch can hold runs of every branch (live or not, reweighed or not, one
sonar or two, drawn, weighed draws, navigation noise)."""

from types import SimpleNamespace

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem, State

from drake_uuv.estimators.contract import Estimate
from drake_uuv.estimators.particle_cloud import ParticleCloud
from drake_uuv.models.measurement import VALID
from drake_uuv.models.motion import double_integrator
from drake_uuv.models.particle_filter import ParticleFilterParameters
from drake_uuv.primitives.batch import per_run
from drake_uuv.testing import set_states as set_context_states

T = 0.1
W = np.diag([0.04, 0.04, 0.01])
R = np.diag([0.01, 0.02])
#: Input ports: name → per-run size.
PORTS = {
    "z": 2, "used": 2, "q_s": 3, "offset": 6, "acceleration": 3, "moving": 1, "drawn": 1,
    "weigh_draw": 1, "status": 1, "draw_x": 6, "draw_P": 36, "Q_nav": 36,
}  # fmt: skip


class CloudHost(LeafSystem):
    """Hosts a :class:`ParticleCloud` of ``count`` particles for ``batch_size`` runs.

    Outputs ``x_hat`` (6), ``P_hat`` (36), ``nis`` (1): the cloud's posterior; discrete state
    groups 0 and 1 the prediction the cloud writes; abstract state 0 the cloud's arrays.
    """

    def __init__(
        self,
        count: int = 300,
        *,
        batch_size: int = 1,
        threshold: float = 0.5,
        time_step: float = T,
        acceleration_covariance: np.ndarray = W,
        range_covariance: np.ndarray = R,
        kernel: str = "cartesian",
    ) -> None:
        super().__init__()
        self.batch_size = batch_size
        A, B = double_integrator(time_step)
        self.model = (A, B, np.asarray(acceleration_covariance, dtype=float))
        self.window = None
        self.error_model = SimpleNamespace(active=False, navigated_motion=False)
        self._ports = {
            name: self.DeclareVectorInputPort(name, batch_size * size)
            for name, size in PORTS.items()
        }
        self.vehicle_motion = SimpleNamespace(
            state_ports=[],
            offset=lambda context: self._read(context, "offset"),
            acceleration=lambda context: self._read(context, "acceleration"),
        )
        self._x_index = self.DeclareDiscreteState(np.zeros(6 * batch_size))
        self._P_index = self.DeclareDiscreteState(np.zeros(36 * batch_size))
        parameters = ParticleFilterParameters(
            count=count, resample_threshold=threshold, kernel=kernel
        )
        self.cloud = ParticleCloud(self, parameters, range_covariance, batch_size=batch_size)
        self.DeclareVectorOutputPort("x_hat", 6 * batch_size, self._calc_x)
        self.DeclareVectorOutputPort("P_hat", 36 * batch_size, self._calc_P)
        self.DeclareVectorOutputPort("nis", batch_size, self._calc_nis)
        # The cloud is abstract state: the update is an unrestricted one (forced: by hand).
        self.DeclarePeriodicUnrestrictedUpdateEvent(time_step, 0.0, self._update)
        self.DeclareForcedUnrestrictedUpdateEvent(self._update)

    def _read(self, context: Context, name: str) -> np.ndarray:
        return per_run(self._ports[name].Eval(context), self.batch_size)

    def depends_on_measurement(self) -> set:
        return {port.ticket() for port in self._ports.values()} | {
            self.xd_ticket(),
            self.xa_ticket(),
        }

    def ranges(self, context: Context) -> SimpleNamespace:
        return SimpleNamespace(
            z=self._read(context, "z"), valid=self._read(context, "used") != 0.0,
            q_s=self._read(context, "q_s"), exact=True,
        )  # fmt: skip

    def prior(self, context: Context) -> Estimate:
        return Estimate(np.zeros((self.batch_size, 6)), np.zeros((self.batch_size, 6, 6)))

    def navigation_process_noise(self, context: Context) -> np.ndarray:
        return self._read(context, "Q_nav").reshape(-1, 6, 6)

    def write_prediction(
        self,
        discrete_state: DiscreteValues,
        x: np.ndarray,
        P: np.ndarray,
        runs: np.ndarray | None = None,
    ) -> None:
        """As the estimators' base: every run's, or the rows of the mask ``runs`` only."""
        B = self.batch_size
        runs = np.ones(B, dtype=bool) if runs is None else runs
        x_state = per_run(discrete_state.get_mutable_value(self._x_index), B)
        P_state = per_run(discrete_state.get_mutable_value(self._P_index), B, 6, 6)
        x_state[runs] = np.reshape(x, (B, 6))[runs]
        P_state[runs] = np.reshape(P, (B, 6, 6))[runs]

    def _update(self, context: Context, state: State) -> None:
        draw = (self._read(context, "draw_x"), self._read(context, "draw_P").reshape(-1, 6, 6))
        filtered = SimpleNamespace(status=self._read(context, "status")[:, 0])
        self.cloud.advance(
            context, filtered, state, draw, self._read(context, "weigh_draw")[:, 0] != 0,
            drawn=self._read(context, "drawn")[:, 0] != 0,
            runs=self._read(context, "moving")[:, 0] != 0,
        )  # fmt: skip

    def _calc_x(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.cloud.posterior(context)[0].ravel())

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.cloud.posterior(context)[1].ravel())

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.cloud.posterior(context)[2])


def run_inputs(B: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Inputs of B runs about ``x = [-2, -2, 0.3, 0, 0, 0]``, every run live, reweighed by
    both sonars (``(B, n)`` arrays, run i's in row i); the caller varies the branches."""
    rng = np.random.default_rng(seed)
    x = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
    q_s = np.array([-0.6, 1.1, 0.5]) + 0.1 * rng.standard_normal((B, 3))
    d = np.stack(
        [np.linalg.norm(x[:3] + 0.5 * q_s, axis=1), np.linalg.norm(x[:3] - 0.5 * q_s, axis=1)],
        axis=1,
    )
    P = np.diag([0.3, 0.2, 0.25, 0.1, 0.1, 0.1])
    return dict(
        z=d + 0.1 * rng.standard_normal((B, 2)), used=np.ones((B, 2)), q_s=q_s,
        offset=np.zeros((B, 6)), acceleration=rng.standard_normal((B, 3)),
        moving=np.ones((B, 1)), drawn=np.zeros((B, 1)), weigh_draw=np.zeros((B, 1)),
        status=np.full((B, 1), float(VALID)), draw_x=np.tile(x, (B, 1)),
        draw_P=np.tile(P.ravel(), (B, 1)), Q_nav=np.zeros((B, 36)),
        particle_seed=rng.random((B, 1)),
    )  # fmt: skip


#: The cloud's arrays, after the host's two discrete groups, in a run's state list.
CLOUD_ARRAYS = ("particles", "log_weights", "live")


def state_parts(system: "CloudHost", states: list[np.ndarray]) -> tuple[list, dict]:
    """A state list ``[x, P, particles, log_weights, live]`` (each ``(B, ·)``) as the host's
    discrete groups and its cloud's arrays (``assert_batch_equals_runs``' ``states`` and
    ``arrays``)."""
    named = dict(zip(CLOUD_ARRAYS, states[2:], strict=True))
    return list(states[:2]), {system.cloud.state_index: named}


def set_states(system: "CloudHost", context: Context, states: list[np.ndarray]) -> None:
    """Sets a state list (see :func:`state_parts`) in ``context``."""
    set_context_states(context, *state_parts(system, states))


def read_states(system: "CloudHost", context: Context) -> list[np.ndarray]:
    """The state list of ``context`` (see :func:`state_parts`), each ``(B, ·)``."""
    B = system.batch_size
    groups = [context.get_discrete_state(g).CopyToVector().reshape(B, -1) for g in (0, 1)]
    arrays = system.cloud.arrays(context)
    return groups + [getattr(arrays, name).reshape(B, -1).copy() for name in CLOUD_ARRAYS]


def run_states(B: int, count: int, seed: int = 1, spread: float = 0.5) -> list[np.ndarray]:
    """States of B live runs (see :func:`state_parts`): clouds about ``x`` with unequal log
    weights."""
    rng = np.random.default_rng(seed)
    x = np.array([-2.0, -2.0, 0.3, 0.0, 0.0, 0.0])
    particles = x + spread * rng.standard_normal((B, count, 6))
    log_weights = -np.log(rng.uniform(1.0, 2.0, (B, count)))
    return [
        np.zeros((B, 6)), np.zeros((B, 36)), particles.reshape(B, -1), log_weights,
        np.ones((B, 1)),
    ]  # fmt: skip


def reference_step(
    particles: np.ndarray,
    log_weights: np.ndarray,
    seed_value: float,
    parameters: ParticleFilterParameters,
    a_W: np.ndarray,
    *,
    model: tuple[np.ndarray, np.ndarray, np.ndarray],
    draw: tuple[np.ndarray, np.ndarray] | None = None,
    offset: np.ndarray | None = None,
    jitter: np.ndarray | None = None,
    weigh=None,
) -> tuple[np.ndarray, np.ndarray]:
    """One run's periodic update in numpy (:mod:`drake_uuv.models.particle_filter`'s steps)
    from the draws the kernel takes for ``seed_value``: the particles (N×6, stored frame) and
    log weights it should give, to rounding. ``draw``: the cloud is drawn from ``N(draw)``
    (relative, less ``offset``) first, and weighed by ``weigh`` (the drawn particles' log
    weights) when given; ``jitter``: a factor of the navigation's noise."""
    from drake_uuv.models import particle_random as kernels
    from drake_uuv.models.particle_filter import (
        effective_sample_size,
        normalised,
        systematic_resample,
        weighted_moments,
    )
    from drake_uuv.models.range_bearing import (
        from_range_bearing,
        range_bearing_frame,
        to_range_bearing,
    )

    A, B, W = model
    n = parameters.count
    keys = kernels.cloud_keys(np.array([seed_value]))

    def normals(slot: int, size: int) -> np.ndarray:
        return kernels.standard_normals(keys, n, slot, size)[0]

    if draw is not None:
        L = np.linalg.cholesky(draw[1])
        particles = draw[0] + normals(kernels.DRAW_SLOT, 6) @ L.T
        particles -= 0.0 if offset is None else offset
        log_weights = np.full(n, -np.log(n)) if weigh is None else weigh(particles)
    weights = normalised(log_weights)
    if effective_sample_size(weights) < parameters.resample_threshold * n:
        h = parameters.bandwidth
        frame = None
        if h > 0.0 and parameters.kernel == "range_bearing":
            frame = range_bearing_frame(particles.T, weights, offset)
        # The kernel's coordinates: range-bearing about the frame, or the stored ones.
        local = particles if frame is None else to_range_bearing(particles.T, frame, offset).T
        mean, cov = weighted_moments(local.T, weights)
        chosen = systematic_resample(weights, kernels.resampling_uniforms(keys, n)[0])
        a = np.sqrt(1.0 - h * h)
        particles = a * local[chosen] + (1.0 - a) * mean
        if h > 0.0:
            particles += h * normals(kernels.KERNEL_SLOT, 6) @ np.linalg.cholesky(cov).T
        if frame is not None:
            particles = from_range_bearing(particles.T, frame, offset).T
        log_weights = np.full(n, -np.log(n))
    noise = normals(kernels.ACCELERATION_SLOT, 3) @ np.linalg.cholesky(W).T
    moved = particles @ A.T + B @ a_W - noise @ B.T
    if jitter is not None:
        moved += normals(kernels.JITTER_SLOT, 6) @ jitter.T
    return moved, log_weights
