"""ARCHITECTURE.md's recipe, followed with throwaway variants in a copy of the repository.

A new estimator, attitude strategy or plant is four files: its module, its dataclass (in the
slot's scenario module, added to the slot's union), one line in its slot's factory (and the
import it needs), and its test. Each case here writes exactly those into a copy of the
repository (all three into one copy: they touch different slots) and runs the new tests with
every test that enumerates the registered variants (scenario loading and fuzzing, the
builder's registry, the diagram of every variant, the variants command, the package's
architecture), which must all pass without another edit.
"""

import shutil
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import pytest

REPO = Path(__file__).resolve().parents[2]
#: The tests that enumerate the registered variants.
REGISTRY_TESTS = [
    "tests/scenario",
    "tests/closed_loop/test_diagram.py",
    "tests/visualization/test_diagram_graph.py",
    "tests/cli/test_variants_command.py",
    "tests/package",
]


@dataclass(frozen=True)
class Recipe:
    slot: str
    tag: str
    module: str  # path of the new module
    module_text: str
    config_file: str  # the slot's scenario module
    config_text: str
    union: str  # the union's name in config_file
    factory_file: str
    factory_import: str
    table: str  # the factory table's name
    entry: str
    test_text: str


FROZEN = Recipe(
    slot="estimator",
    tag="Frozen",
    module="drake_uuv/estimators/frozen.py",
    module_text='''
        """An estimator that publishes its initial estimate (the recipe's example)."""

        import numpy as np
        from pydrake.systems.framework import Context

        from drake_uuv.estimators.base import (
            Estimate,
            FilteredEstimate,
            MeasurementUpdate,
            Ranges,
            RelativeStateEstimator,
        )
        from drake_uuv.models.measurement import VALID


        class FrozenEstimator(RelativeStateEstimator):
            """Publishes ``Υ̂(0|−1)`` and ``P(0|−1)`` at every step; ports as the base's (with
            ``batch_size`` B, which the base takes, every port holds B runs row-major)."""

            def measurement_update(
                self, context: Context, prior: Estimate, ranges: Ranges
            ) -> MeasurementUpdate | None:
                return None

            def filtered_estimate(self, context: Context) -> FilteredEstimate:
                B, start = self.batch_size, self.initial_estimate
                status = self.ranges(context).status  # (B, 2): each run's step, not updated
                first = status[:, 0]
                return FilteredEstimate(
                    np.tile(start.x, (B, 1)),
                    np.tile(start.P, (B, 1, 1)),
                    np.where(first != VALID, first, status[:, 1]),
                    np.full(B, np.nan),
                )
        ''',
    config_file="drake_uuv/scenario/estimators.py",
    config_text='''

        @dataclass
        class Frozen(EstimatorOptions):
            """Publishes its initial estimate at every step (the recipe's example)."""
        ''',
    union="EstimatorConfig",
    factory_file="drake_uuv/estimators/factory.py",
    factory_import="from drake_uuv.estimators.frozen import FrozenEstimator\n"
    "from drake_uuv.scenario.estimators import Frozen\n",
    table="ESTIMATORS",
    entry="    Frozen: FrozenEstimator,\n",
    test_text="""
        import numpy as np

        from drake_uuv.scenario import load_scenario
        from drake_uuv.simulation import simulate


        def test_the_frozen_estimate_never_moves():
            start = [-2.0, -2.0, 0.0, 0.0, 0.0, 0.0]
            scenario = load_scenario(
                "paper", ["estimator=!Frozen", f"estimator.initial_estimate={start}", "steps=20",
                          "steady_state_start=0"]
            )
            log = simulate(scenario).log
            assert np.all(log["x_TU_hat"] == np.array(start))
        """,
)
SPIN = Recipe(
    slot="attitude",
    tag="Spin",
    module="drake_uuv/attitude/spin.py",
    module_text='''
        """Turns about the world's vertical at a constant rate (the recipe's example)."""

        import numpy as np
        from pydrake.systems.framework import BasicVector, Context, LeafSystem

        from drake_uuv.attitude.base import AttitudeSetting
        from drake_uuv.primitives.batch import batch_size_field, per_run
        from drake_uuv.scenario.attitude import Spin


        class SpinAttitude(LeafSystem):
            """``u2 = [0, 0, rate]``; the plan holds the current attitude (sizes per run:
            with ``batch_size`` B every port holds B runs row-major).

            .. pydrake_system::

                name: SpinAttitude
                input_ports:
                - R_WB_nav
                output_ports:
                - u2_W
                - R_WB_plan
            """

            def __init__(
                self, config: Spin, *, setting: AttitudeSetting, batch_size: int = 1
            ) -> None:
                super().__init__()
                self.batch_size = B = batch_size_field(batch_size)
                self._rate = config.rate
                self._attitude = self.DeclareVectorInputPort("R_WB_nav", 9 * B)
                self.DeclareVectorOutputPort("u2_W", 3 * B, self._calc_rate)
                self.DeclareVectorOutputPort("R_WB_plan", 18 * B, self._calc_plan)

            def _calc_rate(self, context: Context, output: BasicVector) -> None:
                output.set_value(np.tile([0.0, 0.0, self._rate], self.batch_size))

            def _calc_plan(self, context: Context, output: BasicVector) -> None:
                R = per_run(self._attitude.Eval(context), self.batch_size)  # (B, 9)
                output.set_value(np.hstack([R, R]).ravel())
        ''',
    config_file="drake_uuv/scenario/attitude.py",
    config_text='''

        @dataclass
        class Spin:
            """Turns about the world's vertical at a constant rate (the recipe's example)."""

            rate: float = 0.5  # [rad/s]

            def validate(self, name: str) -> None:
                check_positive(f"{name}.rate", self.rate)
        ''',
    union="AttitudeConfig",
    factory_file="drake_uuv/attitude/factory.py",
    factory_import="from drake_uuv.attitude.spin import SpinAttitude\n"
    "from drake_uuv.scenario.attitude import Spin\n",
    table="ATTITUDE_GENERATORS",
    entry="    Spin: SpinAttitude,\n",
    test_text="""
        import numpy as np

        from drake_uuv.scenario import ScenarioError, load_scenario
        from drake_uuv.simulation import simulate

        import pytest


        def test_the_spin_turns_the_baseline_about_the_vertical():
            scenario = load_scenario("paper", ["attitude=!Spin {rate: 0.4}", "steps=10",
                                               "steady_state_start=0"])
            b_W = simulate(scenario).log["b_W"]
            angle = np.arctan2(b_W[:, 1], b_W[:, 0])
            assert np.allclose(np.diff(np.unwrap(angle)), 0.4 * scenario.time_step)
            with pytest.raises(ScenarioError, match=r"^attitude.rate: must be > 0, got -1"):
                load_scenario("paper", ["attitude=!Spin {rate: -1}"])
        """,
)
DRIFTING = Recipe(
    slot="plant",
    tag="DriftingUuv",
    module="drake_uuv/plants/drifting_uuv.py",
    module_text='''
        """The paper's vehicle carried by a uniform current (the recipe's example)."""

        import numpy as np
        from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

        from drake_uuv.models.motion import double_integrator_step
        from drake_uuv.models.so3 import exp_so3_runs
        from drake_uuv.plants.base import PlantSetting
        from drake_uuv.primitives.batch import batch_size_field, per_run, tiled
        from drake_uuv.scenario.plants import DriftingUuv


        class DriftingUuvPlant(LeafSystem):
            """The paper's plant plus a current c: ``p(k+1) = p + t v + ½t² R u1 + t c`` (sizes
            per run: with ``batch_size`` B every port and state holds B runs row-major).

            .. pydrake_system::

                name: DriftingUuvPlant
                input_ports:
                - u1_B
                - u2_W
                output_ports:
                - p_WU
                - v_WU
                - R_WB
            """

            def __init__(
                self, config: DriftingUuv, *, setting: PlantSetting, batch_size: int = 1
            ) -> None:
                super().__init__()
                self.batch_size = B = batch_size_field(batch_size)
                self._t = setting.time_step
                self._current = np.asarray(config.current, dtype=float)
                self._u1 = self.DeclareVectorInputPort("u1_B", 3 * B)
                self._u2 = self.DeclareVectorInputPort("u2_W", 3 * B)
                self._p = self.DeclareDiscreteState(tiled(setting.initial_position, B))
                self._v = self.DeclareDiscreteState(tiled(setting.initial_velocity, B))
                self._R = self.DeclareDiscreteState(tiled(setting.initial_R_WB, B))
                self.DeclarePeriodicDiscreteUpdateEvent(self._t, 0.0, self._update)
                self.DeclareStateOutputPort("p_WU", self._p)
                self.DeclareStateOutputPort("v_WU", self._v)
                self.DeclareStateOutputPort("R_WB", self._R)

            def _update(self, context: Context, state: DiscreteValues) -> None:
                values, B = context.get_discrete_state(), self.batch_size
                R = per_run(values.value(self._R), B, 3, 3)
                a_W = (R @ per_run(self._u1.Eval(context), B)[:, :, None])[:, :, 0]
                p, v = double_integrator_step(
                    per_run(values.value(self._p), B), per_run(values.value(self._v), B), a_W,
                    self._t,
                )
                u2 = per_run(self._u2.Eval(context), B)
                state.set_value(self._p, (p + self._t * self._current).ravel())
                state.set_value(self._v, v.ravel())
                state.set_value(self._R, (exp_so3_runs(u2 * self._t) @ R).ravel())
        ''',
    config_file="drake_uuv/scenario/plants.py",
    config_text='''

        @dataclass
        class DriftingUuv:
            """The paper's vehicle carried by a uniform current (the recipe's example)."""

            current: list[float] = field(default_factory=lambda: [0.1, 0.0, 0.0])  # [m/s]

            def validate(self, name: str) -> None:
                if len(self.current) != 3:
                    raise ScenarioError(f"{name}.current: must be 3 numbers, got {self.current!r}")

            def top_speed(self) -> float | None:
                """None: the plant enforces no top speed."""
                return None
        ''',
    union="PlantConfig",
    factory_file="drake_uuv/plants/factory.py",
    factory_import="from drake_uuv.plants.drifting_uuv import DriftingUuvPlant\n"
    "from drake_uuv.scenario.plants import DriftingUuv\n",
    table="PLANTS",
    entry="    DriftingUuv: DriftingUuvPlant,\n",
    test_text="""
        import numpy as np

        from drake_uuv.scenario import load_scenario
        from drake_uuv.simulation import simulate


        def test_the_current_moves_the_vehicle():
            common = ["steps=6", "steady_state_start=0"]
            still = simulate(load_scenario("paper", common)).log["p_WU"]
            drifting = simulate(load_scenario("paper", [*common, "plant=!DriftingUuv"])).log
            assert np.allclose(drifting["p_WU"][1] - still[1], [0.05, 0.0, 0.0])
        """,
)


