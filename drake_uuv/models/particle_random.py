"""Counter-based random draws for the particle kernels: a run's draws of a step are a pure
function of its key and each draw's counter, so they need no state and do not depend on the
batch.

Randomness, counter-based: run i's draws of a step are a pure function of a 64-bit key (from
the run's uniform of the step, :func:`cloud_keys`) and a counter. Particle j's draws use their
own counters (:data:`SLOTS` slots of 64 counters each: a draw of the initial cloud, the
regularisation, the target's acceleration, the navigation's noise), so every draw is the same
whatever the particle count of the other runs, whether the step resampled or not, and whatever
order the loop takes. The generator is SplitMix64 (as :mod:`drake_uuv.primitives.run_noise`),
the normals Marsaglia and Tsang's ziggurat with 256 layers (Marsaglia & Tsang 2000, "The
ziggurat method for generating random variables"; the tables as numpy's legacy generator
builds them): one 64-bit output gives a normal 99 % of the time, about 2 ns here, where the
Box–Muller transform took 15-35 ns and numpy's generator 10-20 ns (the draws were half of a
step's cost).

numba's cache checks a compiled function's own file only: the kernels of
:mod:`~drake_uuv.models.particle_kernels` and :mod:`~drake_uuv.models.particle_advance` keep
their compiled draws after an edit here until their caches (``__pycache__/particle_*.nbi``,
``.nbc``) are removed.
"""

import hashlib
import math

import numpy as np
from numba import njit

#: Per particle, this many draw slots; slot ``s`` of particle ``j`` starts at counter
#: ``(j · SLOTS + s) · 64`` (a normal takes one counter, a few more on the 1 % rejected).
SLOTS = 32
#: The slots: the initial draw (6), the regularisation kernel (6), the target's acceleration
#: (3), the navigation's process noise (6).
DRAW_SLOT, KERNEL_SLOT, ACCELERATION_SLOT, JITTER_SLOT = 0, 6, 12, 15
_SLOT_SHIFT = np.uint64(6)
_GAMMA = np.uint64(0x9E3779B97F4A7C15)
#: The key's source (BLAKE2b of its name, as RunNoise's sources): a cloud's stream differs
#: from any RunNoise source's.
CLOUD_SOURCE = np.uint64(
    int.from_bytes(hashlib.blake2b(b"particle cloud", digest_size=8).digest(), "little")
)


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marsaglia and Tsang's tables for 256 layers and 52-bit uniforms (numpy's legacy)."""
    m1 = 2.0**52
    dn = tn = 3.6541528853610088
    vn = 0.00492867323399
    ki = np.zeros(256, np.uint64)
    wi = np.zeros(256)
    fi = np.zeros(256)
    q = vn / math.exp(-0.5 * dn * dn)
    ki[0] = np.uint64((dn / q) * m1)
    wi[0], wi[255] = q / m1, dn / m1
    fi[0], fi[255] = 1.0, math.exp(-0.5 * dn * dn)
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(vn / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = np.uint64((dn / tn) * m1)
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / m1
    return ki, wi, fi


_KI, _WI, _FI = _ziggurat_tables()
_TAIL = 3.6541528853610088


@njit
def _mix(z: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit
def _raw(key: np.uint64, counter: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    return _mix(key + (counter + np.uint64(1)) * _GAMMA)


@njit
def uniform(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """In [0, 1) on a 2⁻⁵³ grid."""
    return float(_raw(key, counter) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit
def normal_loop(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """A standard normal from the counters ``counter, counter + 1, …`` (the whole ziggurat)."""
    while True:
        r = _raw(key, counter)
        counter += np.uint64(1)
        layer = r & np.uint64(0xFF)
        r >>= np.uint64(8)
        negative = (r & np.uint64(1)) != np.uint64(0)
        rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
        x = float(rabs) * _WI[layer]
        if negative:
            x = -x
        if rabs < _KI[layer]:
            return x
        if layer == 0:  # the tail beyond the base strip
            while True:
                xx = -(1.0 / _TAIL) * math.log1p(-uniform(key, counter))
                yy = -math.log1p(-uniform(key, counter + np.uint64(1)))
                counter += np.uint64(2)
                if yy + yy > xx * xx:
                    return -(_TAIL + xx) if negative else _TAIL + xx
        elif (_FI[layer - 1] - _FI[layer]) * uniform(key, counter) + _FI[layer] < math.exp(
            -0.5 * x * x
        ):
            return x
        counter += np.uint64(1)


@njit
def normal(key: np.uint64, counter: np.uint64) -> float:  # pragma: no cover - compiled
    """A standard normal from the counters ``counter, counter + 1, …``: the ziggurat's first
    try (accepted 99 % of the time; small, so LLVM inlines it where it is called: numba's own
    inlining tripled the kernels' first compilation), the rest in :func:`normal_loop` (which
    takes the same first try again, so the value does not depend on where it was computed)."""
    r = _raw(key, counter) >> np.uint64(8)
    layer = _raw(key, counter) & np.uint64(0xFF)
    rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
    if rabs < _KI[layer]:
        x = float(rabs) * _WI[layer]
        return -x if (r & np.uint64(1)) != np.uint64(0) else x
    return normal_loop(key, counter)


@njit
def slot_counter(particle: int, slot: int) -> np.uint64:  # pragma: no cover - compiled
    return np.uint64(particle * SLOTS + slot) << _SLOT_SHIFT


@njit(cache=True)
def cloud_keys(uniforms: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Each run's key of a step from its uniform draw ``u`` in [0, 1) (53 bits)."""
    keys = np.empty(uniforms.shape[0], dtype=np.uint64)
    for b in range(uniforms.shape[0]):
        u = uniforms[b]
        seed = np.uint64(u * 9007199254740992.0) if 0.0 <= u < 1.0 else np.uint64(0)
        keys[b] = _mix(_mix(seed) ^ CLOUD_SOURCE)
    return keys


@njit(cache=True)
def standard_normals(
    keys: np.ndarray, count: int, slot: int, size: int
) -> np.ndarray:  # pragma: no cover - compiled
    """The normals of slots ``slot … slot + size − 1`` of particles ``0 … count − 1`` of each
    key: ``(B, count, size)`` (for tests: the draws the steps use)."""
    out = np.empty((keys.shape[0], count, size))
    for b in range(keys.shape[0]):
        for j in range(count):
            for k in range(size):
                out[b, j, k] = normal(keys[b], slot_counter(j, slot + k))
    return out


@njit(cache=True)
def resampling_uniforms(keys: np.ndarray, count: int) -> np.ndarray:  # pragma: no cover
    """Each key's offset of systematic resampling for a cloud of ``count`` particles (for
    tests: the offset the steps use)."""
    out = np.empty(keys.shape[0])
    for b in range(keys.shape[0]):
        out[b] = uniform(keys[b], resampling_counter(count))
    return out


@njit
def resampling_counter(count: int) -> np.uint64:  # pragma: no cover - compiled
    """The counter of the resampling's offset: the first after every particle's slots."""
    return np.uint64(count * SLOTS) << _SLOT_SHIFT
