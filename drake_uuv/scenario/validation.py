"""Checks shared by every configuration dataclass; each raises a one-line ScenarioError.

A message always names the dotted field and the value, e.g. ``sonar.noise_variances: must be
> 0 (at least 1e-12 m²), got [-0.01, 0.01]``.
"""

import math
from typing import Any, NoReturn

import numpy as np

# Largest magnitude of any number in a scenario: far beyond any physical value in SI units,
# far below where squares and products in the filter overflow.
LIMIT = 1e6


class ScenarioError(ValueError):
    """A scenario field has a bad value; the message names the field and the value.

    The message is always one line: control characters from user input are escaped.
    """

    def __init__(self, message: str) -> None:
        super().__init__("".join(c if c.isprintable() else repr(c)[1:-1] for c in message))


def fail(name: str, requirement: str, value: Any) -> NoReturn:
    """Raises ``ScenarioError("<name>: <requirement>, got <value>")``."""
    raise ScenarioError(f"{name}: {requirement}, got {value!r}")


def check_finite(name: str, array: np.ndarray, value: Any) -> None:
    """Every entry finite and at most :data:`LIMIT` in magnitude."""
    if not np.all(np.isfinite(array)):
        fail(name, "must be finite", value)
    if np.any(np.abs(array) > LIMIT):
        fail(name, f"must be at most {LIMIT:g} in magnitude", value)


def check_vector(name: str, value: list[float], size: int) -> np.ndarray:
    """A list of ``size`` finite numbers, as an array."""
    array = np.asarray(value, dtype=float)
    if array.shape != (size,):
        fail(name, f"must be a list of {size} numbers", value)
    check_finite(name, array, value)
    return array


def check_matrix(name: str, value: list[list[float]], size: int) -> np.ndarray:
    """A ``size``×``size`` matrix of finite numbers, as an array."""
    if not all(isinstance(row, list) and len(row) == size for row in value) or len(value) != size:
        fail(name, f"must be a {size}×{size} matrix (list of {size} lists of {size})", value)
    array = np.asarray(value, dtype=float)
    check_finite(name, array, value)
    return array


def check_positive(name: str, value: float, strict: bool = True) -> None:
    """``value > 0`` (or ``≥ 0`` with ``strict=False``), finite and within :data:`LIMIT`."""
    if not math.isfinite(value) or (value <= 0.0 if strict else value < 0.0):
        fail(name, "must be > 0" if strict else "must be ≥ 0", value)
    check_finite(name, np.asarray(value), value)


def check_between(name: str, value: float, low: float, high: float) -> None:
    """``low ≤ value ≤ high``."""
    if not (math.isfinite(value) and low <= value <= high):
        fail(name, f"must be in [{low:g}, {high:g}]", value)


def check_spd(name: str, value: list[list[float]], size: int) -> np.ndarray:
    """A symmetric positive-definite ``size``×``size`` matrix, as an array."""
    array = check_matrix(name, value, size)
    if not np.allclose(array, array.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(array).max())):
        fail(name, "must be symmetric", value)
    if np.linalg.eigvalsh(array).min() <= 0.0:
        fail(name, "must be positive definite", value)
    return array


def check_choice(name: str, value: str, options: tuple[str, ...]) -> None:
    """One of ``options``."""
    if value not in options:
        fail(name, f"must be one of {', '.join(options)}", value)


def check_probability(name: str, value: float | None, upper_inclusive: bool = False) -> None:
    """None, or a probability in (0, 1) (or (0, 1] with ``upper_inclusive``)."""
    if value is None:
        return
    inside = 0.0 < value <= 1.0 if upper_inclusive else 0.0 < value < 1.0
    if not (math.isfinite(value) and inside):
        fail(name, "must be in (0, 1]" if upper_inclusive else "must be in (0, 1)", value)
