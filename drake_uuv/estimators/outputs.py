"""The base estimator's output ports, published when it holds abstract state, so that an
unrestricted update leaves the loop's timing as a discrete update has it.

A base of :class:`~drake_uuv.estimators.base.RelativeStateEstimator` (the ports are listed
there). An estimator that holds
abstract state (a raw-range filter's particle cloud,
:class:`~drake_uuv.primitives.run_arrays.RunArrays`, shared rather than copied while it does
not change) must update it without restriction: a discrete update cannot write an abstract
state. Drake's Simulator applies every unrestricted update of a tick before it computes the
discrete ones, so the other systems' updates at that tick would read this estimator's *next*
state through its outputs. The outputs are published instead: the update keeps, with the
time, what every output showed before it, and an output asked at that same time (by the
other systems' updates) shows that; asked at any other time (the loggers at the next tick,
before its updates; a test) it is computed from the state as always. The loop's numbers are a
discrete update's, bit for bit.

What it reads of the estimator: ``batch_size``, ``_time_step``, ``_filtered``, ``_window``,
``_x_index``, ``_P_index``, ``vehicle_motion``, :meth:`advance_state`, :meth:`prior`,
:meth:`_record_window` and, with late ranges, ``_stepped_before``.
"""

import math
from collections.abc import Callable

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, OutputPort, State

from drake_uuv.primitives.run_arrays import SharedValue


class Shown(SharedValue):
    """What the published outputs showed before the update at ``time`` (NaN: none yet), in
    their order of declaration. Never written in place: Drake's copies share it."""

    __slots__ = ("time", "values")

    def __init__(self, time: float = math.nan, values: list[np.ndarray] | None = None) -> None:
        self.time, self.values = time, values or []


class EstimatorOutputs:
    """The output ports of an estimator and, with abstract state, its unrestricted update
    (see the module notes); without abstract state its outputs are plain ones and its update
    the discrete one."""

    def _declare_outputs(self) -> None:
        """The output ports (see the class notes), of the filtered estimate's cache entry."""
        depends = {self._filtered.ticket()}
        self.declare_output("x_TU_hat", 6, self._calc_x_hat, depends)
        self.declare_output("P_TU", 36, self._calc_P, depends)
        if self._window is not None:  # the belief stepped through the window's earlier ranges
            before = {self._stepped_before.ticket()}
            self.declare_output("x_TU_prior", 6, self._calc_prior_before, before)
            self.declare_output("P_TU_prior", 36, self._calc_P_prior_before, before)
        elif self.vehicle_motion.state_ports:
            prior_tickets = {
                self.xd_ticket(),
                *(p.ticket() for p in self.vehicle_motion.state_ports),
            }
            self.declare_output("x_TU_prior", 6, self._calc_prior, prior_tickets)
            self.declare_state_output("P_TU_prior", self._P_index, 36)
        else:
            self.declare_state_output("x_TU_prior", self._x_index, 6)
            self.declare_state_output("P_TU_prior", self._P_index, 36)
        self.declare_output("measurement_status", 1, self._calc_status, depends)
        self.declare_output("nis", 1, self._calc_nis, depends)

    def _declare_published(self, abstract_state: bool) -> None:
        """Whether the estimator holds abstract state; if so, the abstract state that keeps
        what the outputs showed before this tick's update (:class:`Shown`)."""
        self._abstract = bool(abstract_state)
        self._published_ports: list[OutputPort] = []
        if self._abstract:
            self._published_index = self.DeclareAbstractState(AbstractValue.Make(Shown()))

    def _declare_update(self, discrete_update: Callable) -> None:
        """The periodic update: ``discrete_update`` or, with abstract state, the unrestricted
        one (and the same update forced, without publishing, for a caller stepping the
        estimator by hand: its outputs then read the next step's state)."""
        if not self._abstract:
            self.DeclarePeriodicDiscreteUpdateEvent(self._time_step, 0.0, discrete_update)
            return
        self.DeclarePeriodicUnrestrictedUpdateEvent(self._time_step, 0.0, self._update_state)
        self.DeclareForcedUnrestrictedUpdateEvent(self._step_state)

    def declare_output(
        self, name: str, size: int, calc: Callable, prerequisites: set | None = None
    ) -> OutputPort:
        """Declares the vector output ``name`` of ``size`` entries a run, computed by ``calc``
        (of the ``prerequisites``' tickets), published with abstract state."""
        B = self.batch_size
        if not self._abstract:
            return self.DeclareVectorOutputPort(name, B * size, calc, prerequisites)
        shown = {self.abstract_state_ticket(self._published_index), self.time_ticket()}
        port = self.DeclareVectorOutputPort(
            name, B * size, self._published(name, calc), (prerequisites or set()) | shown
        )
        self._published_ports.append(port)
        return port

    def declare_state_output(self, name: str, index: int, size: int) -> OutputPort:
        """Declares the output ``name`` of discrete-state group ``index`` (``size`` a run),
        published with abstract state."""
        if not self._abstract:
            return self.DeclareStateOutputPort(name, index)

        def calc(context: Context, output: BasicVector) -> None:
            output.set_value(context.get_discrete_state(index).get_value())

        return self.declare_output(name, size, calc, {self.discrete_state_ticket(index)})

    def _update_state(self, context: Context, state: State) -> None:
        shown = Shown(context.get_time(), [port.Eval(context) for port in self._published_ports])
        self._step_state(context, state)
        published = state.get_mutable_abstract_state().get_mutable_value(self._published_index)
        published.set_value(shown)

    def _step_state(self, context: Context, state: State) -> None:
        self.advance_state(context, self._filtered.Eval(context), state)
        if self._window is not None:
            self._record_window(context, state.get_mutable_discrete_state())

    def _published(self, name: str, calc: Callable) -> Callable:
        """``calc`` of the output ``name``, or what it showed before this tick's update when
        asked at the time of an update already applied."""
        index, slot = self._published_index, len(self._published_ports)

        def published(context: Context, output: BasicVector) -> None:
            shown = context.get_abstract_state(index).get_value()
            if shown.time == context.get_time():
                output.set_value(shown.values[slot])
            else:
                calc(context, output)

        return published

    def _calc_prior(self, context: Context, output: BasicVector) -> None:
        output.set_value(self.prior(context).x.ravel())

    def _calc_x_hat(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).x.ravel())

    def _calc_P(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).published_P.ravel())

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).status)

    def _calc_nis(self, context: Context, output: BasicVector) -> None:
        output.set_value(self._filtered.Eval(context).nis)
