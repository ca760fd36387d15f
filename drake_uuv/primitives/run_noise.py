"""Per-run random numbers for a batch: run i's draw is a function of its seed, source and step.

Why not Drake's ``RandomSource``: it draws one stream for its whole output vector, so with B
runs in one vector, run i's noise would depend on B and on the run's place in the batch, and a
run could not be repeated alone. Why not one numpy ``Generator`` per run and source: drawing
would be state that a calc must not change (Drake caches outputs), so each refill would have to
be an update event on a copied abstract state; a counter-based generator has no state at all.

The generator: Philox4x32-10 (Salmon, Moraes, Dror and Shaw, "Parallel random numbers: as easy
as 1, 2, 3", SC 2011; the counter-based generator of Random123, cuRAND and JAX), keyed by a hash
of the run's seed and the source's name, its counter the step and the value's index. Value j of
step k is one Philox block of counter (j, k, 0, 0): no state, nothing to refill, the same
numbers whether the run goes alone or in any batch, in any process. Philox4x32-10 passes
BigCrush for any key and counter pattern (its authors' tests); the implementation here
reproduces Random123's known-answer vectors (``tests/primitives/test_run_noise.py``). Two
uniforms of 53 bits come from a block's four words; normals from the Box–Muller transform of
the two, uniforms and exponentials (mean 1, by inversion) from the first.

(A SplitMix64 stream per run, ``mix(key + n·γ)``, was tried first: its draws passed every
moment and correlation test here, yet over 3000 runs of the paper's loop 74 runs left their
NEES band and the runs' mean NEES spread with a standard deviation of 0.771, against 44 and
0.742 with numpy's PCG64 streams; with Philox, 49 and 0.747.)

The kernel is compiled with numba (``cache=True`` keeps the machine code between processes):
a source of a single run costs about a microsecond a step, where a dozen numpy calls on
three-element arrays would cost more than the rest of the loop's noise handling.
"""

import hashlib
import math

import numpy as np
from numba import njit
from pydrake.common import RandomDistribution
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.primitives.setting import time_step_field

#: The distributions a random input port may have, by Drake's enum: the kernel's codes.
DISTRIBUTION_CODES = {
    RandomDistribution.kGaussian: 0,
    RandomDistribution.kUniform: 1,
    RandomDistribution.kExponential: 2,
}


@njit(cache=True)
def _mix(z: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    """SplitMix64's output function (the finaliser of MurmurHash3 with Stafford's constants)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


_MASK32 = np.uint64(0xFFFFFFFF)
# Philox4x32's multipliers and Weyl key increments (Random123).
_M0, _M1 = np.uint64(0xD2511F53), np.uint64(0xCD9E8D57)
_W0, _W1 = np.uint64(0x9E3779B9), np.uint64(0xBB67AE85)


@njit(cache=True)
def philox4x32(
    c0: np.uint64, c1: np.uint64, c2: np.uint64, c3: np.uint64, k0: np.uint64, k1: np.uint64
) -> tuple:  # pragma: no cover - compiled
    """Philox4x32-10 of the counter ``(c0, c1, c2, c3)`` and key ``(k0, k1)`` (32-bit words
    held in uint64): four 32-bit words."""
    for r in range(10):
        if r > 0:
            k0 = (k0 + _W0) & _MASK32
            k1 = (k1 + _W1) & _MASK32
        p0 = _M0 * c0
        p1 = _M1 * c2
        c0, c1, c2, c3 = (
            ((p1 >> np.uint64(32)) ^ c1 ^ k0) & _MASK32,
            p1 & _MASK32,
            ((p0 >> np.uint64(32)) ^ c3 ^ k1) & _MASK32,
            p0 & _MASK32,
        )
    return c0, c1, c2, c3


@njit(cache=True)
def run_keys(seeds: np.ndarray, source: np.uint64) -> np.ndarray:  # pragma: no cover - compiled
    """Each run's 64-bit key for one source: ``mix(mix(seed) ^ source)`` (SplitMix64's
    finaliser as a hash; Philox takes its two 32-bit halves)."""
    keys = np.empty(seeds.shape[0], dtype=np.uint64)
    for i in range(seeds.shape[0]):
        keys[i] = _mix(_mix(np.uint64(seeds[i])) ^ source)
    return keys


@njit(cache=True)
def draw_step(
    keys: np.ndarray, step: int, size: int, distribution: int
) -> np.ndarray:  # pragma: no cover - compiled
    """The draws of ``step`` for each run: a ``(B, size)`` array; value j from the Philox
    block of counter ``(j, step, 0, 0)`` under the run's key."""
    out = np.empty((keys.shape[0], size))
    two_pi = 2.0 * math.pi
    scale = 1.0 / 9007199254740992.0  # 2^-53
    k = np.uint64(step)
    for i in range(keys.shape[0]):
        k0 = keys[i] & _MASK32
        k1 = keys[i] >> np.uint64(32)
        for j in range(size):
            w0, w1, w2, w3 = philox4x32(
                np.uint64(j), k & _MASK32, k >> np.uint64(32), np.uint64(0), k0, k1
            )
            u1 = float(((w0 << np.uint64(32)) | w1) >> np.uint64(11)) * scale
            if distribution == 1:
                out[i, j] = u1
            elif distribution == 2:
                out[i, j] = -math.log1p(-u1)
            else:
                u2 = float(((w2 << np.uint64(32)) | w3) >> np.uint64(11)) * scale
                out[i, j] = math.sqrt(-2.0 * math.log1p(-u1)) * math.cos(two_pi * u2)
    return out


