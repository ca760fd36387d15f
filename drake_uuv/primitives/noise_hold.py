"""Holds one random sample per step so every reader of step k sees the same draw."""

import numpy as np
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem


class NoiseHold(LeafSystem):
    """Sample-and-hold of a ``RandomSource``, latched at initialization and at every tick.

    Why: Drake's ``RandomSource`` draws its next sample in an *unrestricted* update, and the
    Simulator runs unrestricted updates before discrete updates at the same tick. A system that
    reads the source directly in a feedthrough output therefore sees draw n at the tick's
    publish (the loggers) but draw n + 1 in that tick's discrete updates (the plant, the
    filter): the log would not hold the measurement the filter used, and every output
    downstream is computed twice per step. Latching the draw into discrete state gives one
    value per step, read identically by publishes and updates.

    Sequence: the initialization event latches the source's first draw for step 0; the update at
    step k latches the draw the source has just made, which becomes step k + 1's sample.

    .. pydrake_system::

        name: NoiseHold
        input_ports:
        - sample
        output_ports:
        - held_sample
    """

    def __init__(self, size: int, time_step: float) -> None:
        super().__init__()
        self._input = self.DeclareVectorInputPort("sample", size)
        self._state_index = self.DeclareDiscreteState(np.zeros(size))
        self.DeclareInitializationDiscreteUpdateEvent(self._latch)
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._latch)
        self.DeclareStateOutputPort("held_sample", self._state_index)

    def _latch(self, context: Context, discrete_state: DiscreteValues) -> None:
        discrete_state.set_value(self._state_index, self._input.Eval(context))
