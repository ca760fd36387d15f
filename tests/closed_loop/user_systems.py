"""Systems a user writes for the loop: an estimator and a tracking law of a few lines each."""

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem


class ConstantEstimator(LeafSystem):
    """Publishes a constant estimate ``x`` with covariance ``P``: the estimator slot's
    outputs and nothing else (no input; it never looks at the sonar)."""

    def __init__(self, x: np.ndarray, P: np.ndarray) -> None:
        super().__init__()
        self.x, self.P = np.asarray(x, dtype=float), np.asarray(P, dtype=float)
        for name in ("x_TU_hat", "x_TU_prior"):
            self.DeclareVectorOutputPort(name, 6, self._calc_x)
        for name in ("P_TU", "P_TU_prior"):
            self.DeclareVectorOutputPort(name, 36, self._calc_P)
        self.DeclareVectorOutputPort("measurement_status", 1, self._calc_status)
        self.DeclareVectorOutputPort("nis", 1, self._calc_nis)

    def estimate(self, context: Context) -> tuple[np.ndarray, np.ndarray, float]:
        """``(x, P, nis)`` published at the context's time (NaN: no update)."""
        return self.x, self.P, math.nan

    def _calc_x(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.estimate(context)[0])

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.estimate(context)[1].ravel())

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, 0.0)

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self.estimate(context)[2])


class ProportionalTracking(LeafSystem):
    """``u1_W = −k (q̂ − q*)`` with q* in the world, and no ``gain`` property."""

    def __init__(self, k: float, q_star: np.ndarray) -> None:
        super().__init__()
        self._k, self._q_star = k, np.asarray(q_star, dtype=float)
        self._x_hat = self.DeclareVectorInputPort("x_TU_hat", 6)
        self._R_WB = self.DeclareVectorInputPort("R_WB_nav", 9)
        self.DeclareVectorOutputPort("u1_W", 3, self._calc_u1_W)
        self.DeclareVectorOutputPort("u1_B", 3, self._calc_u1_B)

    def _u1_W(self, context: Context) -> np.ndarray:
        return -self._k * (self._x_hat.Eval(context)[:3] - self._q_star)

    def _calc_u1_W(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._u1_W(context))

    def _calc_u1_B(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._R_WB.Eval(context).reshape(3, 3).T @ self._u1_W(context))