def _apply(root: Path, recipe: Recipe) -> list[str]:
    """Writes the recipe's four files into ``root``; returns their paths."""
    (root / recipe.module).write_text(textwrap.dedent(recipe.module_text).lstrip())
    config = root / recipe.config_file
    text = config.read_text()
    head, union_line = text.rsplit(f"{recipe.union} = ", 1)
    first, rest = union_line.split("\n", 1)
    text = (
        head.rstrip()
        + "\n"
        + textwrap.dedent(recipe.config_text)
        + f"\n\n{recipe.union} = {first} | {recipe.tag}\n"
        + rest
    )
    config.write_text(text)
    factory = root / recipe.factory_file
    text = factory.read_text()
    text = text.replace(
        "\n\n#: Variant dataclass", "\n" + recipe.factory_import + "\n#: Variant dataclass", 1
    )
    table_start = text.index(f"{recipe.table}: dict")
    table_end = text.index("\n}\n", table_start)
    text = text[:table_end] + "\n" + recipe.entry.rstrip("\n") + text[table_end:]
    factory.write_text(text)
    test = root / "tests" / "package" / f"test_recipe_{recipe.tag.lower()}.py"
    test.write_text(textwrap.dedent(recipe.test_text).lstrip())
    return [recipe.module, recipe.config_file, recipe.factory_file, str(test.relative_to(root))]


