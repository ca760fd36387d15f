"""Helpers for unit-testing one system alone: fix its inputs, take one discrete update."""

import numpy as np
from pydrake.systems.framework import Context, System


def fixed_context(system: System, **inputs: np.ndarray) -> Context:
    """A default context of ``system`` with each named input port fixed to a value."""
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, np.atleast_1d(np.asarray(value, dtype=float)))
    return context


def discrete_update(system: System, context: Context, group: int = 0) -> np.ndarray:
    """The system's next discrete state (one group) after its unique periodic update."""
    return system.EvalUniquePeriodicDiscreteUpdate(context).get_vector(group).CopyToVector()


def after_update(system: System, context: Context) -> Context:
    """A copy of ``context`` advanced by the system's unique periodic discrete update (the
    next step's state, read through the system's own accessors)."""
    after = context.Clone()
    after.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
    return after
