"""Helpers for unit-testing one system alone: fix its inputs, take one discrete update."""

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from pydrake.systems.framework import Context, PortDataType, System

from drake_uuv.primitives.run_arrays import RunArrays


def fixed_context(system: System, **inputs: np.ndarray) -> Context:
    """A default context of ``system`` with each named input port fixed to a value."""
    context = system.CreateDefaultContext()
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, np.atleast_1d(np.asarray(value, dtype=float)))
    return context


def discrete_update(system: System, context: Context, group: int = 0) -> np.ndarray:
    """The system's next discrete state (one group) after its periodic update."""
    return after_update(system, context).get_discrete_state(group).CopyToVector()


def after_update(system: System, context: Context) -> Context:
    """A copy of ``context`` advanced by the system's periodic update (the next step's state,
    read through the system's own accessors): its unique periodic discrete update or, for a
    system with abstract state (an estimator carrying particles), its forced unrestricted
    update, the same step without publishing its outputs."""
    after = context.Clone()
    if system.GetUniquePeriodicDiscreteUpdateAttribute() is not None:
        after.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
    else:
        system.CalcForcedUnrestrictedUpdate(context, after.get_mutable_state())
    return after


def set_states(
    context: Context,
    states: Sequence[np.ndarray],
    arrays: Mapping[int, Mapping[str, np.ndarray]] | None = None,
) -> None:
    """Sets each discrete-state group ``g`` to ``states[g]`` (flattened) and each abstract
    state's named arrays of ``arrays`` (:func:`set_run_arrays`)."""
    for group, value in enumerate(states):
        context.SetDiscreteState(group, np.asarray(value, dtype=float).ravel())
    for index, named in (arrays or {}).items():
        set_run_arrays(context, index, **named)


def set_run_arrays(context: Context, index: int, **arrays: np.ndarray) -> None:
    """Replaces named arrays of the :class:`~drake_uuv.primitives.run_arrays.RunArrays` held
    in abstract state ``index`` (each ``(B, ...)``; a flat ``(B, n)`` row is reshaped)."""
    held = context.get_abstract_state(index).get_value()
    shaped = {
        name: np.asarray(value, dtype=float).reshape(getattr(held, name).shape)
        for name, value in arrays.items()
    }
    context.SetAbstractState(index, held.replaced(**shaped))


def assert_batch_equals_runs(
    make: Callable[[int], System],
    inputs: Mapping[str, np.ndarray],
    states: Sequence[np.ndarray] | None = None,
    *,
    time: float = 0.0,
    arrays: Mapping[int, Mapping[str, np.ndarray]] | None = None,
) -> None:
    """Checks that one step of a batch of B runs is, bit for bit, B steps of single runs.

    ``make(batch_size)`` builds the system; ``inputs`` maps input port names to ``(B, n)``
    arrays (run i's value in row i); ``states``, one ``(B, n_g)`` array per discrete-state
    group, sets the runs' states (default: the system's own initial state); ``arrays`` maps an
    abstract state's index to named ``(B, ...)`` arrays of its
    :class:`~drake_uuv.primitives.run_arrays.RunArrays` (a particle cloud's). Every vector
    output port and the periodic update (:func:`after_update`: every discrete group and every
    abstract state's arrays) are compared run by run; the first difference raises
    ``AssertionError`` naming the port (or state) and the run.
    """
    values = {name: np.asarray(value, dtype=float) for name, value in inputs.items()}
    held = [a for named in (arrays or {}).values() for a in named.values()]
    sizes = {len(value) for value in values.values()} | {len(s) for s in [*(states or []), *held]}
    if len(sizes) != 1:
        raise ValueError(f"inputs and states: must all have B rows, got sizes {sorted(sizes)}")
    (B,) = sizes
    batch = make(B)
    batch_context = _step_context(batch, values, states, arrays, time, slice(None))
    batch_outputs = _vector_outputs(batch, batch_context)
    batch_next = _next_state(batch, batch_context)
    for i in range(B):
        single = make(1)
        context = _step_context(single, values, states, arrays, time, slice(i, i + 1))
        for name, value in _vector_outputs(single, context).items():
            got = batch_outputs[name].reshape(B, -1)[i]
            if not np.array_equal(got, value, equal_nan=True):
                raise AssertionError(f"output {name!r}, run {i}: batch {got} != alone {value}")
        for label, value in _next_state(single, context).items():
            got = batch_next[label].reshape(B, -1)[i]
            if not np.array_equal(got, value.ravel(), equal_nan=True):
                raise AssertionError(f"{label}, run {i}: batch {got} != alone {value}")


def _step_context(
    system: System,
    inputs: Mapping[str, np.ndarray],
    states: Sequence[np.ndarray] | None,
    arrays: Mapping[int, Mapping[str, np.ndarray]] | None,
    time: float,
    runs: slice,
) -> Context:
    context = system.CreateDefaultContext()
    context.SetTime(time)
    for name, value in inputs.items():
        system.GetInputPort(name).FixValue(context, value[runs].ravel())
    set_states(
        context,
        [np.asarray(value, dtype=float)[runs] for value in states or []],
        {
            i: {name: value[runs] for name, value in named.items()}
            for i, named in (arrays or {}).items()
        },
    )
    return context


def _vector_outputs(system: System, context: Context) -> dict[str, np.ndarray]:
    outputs = {}
    for i in range(system.num_output_ports()):
        port = system.get_output_port(i)
        if port.get_data_type() == PortDataType.kVectorValued:
            outputs[port.get_name()] = np.array(port.Eval(context), dtype=float)
    return outputs


def _next_state(system: System, context: Context) -> dict[str, np.ndarray]:
    """The state after the system's periodic update by label, each ``(B, ...)`` flattened per
    run: every discrete group, and each named array of an abstract state's ``RunArrays``
    (none for a system without a periodic update)."""
    periodic_discrete = system.GetUniquePeriodicDiscreteUpdateAttribute() is not None
    if not periodic_discrete and context.num_abstract_states() == 0:
        return {}
    after = after_update(system, context)
    B = getattr(system, "batch_size", 1)
    state = {
        f"discrete state group {g}": after.get_discrete_state(g).CopyToVector().reshape(B, -1)
        for g in range(after.num_discrete_state_groups())
    }
    for index in range(after.num_abstract_states()):
        held = after.get_abstract_state(index).get_value()
        if isinstance(held, RunArrays):
            for name, value in held.runs().items():
                state[f"abstract state {index} {name!r}"] = value.reshape(B, -1)
    return state
