"""The dual sonar steps a batch of runs: each run's outputs and next state are, bit for bit,
those of the run alone, whatever the batch; a failed run leaves the others alone."""

import dataclasses

import numpy as np
import pytest

from drake_uuv.models.measurement import (
    DROPPED,
    NO_ARRIVAL,
    OUT_OF_BEAM,
    OUT_OF_RANGE,
    VALID,
)
from drake_uuv.models.so3 import exp_so3_runs
from drake_uuv.scenario import SonarConfig
from drake_uuv.sensors import DualSonar
from drake_uuv.sensors.dual_sonar import output_layout
from drake_uuv.sensors.sonar_kernels import _pairwise_sum
from drake_uuv.sensors.sonar_timing import TickGeometry, entry_size
from drake_uuv.testing import assert_batch_equals_runs, fixed_context
from tests.conftest import ETA_UNEQUAL, T

NOW = 3.0  # the tick of the step under test


def make(config: SonarConfig, noise_model: str = "derived"):
    return lambda B: DualSonar(config, noise_model=noise_model, time_step=T, batch_size=B)


def random_inputs(
    rng: np.random.Generator, B: int, config: SonarConfig, *, spread: float = 3.0
) -> dict[str, np.ndarray]:
    """Every input a sonar of ``config`` may have, for B runs: random vehicles and targets
    (a few metres apart), attitudes, velocities, draws; a prediction near the truth for
    some runs and far off for others, pointing by the true attitude for some runs and by
    one a few degrees off for others."""
    f = config.samples_per_step
    p_WU = rng.normal(scale=spread, size=(B, 3))
    p_WT = rng.normal(scale=spread, size=(B, 3))
    R_WB = exp_so3_runs(rng.normal(size=(B, 3)))
    heading = exp_so3_runs(rng.normal(scale=0.1, size=(B, 3)))
    R_nav = np.where(rng.uniform(size=(B, 1, 1)) < 0.5, R_WB, heading @ R_WB)
    q = p_WU - p_WT
    off = rng.uniform(size=(B, 1)) < 0.5
    q_prior = q + np.where(off, rng.normal(scale=3.0, size=(B, 3)), 0.05 * rng.normal(size=(B, 3)))
    A = rng.normal(scale=0.1, size=(B, 6, 6))
    P = A @ A.transpose(0, 2, 1) * rng.choice([1e-4, 1.0], size=(B, 1, 1))
    return {
        "p_WU": p_WU,
        "R_WB": R_WB.reshape(B, 9),
        "p_WT": p_WT,
        "range_noise": rng.standard_normal((B, 2 * f)),
        "v_WU": rng.normal(size=(B, 3)),
        "v_WT": rng.normal(size=(B, 3)),
        "x_TU_prior": np.concatenate([q_prior, rng.normal(size=(B, 3))], axis=1),
        "R_WB_nav": R_nav.reshape(B, 9),
        "P_TU_prior": P.reshape(B, 36),
        "fault_uniform": rng.uniform(size=(B, 4)),
        "multipath_noise": rng.exponential(size=(B, 2)),
    }