def source_id(name: str) -> np.uint64:
    """A source's 64-bit identity: the first 8 bytes of BLAKE2b of its name."""
    return np.uint64(
        int.from_bytes(hashlib.blake2b(name.encode(), digest_size=8).digest(), "little")
    )


def run_draws(
    seeds: np.ndarray | list[int],
    name: str,
    step: int,
    size: int,
    distribution: RandomDistribution = RandomDistribution.kGaussian,
) -> np.ndarray:
    """What :class:`RunNoise` named ``name`` outputs at ``step`` for runs of these seeds,
    ``(len(seeds), size)`` (for tests and for code that needs a run's draws outside a diagram)."""
    keys = run_keys(np.asarray(seeds, dtype=np.int64), source_id(name))
    return draw_step(keys, int(step), int(size), DISTRIBUTION_CODES[distribution])


#: The largest seed: seeds are exact integers in a double (the numeric parameter).
MAX_SEED = 2**53


class RunNoise(LeafSystem):
    """The random numbers of one source for a batch of runs, each run from its own seed.

    .. pydrake_system::

        name: RunNoise
        output_ports:
        - draw

    - ``draw`` (B·n): run i's n values of this step, ``[i·n, (i + 1)·n)``, of ``distribution``
      (standard normal, uniform on [0, 1), or exponential of mean 1). The step is
      ``k = ⌊t / time_step⌋``: the value is the same at a tick's publish and at its updates, and
      held between ticks (a continuous plant's integrator steps in between).
    - Numeric parameter 0: the B runs' seeds (:meth:`set_seeds`; default ``0, …, B − 1``).

    The draw of run i at step k is a pure function of (``seeds[i]``, ``name``, k)
    (:func:`run_draws`): the same alone or in any batch, and no other source's (names are
    unique in a diagram) or run's.
    """

    def __init__(
        self,
        name: str,
        distribution: RandomDistribution,
        size: int,
        *,
        batch_size: int = 1,
        time_step: float,
    ) -> None:
        super().__init__()
        if distribution not in DISTRIBUTION_CODES:
            raise ValueError(
                f"distribution: must be Gaussian, uniform or exponential, got {distribution!r}"
            )
        self.batch_size = batch_size_field(batch_size)
        self._name = str(name)
        self._source = source_id(self._name)
        self._code = DISTRIBUTION_CODES[distribution]
        self._size = int(size)
        self._time_step = time_step_field(time_step)
        self._seeds_index = self.DeclareNumericParameter(
            BasicVector(np.arange(self.batch_size, dtype=float))
        )
        self.DeclareVectorOutputPort(
            "draw",
            self.batch_size * self._size,
            self._calc_draw,
            {self.time_ticket(), self.all_parameters_ticket()},
        )

    @property
    def source_name(self) -> str:
        return self._name

    def set_seeds(self, context: Context, seeds: np.ndarray | list[int]) -> None:
        """Sets the B runs' seeds (integers in [0, 2^53)) in this system's ``context``."""
        seeds = np.asarray(seeds)
        if seeds.shape != (self.batch_size,) or not np.all(np.isfinite(seeds)):
            raise ValueError(
                f"seeds: must be {self.batch_size} integers (one per run), got {seeds.tolist()!r}"
            )
        if np.any(seeds != np.round(seeds)) or np.any(seeds < 0) or np.any(seeds >= MAX_SEED):
            raise ValueError(f"seeds: must be integers in [0, 2^53), got {seeds.tolist()!r}")
        context.get_mutable_numeric_parameter(self._seeds_index).SetFromVector(seeds.astype(float))

    def seeds(self, context: Context) -> np.ndarray:
        """The B runs' seeds in ``context``."""
        return context.get_numeric_parameter(self._seeds_index).get_value().astype(np.int64)

    def _calc_draw(self, context: Context, output: BasicVector) -> None:
        step = math.floor(context.get_time() / self._time_step + 1e-6)
        keys = run_keys(self.seeds(context), self._source)
        output.set_value(draw_step(keys, step, self._size, self._code).ravel())
