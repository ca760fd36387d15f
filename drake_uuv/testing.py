"""Helpers for unit-testing one system alone: fix its inputs, take one discrete update."""

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from pydrake.systems.framework import Context, PortDataType, System


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


def assert_batch_equals_runs(
    make: Callable[[int], System],
    inputs: Mapping[str, np.ndarray],
    states: Sequence[np.ndarray] | None = None,
    *,
    time: float = 0.0,
) -> None:
    """Checks that one step of a batch of B runs is, bit for bit, B steps of single runs.

    ``make(batch_size)`` builds the system; ``inputs`` maps input port names to ``(B, n)``
    arrays (run i's value in row i); ``states``, one ``(B, n_g)`` array per discrete-state
    group, sets the runs' states (default: the system's own initial state). Every vector output
    port and, for a system with one, the unique periodic discrete update are compared run by
    run; the first difference raises ``AssertionError`` naming the port (or state group) and
    the run.
    """
    values = {name: np.asarray(value, dtype=float) for name, value in inputs.items()}
    sizes = {len(value) for value in values.values()} | {len(s) for s in states or []}
    if len(sizes) != 1:
        raise ValueError(f"inputs and states: must all have B rows, got sizes {sorted(sizes)}")
    (B,) = sizes
    batch = make(B)
    batch_context = _step_context(batch, values, states, time, slice(None))
    batch_outputs = _vector_outputs(batch, batch_context)
    batch_next = _next_state(batch, batch_context)
    for i in range(B):
        single = make(1)
        context = _step_context(single, values, states, time, slice(i, i + 1))
        for name, value in _vector_outputs(single, context).items():
            got = batch_outputs[name].reshape(B, -1)[i]
            if not np.array_equal(got, value, equal_nan=True):
                raise AssertionError(f"output {name!r}, run {i}: batch {got} != alone {value}")
        for group, value in enumerate(_next_state(single, context)):
            got = batch_next[group].reshape(B, -1)[i]
            if not np.array_equal(got, value, equal_nan=True):
                raise AssertionError(
                    f"discrete state group {group}, run {i}: batch {got} != alone {value}"
                )


def _step_context(
    system: System,
    inputs: Mapping[str, np.ndarray],
    states: Sequence[np.ndarray] | None,
    time: float,
    runs: slice,
) -> Context:
    context = system.CreateDefaultContext()
    context.SetTime(time)
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, value[runs].ravel())
    for group, value in enumerate(states or []):
        context.SetDiscreteState(group, np.asarray(value, dtype=float)[runs].ravel())
    return context


def _vector_outputs(system: System, context: Context) -> dict[str, np.ndarray]:
    outputs = {}
    for i in range(system.num_output_ports()):
        port = system.get_output_port(i)
        if port.get_data_type() == PortDataType.kVectorValued:
            outputs[port.get_name()] = np.array(port.Eval(context), dtype=float)
    return outputs


def _next_state(system: System, context: Context) -> list[np.ndarray]:
    if context.num_discrete_state_groups() == 0:
        return []
    try:
        update = system.EvalUniquePeriodicDiscreteUpdate(context)
    except RuntimeError:  # no unique periodic discrete update
        return []
    return [update.get_vector(g).CopyToVector() for g in range(update.num_groups())]