RECIPES = [FROZEN, SPIN, DRIFTING]


@dataclass(frozen=True)
class Copy:
    """The copy with every recipe applied: each one's four files, the suite's verdicts."""

    written: dict[str, list[str]]  # tag -> the four files it wrote
    outcomes: dict[str, str]  # test id -> its outcome in the copy's suite
    variants: str  # `drake-uuv variants` in the copy


@pytest.fixture(scope="module")
def copy(tmp_path_factory: pytest.TempPathFactory) -> Copy:
    """One copy of the repository with the three recipes, its registry tests run once.

    The recipes touch different slots, so applying them together is what three authors'
    separate changes would give; one run of the registry tests then checks them all.
    """
    root = tmp_path_factory.mktemp("recipe") / "repo"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache")
    for folder in ("drake_uuv", "tests", "diagrams", "studies"):
        shutil.copytree(REPO / folder, root / folder, ignore=ignore)
    for name in ("pyproject.toml", "README.md", "ARCHITECTURE.md"):
        shutil.copy(REPO / name, root / name)
    written = {recipe.tag: _apply(root, recipe) for recipe in RECIPES}
    report = root / "report.xml"
    command = [
        sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0",
        "-m", "not slow", f"--junitxml={report}", *REGISTRY_TESTS,
        *(files[-1] for files in written.values()),
    ]  # fmt: skip
    result = subprocess.run(command, cwd=root, capture_output=True, text=True, timeout=600)
    assert report.exists(), result.stdout[-3000:] + result.stderr[-3000:]
    outcomes = {}
    for case in ElementTree.parse(report).iter("testcase"):
        failed = case.find("failure") is not None or case.find("error") is not None
        skipped = case.find("skipped") is not None
        outcome = "failed" if failed else "skipped" if skipped else "passed"
        outcomes[f"{case.get('classname')}::{case.get('name')}"] = outcome
    assert outcomes, result.stdout[-3000:]
    failures = [name for name, outcome in outcomes.items() if outcome == "failed"]
    assert not failures, f"{failures}\n" + result.stdout[-3000:]
    variants = subprocess.run(
        [sys.executable, "-m", "drake_uuv.cli", "variants"], cwd=root, capture_output=True,
        text=True, timeout=120,
    )  # fmt: skip
    return Copy(written, outcomes, variants.stdout)


@pytest.mark.slow
@pytest.mark.parametrize("recipe", RECIPES, ids=lambda r: r.slot)
def test_a_new_variant_is_four_files(copy: Copy, recipe: Recipe) -> None:
    written = copy.written[recipe.tag]
    assert len(written) == 4
    # The recipe's own test ran in the copy and passed, beside every registry test.
    module = f"tests.package.test_recipe_{recipe.tag.lower()}"
    own = {name: outcome for name, outcome in copy.outcomes.items() if name.startswith(module)}
    assert own and set(own.values()) == {"passed"}, own
    # The new variant is in the copy's registry, not in this one's.
    assert f"\n  {recipe.tag} " in copy.variants
