"""The sampled double integrator shared by the vehicle, the target and the relative state."""

import numpy as np


def double_integrator(time_step: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of ``X(k+1) = A X(k) + B a(k)`` for ``X = [p, v]`` in R^6 (paper eq. 1)."""
    t = time_step
    A = np.block([[np.eye(3), t * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    B = np.vstack([0.5 * t * t * np.eye(3), t * np.eye(3)])
    return A, B