def ports_of(sonar: DualSonar, values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The values of the input ports ``sonar`` has."""
    return {name: value for name, value in values.items() if sonar.HasInputPort(name)}


def random_states(
    rng: np.random.Generator, sonar: DualSonar, inputs: dict[str, np.ndarray]
) -> list[np.ndarray]:
    """Random previous geometry (the tick before ``NOW``, near this one; the first tick, NaN,
    for some runs) and random FIFO entries of every status, for B runs."""
    B = len(inputs["p_WU"])
    f = sonar.GetOutputPort("range_samples").size() // (2 * B)
    R = exp_so3_runs(rng.normal(scale=0.2, size=(B, 3))) @ inputs["R_WB"].reshape(B, 3, 3)
    R_nav = np.where(rng.uniform(size=(B, 1, 1)) < 0.5, R, exp_so3_runs(rng.normal(size=(B, 3))))
    previous = np.concatenate(
        [
            np.full((B, 1), NOW - T),
            inputs["p_WU"] - 0.5 * inputs["v_WU"],
            inputs["v_WU"] + rng.normal(scale=0.1, size=(B, 3)),
            R.reshape(B, 9),
            inputs["p_WT"] - 0.5 * inputs["v_WT"],
            inputs["v_WT"],
            inputs["x_TU_prior"][:, :3] + rng.normal(size=(B, 3)),
            rng.uniform(0.0, 2.0, size=(B, 1)),
            R_nav.reshape(B, 9),
        ],
        axis=1,
    )
    assert previous.shape[1] == TickGeometry.SIZE
    previous[rng.uniform(size=B) < 0.3] = np.nan  # before the first tick
    states = [previous]
    context = sonar.CreateDefaultContext()
    for group in range(1, context.num_discrete_state_groups()):
        slots = context.get_discrete_state(group).size() // (B * entry_size(f))
        entries = rng.normal(loc=5.0, size=(B, slots, entry_size(f)))
        entries[:, :, f] = rng.integers(0, 6, size=(B, slots))  # any status
        entries[:, :, f + 1] = rng.exponential(size=(B, slots))
        states.append(entries.reshape(B, -1))
    return states


def statuses(config: SonarConfig, inputs: dict, states=None, noise_model="derived") -> set:
    """The statuses one step of the batch gives (to check a batch takes several branches)."""
    B = len(inputs["p_WU"])
    sonar = make(config, noise_model)(B)
    context = fixed_context(sonar, **{k: v.ravel() for k, v in ports_of(sonar, inputs).items()})
    context.SetTime(NOW)
    for group, value in enumerate(states or []):
        context.SetDiscreteState(group, value.ravel())
    return set(sonar.GetOutputPort("sonar_status").Eval(context).astype(int))


@pytest.mark.parametrize("samples_per_step", [1, 3])
@pytest.mark.parametrize("noise_model", ["derived", "paper_printed"])
@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_the_plain_sonar_s_batch_is_each_run_alone(
    batch_size: int, noise_model: str, samples_per_step: int
) -> None:
    rng = np.random.default_rng([batch_size, samples_per_step])
    config = SonarConfig(
        noise_variances=ETA_UNEQUAL.tolist(),
        samples_per_step=samples_per_step,
        sound_speed_error=0.02 if samples_per_step > 1 else 0.0,
    )
    sonar = make(config, noise_model)
    inputs = ports_of(sonar(1), random_inputs(rng, batch_size, config))
    assert_batch_equals_runs(sonar, inputs, time=NOW)


def test_the_batch_ports_hold_b_runs_row_major() -> None:
    """Each port's size is B × its size per run, and each run's slice is that run's: the
    Demultiplexer cuts the leaf's output-by-output blocks into ports row-major by run."""
    B, config = 3, SonarConfig(samples_per_step=2)
    sonar = make(config)(B)
    sizes = {name: B * n for name, n in output_layout(2)}
    ports = [sonar.get_output_port(i) for i in range(sonar.num_output_ports())]
    assert {p.get_name(): p.size() for p in ports} == sizes
    inputs = {"p_WU": 3, "R_WB": 9, "p_WT": 3, "range_noise": 4}
    ports = [sonar.get_input_port(i) for i in range(sonar.num_input_ports())]
    assert {p.get_name(): p.size() for p in ports} == {k: B * n for k, n in inputs.items()}
    rng = np.random.default_rng(1)
    values = ports_of(sonar, random_inputs(rng, B, config))
    values["range_noise"][:] = 0.0
    context = fixed_context(sonar, **{k: v.ravel() for k, v in values.items()})
    q_s = np.einsum("bij,j->bi", values["R_WB"].reshape(B, 3, 3), config.baseline)
    q = values["p_WU"] - values["p_WT"]
    expected = np.linalg.norm([q + 0.5 * q_s, q - 0.5 * q_s], axis=2).T
    got = sonar.GetOutputPort("ranges").Eval(context).reshape(B, 2)
    np.testing.assert_allclose(got, expected, rtol=1e-14)
    np.testing.assert_allclose(sonar.GetOutputPort("b_W").Eval(context).reshape(B, 3), q_s)


TIMINGS = [
    ([0.1, 0.35], 0.4),  # d = (1, 2): one FIFO of one slot
    ([0.0, 0.25], 0.0),  # d = (0, 1): one sonar at the tick, one between ticks
    ([0.49, 0.0], 1.3),  # d = (4, 3): FIFOs of 3 and 2 slots
    ([0.0, 0.0], 0.5),  # d = (1, 1): pings at the previous tick (s = 0)
]


@pytest.mark.parametrize(("offsets", "latency"), TIMINGS)
@pytest.mark.parametrize("samples_per_step", [1, 3])
@pytest.mark.parametrize("noise_model", ["derived", "paper_printed"])
@pytest.mark.parametrize("batch_size", [1, 2, 5])
def test_the_timed_sonar_s_batch_is_each_run_alone(
    offsets: list[float], latency: float, samples_per_step: int, noise_model: str, batch_size: int
) -> None:
    """Outputs and next state (the tick's geometry, the FIFOs) from random previous
    geometry and FIFO entries: some runs at their first tick, the others pinging between
    ticks."""
    rng = np.random.default_rng([batch_size, samples_per_step, int(10 * latency)])
    config = SonarConfig(
        noise_variances=ETA_UNEQUAL.tolist(),
        samples_per_step=samples_per_step,
        ping_offsets=offsets,
        latency=latency,
        sound_speed_error=-0.01,
    )
    sonar = make(config, noise_model)
    values = random_inputs(rng, batch_size, config)
    inputs = ports_of(sonar(1), values)
    states = random_states(rng, sonar(batch_size), values)
    assert_batch_equals_runs(sonar, inputs, states, time=NOW)


FAULTY = SonarConfig(
    noise_variances=ETA_UNEQUAL.tolist(),
    max_range=6.0,
    beam_half_angle_deg=15.0,
    search_sigma=1.0,
    dropout_probability=[0.3, 0.2],
    outlier_probability=0.3,
    outlier_scale=0.7,
)


@pytest.mark.parametrize(
    ("offsets", "latency", "samples_per_step"),
    [([0.0, 0.0], 0.0, 1), ([0.0, 0.0], 0.0, 3), ([0.2, 0.0], 0.6, 3), ([0.0, 0.3], 0.0, 1)],
)
@pytest.mark.parametrize("noise_model", ["derived", "paper_printed"])
def test_a_faulty_sonar_s_batch_is_each_run_alone(
    offsets: list[float], latency: float, samples_per_step: int, noise_model: str
) -> None:
    """A beam, a maximum range, dropouts and outliers: runs inside and outside the beam and
    the range, dropped and not, in one batch (checked), each run as alone."""
    B = 12
    rng = np.random.default_rng([samples_per_step, int(10 * latency)])
    config = dataclasses.replace(
        FAULTY, ping_offsets=offsets, latency=latency, samples_per_step=samples_per_step
    )
    sonar = make(config, noise_model)
    values = random_inputs(rng, B, config)
    inputs = ports_of(sonar(1), values)
    states = random_states(rng, sonar(B), values) if sonar(1).num_discrete_state_groups() else None
    assert_batch_equals_runs(sonar, inputs, states, time=NOW)
    taken = statuses(config, inputs, states, noise_model)
    assert {VALID, OUT_OF_BEAM, OUT_OF_RANGE, DROPPED} <= taken, taken
    if states is not None:
        assert NO_ARRIVAL in taken


@pytest.mark.parametrize(
    ("offsets", "latency"), [([0.0, 0.0], 0.0), ([0.1, 0.35], 0.4), ([0.49, 0.0], 1.3)]
)
# numpy's matmul of an inf attitude (R_WB b, as before) warns by numpy's default; it does not
# raise (a study runs under errstate(all="ignore")).
@pytest.mark.filterwarnings("ignore:invalid value encountered in matmul:RuntimeWarning")
def test_a_failed_run_leaves_the_others_alone(offsets: list[float], latency: float) -> None:
    """A run whose inputs and state are NaN (or inf) raises nothing and changes no bit of the
    other runs' outputs and next state; its own geometry (``p_TS_W``) is not finite."""
    B, bad = 4, 1
    config = dataclasses.replace(FAULTY, ping_offsets=offsets, latency=latency)
    rng = np.random.default_rng(7)
    sonar = make(config)(B)
    values = random_inputs(rng, B, config)
    inputs = ports_of(sonar, values)
    states = random_states(rng, sonar, values) if sonar.num_discrete_state_groups() else []
    if states:
        states[0][:, 0] = NOW - T  # every run past its first tick

    def step(values: dict, state: list) -> tuple[dict, list]:
        context = fixed_context(sonar, **{k: v.ravel() for k, v in values.items()})
        context.SetTime(NOW)
        for group, value in enumerate(state):
            context.SetDiscreteState(group, value.ravel())
        outputs = {}
        for i in range(sonar.num_output_ports()):
            port = sonar.get_output_port(i)
            outputs[port.get_name()] = np.array(port.Eval(context)).reshape(B, -1)
        after = []
        if state:
            update = sonar.EvalUniquePeriodicDiscreteUpdate(context)
            after = [update.get_vector(g).CopyToVector().reshape(B, -1) for g in range(len(state))]
        return outputs, after

    clean_outputs, clean_next = step(inputs, states)
    for poison in (np.nan, np.inf):
        failed = {k: v.copy() for k, v in inputs.items()}
        for name in ("p_WU", "R_WB", "v_WU", "x_TU_prior", "R_WB_nav", "P_TU_prior"):
            if name in failed:
                failed[name][bad] = poison
        failed_states = [s.copy() for s in states]
        for s in failed_states:
            s[bad, 1:] = poison
        outputs, after = step(failed, failed_states)
        others = np.arange(B) != bad
        for name, value in outputs.items():
            np.testing.assert_array_equal(value[others], clean_outputs[name][others], name)
        for group, value in enumerate(after):
            np.testing.assert_array_equal(value[others], clean_next[group][others])
        assert not np.isfinite(outputs["p_TS_W"][bad]).any()


@pytest.mark.parametrize("n", [*range(1, 140), 255, 256, 257, 1000, 1031, 4097, 10_000])
def test_the_kernel_sums_as_numpy_does(n: int) -> None:
    """The sum of f squares, whose bits m and Γ carry: numpy's pairwise summation."""
    x = np.random.default_rng(n).normal(scale=5.0, size=(2, n))
    squares = x * x
    expected = squares.sum(axis=1)
    assert [_pairwise_sum(squares[i], 0, n) for i in range(2)] == expected.tolist()
