"""The paper's linear Kalman filter on the squared-range difference, eq. (9)."""

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    Context,
    DiscreteValues,
    LeafSystem,
    ValueProducer,
)

from drake_uuv.plants.double_integrator import double_integrator

_I6 = np.eye(6)


def kf_predict(
    x: np.ndarray, P: np.ndarray, a_W: np.ndarray, A: np.ndarray, B: np.ndarray, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``Υ̂(k+1|k) = A Υ̂(k) + B a_W(k)``, ``P(k+1|k) = A P Aᵀ + Q`` with ``Q = B W Bᵀ``."""
    return A @ x + B @ a_W, A @ P @ A.T + Q


def range_difference_update(
    x_pred: np.ndarray, P_pred: np.ndarray, Y: float, m: float, Gamma: float, q_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The scalar measurement update of ``Y = q_sᵀ q + v̄``, ``E v̄ = m``, ``Var v̄ = Γ``.

    ``C = [q_sᵀ, 0]``; ``K = P Cᵀ (C P Cᵀ + Γ)⁻¹``; ``Υ̂ = Υ̂⁻ + K (Y − C Υ̂⁻ − m)``; the
    covariance in Joseph form ``(I − KC) P (I − KC)ᵀ + K Γ Kᵀ``, which stays symmetric positive
    definite under rounding.
    """
    PCt = P_pred[:, :3] @ q_s
    S = float(q_s @ PCt[:3]) + Gamma
    K = PCt / S
    innovation = Y - float(q_s @ x_pred[:3]) - m
    I_KC = _I6.copy()
    I_KC[:, :3] -= np.outer(K, q_s)
    P = I_KC @ P_pred @ I_KC.T + Gamma * np.outer(K, K)
    return x_pred + K * innovation, P


@dataclass
class FilteredEstimate:
    """``Υ̂(k|k)`` and ``P(k|k)``."""

    x: np.ndarray
    P: np.ndarray


class RangeDifferenceKalmanFilter(LeafSystem):
    """The paper's KF (eq. 9) on ``Y = ½(d1² − d2²)``, with the covariance in Joseph form.

    Discrete state: the *predicted* ``Υ̂(k|k−1)`` and ``P(k|k−1)``. The filtered estimate at
    step k is a direct-feedthrough output of the measurement inputs (not of ``a_W``), so the
    controller acts on ``Υ̂(k|k)`` in the same tick, as in the paper; the periodic update then
    predicts ``Υ̂(k+1|k)`` with the applied acceleration.

    .. pydrake_system::

        name: RangeDifferenceKalmanFilter
        input_ports:
        - Y
        - m
        - Gamma
        - q_s
        - a_W
        output_ports:
        - x_hat
        - P

    - ``Y``, ``m``, ``Gamma`` (1 each): measurement, noise mean, noise variance.
    - ``q_s`` (3): world sonar baseline, ``C = [q_sᵀ, 0]``.
    - ``a_W`` (3): the vehicle's applied world acceleration ``R u1`` at step k.
    - ``x_hat`` (6): filtered ``Υ̂(k|k) = [q̂, ϑ̂]``.
    - ``P`` (36): filtered covariance ``P(k|k)``, row-major.
    """

    def __init__(
        self,
        time_step: float,
        acceleration_covariance: np.ndarray,
        initial_estimate: np.ndarray,
        initial_covariance: np.ndarray,
    ) -> None:
        super().__init__()
        self._A, self._B = double_integrator(time_step)
        self._Q = self._B @ np.asarray(acceleration_covariance, dtype=float) @ self._B.T
        self._Y_port = self.DeclareVectorInputPort("Y", 1)
        self._m_port = self.DeclareVectorInputPort("m", 1)
        self._Gamma_port = self.DeclareVectorInputPort("Gamma", 1)
        self._q_s_port = self.DeclareVectorInputPort("q_s", 3)
        self._a_port = self.DeclareVectorInputPort("a_W", 3)
        # Predicted state Υ̂(k|k−1) (6) followed by P(k|k−1) row-major (36).
        self._state_index = self.DeclareDiscreteState(
            np.concatenate([initial_estimate, np.asarray(initial_covariance, dtype=float).ravel()])
        )
        measurement_tickets = {
            port.ticket() for port in (self._Y_port, self._m_port, self._Gamma_port, self._q_s_port)
        }
        self._filtered = self.DeclareCacheEntry(
            "filtered estimate",
            ValueProducer(
                allocate=AbstractValue.Make(FilteredEstimate(np.zeros(6), np.eye(6))).Clone,
                calc=self._calc_filtered,
            ),
            measurement_tickets | {self.xd_ticket()},
        )
        depends = {self._filtered.ticket()}
        self.DeclareVectorOutputPort("x_hat", 6, self._calc_x_hat, depends)
        self.DeclareVectorOutputPort("P", 36, self._calc_P, depends)
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._predict)

    def _calc_filtered(self, context: Context, value: AbstractValue) -> None:
        predicted = context.get_discrete_state(self._state_index).get_value()
        x, P = range_difference_update(
            predicted[:6],
            predicted[6:].reshape(6, 6),
            self._Y_port.Eval(context)[0],
            self._m_port.Eval(context)[0],
            self._Gamma_port.Eval(context)[0],
            self._q_s_port.Eval(context),
        )
        value.set_value(FilteredEstimate(x, P))

    def _predict(self, context: Context, discrete_state: DiscreteValues) -> None:
        filtered: FilteredEstimate = self._filtered.Eval(context)
        x, P = kf_predict(
            filtered.x, filtered.P, self._a_port.Eval(context), self._A, self._B, self._Q
        )
        next_state = np.empty(42)
        next_state[:6] = x
        next_state[6:] = P.ravel()
        discrete_state.set_value(self._state_index, next_state)

    def _calc_x_hat(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).x)

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).P.ravel())
