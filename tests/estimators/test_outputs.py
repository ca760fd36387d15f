"""An estimator that carries particles updates without restriction and publishes its outputs:
the other systems' updates at a tick read what the outputs showed before the estimator's
update, as with a discrete update, and a logger reads the same values."""

import copy

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput

from drake_uuv.primitives.run_arrays import RunArrays
from tests.estimators.range_filters import inputs, make

STEPS = 12


class Probe(LeafSystem):
    """A discrete system that keeps, at each tick, the value its input shows to its update."""

    def __init__(self, size: int, period: float) -> None:
        super().__init__()
        self.DeclareVectorInputPort("u", size)
        state = self.DeclareDiscreteState(size)
        self.DeclareStateOutputPort("read", state)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)

    def _update(self, context: Context, discrete_state) -> None:
        discrete_state.set_value(0, self.get_input_port(0).Eval(context))


def run_probed(kind: str, port: str, **fields) -> tuple[np.ndarray, np.ndarray]:
    """The estimator alone on constant inputs for STEPS ticks: what a discrete system read of
    ``port`` in its update at each tick, and what a logger recorded of it at each tick."""
    builder = DiagramBuilder()
    estimator = builder.AddSystem(make(kind, **fields))
    for name, value in inputs(estimator).items():
        source = builder.AddSystem(ConstantVectorSource(np.atleast_1d(value).astype(float)))
        builder.Connect(source.get_output_port(), estimator.GetInputPort(name))
    output = estimator.GetOutputPort(port)
    probe = builder.AddSystem(Probe(output.size(), estimator.time_step))
    builder.Connect(output, probe.get_input_port(0))
    logged = LogVectorOutput(output, builder, estimator.time_step)
    read = LogVectorOutput(probe.get_output_port(0), builder, estimator.time_step)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(STEPS * estimator.time_step)
    context = simulator.get_context()
    # The probe's state at tick k + 1 holds what it read at tick k.
    return read.FindLog(context).data()[:, 1:], logged.FindLog(context).data()[:, :-1]


@pytest.mark.parametrize("port", ["x_TU_hat", "P_TU", "x_TU_prior", "estimator_phase"])
@pytest.mark.parametrize("kind", ["ekf", "pf"])
def test_a_discrete_update_at_a_tick_reads_what_the_outputs_showed_before_it(
    kind: str, port: str
) -> None:
    read, logged = run_probed(kind, port)
    assert make(kind).cloud is not None  # abstract state: the update is unrestricted
    assert np.ptp(logged, axis=1).max() > 0.0 or port == "estimator_phase"
    assert_array_equal(read, logged)


def test_without_particles_the_update_is_discrete_and_reads_the_same() -> None:
    system = make("ekf", particle_bridge=False)
    assert system.cloud is None
    assert system.GetUniquePeriodicDiscreteUpdateAttribute() is not None
    read, logged = run_probed("ekf", "x_TU_hat", particle_bridge=False)
    assert_array_equal(read, logged)
    # The same filter with the bridge gives the same estimates where the bridge is idle.
    bridged, _ = run_probed("ekf", "x_TU_hat")
    assert_array_equal(read, bridged)


def test_run_arrays_are_shared_by_copies_and_never_written_in_place() -> None:
    value = RunArrays(particles=np.zeros((2, 3, 6)), live=np.zeros(2))
    assert copy.deepcopy(value) is value and copy.copy(value) is value
    with pytest.raises(ValueError, match="read-only"):
        value.particles[0, 0, 0] = 1.0
    with pytest.raises(AttributeError, match="immutable: build a new one with replaced"):
        value.live = np.ones(2)
    with pytest.raises(AttributeError, match="RunArrays has no array 'weights'"):
        _ = value.weights
    with pytest.raises(ValueError, match=r"replaced: no arrays named \['weights'\]"):
        value.replaced(weights=np.ones(2))
    moved = value.replaced(live=np.ones(2))
    assert moved.particles is value.particles and moved.live.tolist() == [1.0, 1.0]
    assert value.live.tolist() == [0.0, 0.0]
    assert sorted(moved.runs()) == ["live", "particles"]


def test_an_idle_cloud_is_carried_from_step_to_step_without_a_copy() -> None:
    """A bridged EKF whose runs never enter their particles: the cloud's arrays after a
    simulated second are the very arrays it started with."""
    system = make("ekf")
    builder = DiagramBuilder()
    estimator = builder.AddSystem(system)
    for name, value in inputs(estimator).items():
        source = builder.AddSystem(ConstantVectorSource(np.atleast_1d(value).astype(float)))
        builder.Connect(source.get_output_port(), estimator.GetInputPort(name))
    simulator = Simulator(builder.Build())
    context = estimator.GetMyContextFromRoot(simulator.get_context())
    start = estimator.cloud.arrays(context).particles
    simulator.AdvanceTo(STEPS * estimator.time_step)
    assert not estimator.cloud.live(context).any()
    assert estimator.cloud.arrays(context).particles is start


def test_a_filter_with_particles_refuses_to_advance_without_its_whole_state() -> None:
    system = make("pf")
    context = system.CreateDefaultContext()
    with pytest.raises(ValueError, match="state: a filter with particles advances its whole"):
        system.advance(context, None, context.get_mutable_discrete_state())
