"""The systems' conventions, read from the package: short constructors, no wiring across slots.

(a) Every ``LeafSystem`` or ``Diagram`` subclass defined in ``drake_uuv`` takes at most three
positional constructor parameters (after ``self``): a system takes its own configuration
and gets everything else by keyword (the modules are imported and the signatures inspected).

(b) A module of a slot's folder (``plants/``, ``navigation/``, ``sensors/``,
``estimators/``, ``attitude/``, ``tracking/``) imports no configuration class of another slot
(the classes are resolved to the module that defines them, so ``from drake_uuv.scenario
import Ekf`` counts as importing
``drake_uuv.scenario.estimators``); a system module (not the folder's ``factory`` or
``__init__``) imports no ``Scenario``; and none calls ``getattr`` on a configuration (a name
bound to a parameter annotated with a scenario class, to ``config``/``scenario``, or to
anything computed from those).
"""

import ast
import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import pytest
from pydrake.systems.framework import Diagram, LeafSystem

import drake_uuv
from drake_uuv.scenario import Scenario

SOURCE = Path(drake_uuv.__file__).resolve().parent
MAX_POSITIONAL = 3
#: A slot's folder → the scenario module of its configurations (the sonar has none).
SLOT_CONFIGS = {
    "plants": "drake_uuv.scenario.plants",
    "navigation": "drake_uuv.scenario.navigation",
    "sensors": None,
    "estimators": "drake_uuv.scenario.estimators",
    "attitude": "drake_uuv.scenario.attitude",
    "tracking": "drake_uuv.scenario.tracking",
}
CONFIG_MODULES = {module for module in SLOT_CONFIGS.values() if module}
ALL_MODULES = sorted(
    info.name for info in pkgutil.walk_packages([str(SOURCE)], prefix="drake_uuv.")
)


def _marked(module: str) -> pytest.param:
    return pytest.param(module, id=module.removeprefix("drake_uuv."))


# ------------------------------------------------------------------ (a) constructors


def positional_parameters(cls: type) -> int | None:
    """How many parameters after ``self`` can be passed by position (None: ``*args``)."""
    parameters = list(inspect.signature(cls.__init__).parameters.values())[1:]
    if any(p.kind is p.VAR_POSITIONAL for p in parameters):
        return None
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in parameters)


def long_constructors(module_name: str) -> list[str]:
    """The systems defined in the module whose constructors take too many positions."""
    module = importlib.import_module(module_name)
    found = []
    for name, cls in vars(module).items():
        if not (
            inspect.isclass(cls)
            and issubclass(cls, LeafSystem | Diagram)
            and cls.__module__ == module_name
        ):
            continue
        count = positional_parameters(cls)
        if count is None or count > MAX_POSITIONAL:
            found.append(f"{name}: {'*args' if count is None else count} positional")
    return found


def test_the_constructor_check_counts_positions_after_self() -> None:
    class Long(LeafSystem):
        def __init__(self, a, b, c, d=1, *, e=2) -> None: ...

    class Short(LeafSystem):
        def __init__(self, config, *, setting) -> None: ...

    class Spread(LeafSystem):
        def __init__(self, *args) -> None: ...

    assert [positional_parameters(c) for c in (Long, Short, Spread)] == [4, 1, None]


def test_every_system_of_the_package_is_found() -> None:
    systems = set()
    for module_name in ALL_MODULES:
        module = importlib.import_module(module_name)
        systems |= {
            f"{module_name}.{name}"
            for name, cls in vars(module).items()
            if inspect.isclass(cls)
            and issubclass(cls, LeafSystem | Diagram)
            and cls.__module__ == module_name
        }
    assert {
        "drake_uuv.plants.hovering_auv.HoveringAuvPlant",
        "drake_uuv.attitude.information_seeking.InformationSeekingAttitude",
        "drake_uuv.visualization.live_visualizer.LiveMeshcatVisualizer",
    } < systems


@pytest.mark.parametrize("module", [_marked(m) for m in ALL_MODULES])
def test_systems_take_at_most_three_positional_parameters(module: str) -> None:
    found = long_constructors(module)
    assert not found, f"{module}: {'; '.join(found)} (at most {MAX_POSITIONAL})"


# ------------------------------------------------------------- (b) no wiring across slots


def imported_scenario_names(tree: ast.AST) -> dict[str, str]:
    """Each name a module binds from ``drake_uuv.scenario*`` → the module defining it."""
    found = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(
            "drake_uuv.scenario"
        ):
            source = importlib.import_module(node.module)
            for alias in node.names:
                value = getattr(source, alias.name)
                origin = getattr(value, "__module__", None) if inspect.isclass(value) else None
                found[alias.asname or alias.name] = origin or f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("drake_uuv.scenario"):
                    found[alias.asname or alias.name] = alias.name
    return found


def imports_scenario(tree: ast.AST) -> bool:
    """Whether the module binds the whole :class:`~drake_uuv.scenario.Scenario`."""
    return any(
        isinstance(node, ast.ImportFrom)
        and (node.module or "").startswith("drake_uuv.scenario")
        and getattr(importlib.import_module(node.module), alias.name, None) is Scenario
        for node in ast.walk(tree)
        for alias in getattr(node, "names", [])
    )


def foreign_configs(tree: ast.AST, folder: str) -> list[str]:
    """Configuration classes of another slot that the module imports."""
    own = SLOT_CONFIGS[folder]
    return sorted(
        f"{name} ({origin})"
        for name, origin in imported_scenario_names(tree).items()
        if any(origin == m or origin.startswith(f"{m}.") for m in CONFIG_MODULES - {own})
    )


def getattr_on_configs(tree: ast.AST) -> list[str]:
    """``getattr`` calls whose object is, or is computed from, a configuration."""
    classes = {
        name
        for name, origin in imported_scenario_names(tree).items()
        if origin.startswith("drake_uuv.scenario")
    }
    tainted = {"config", "scenario"}
    for node in ast.walk(tree):
        if isinstance(node, ast.arg) and node.annotation is not None:
            annotation = {n.id for n in ast.walk(node.annotation) if isinstance(n, ast.Name)}
            if annotation & classes:
                tainted.add(node.arg)
    assignments = [n for n in ast.walk(tree) if isinstance(n, ast.Assign)]
    changed = True
    while changed:  # names assigned from tainted expressions, to a fixed point
        changed = False
        for node in assignments:
            if _mentions(node.value, tainted):
                for target in node.targets:
                    for name in ast.walk(target):
                        if isinstance(name, ast.Name) and name.id not in tainted:
                            tainted.add(name.id)
                            changed = True
    return [
        f"line {node.lineno}: {ast.unparse(node)}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "getattr"
        and node.args
        and _mentions(node.args[0], tainted)
    ]


def _mentions(expression: ast.AST, tainted: set[str]) -> bool:
    names = {n.id for n in ast.walk(expression) if isinstance(n, ast.Name)}
    return bool(names & tainted) or bool(
        re.search(r"\._?(config|scenario)\b", ast.unparse(expression))
    )


def test_the_checks_find_the_wiring_they_forbid() -> None:
    old_planner = ast.parse(
        "from drake_uuv.scenario import Ekf, InformationSeeking, Scenario\n"
        "def from_scenario(cls, scenario: Scenario):\n"
        "    a, e, tracking = scenario.attitude, scenario.estimator, scenario.tracking\n"
        "    return getattr(tracking, 'feedforward', False)\n"
        "def f(law: InformationSeeking):\n"
        "    return getattr(law, 'horizon'), getattr(self._config, 'x')\n"
    )
    assert foreign_configs(old_planner, "attitude") == ["Ekf (drake_uuv.scenario.estimators)"]
    assert imports_scenario(old_planner)
    assert len(getattr_on_configs(old_planner)) == 3
    fine = ast.parse(
        "from drake_uuv.scenario.attitude import InformationSeeking\n"
        "def f(config: InformationSeeking, system):\n"
        "    return config.horizon, getattr(system, 'extra_signals', ())\n"
    )
    assert foreign_configs(fine, "attitude") == [] and getattr_on_configs(fine) == []
    assert not imports_scenario(fine)


def _slot_modules() -> list[pytest.param]:
    return [_marked(m) for m in ALL_MODULES if m.split(".")[1] in SLOT_CONFIGS]


def _tree(module: str) -> ast.AST:
    return ast.parse(Path(importlib.import_module(module).__file__).read_text())


@pytest.mark.parametrize("module", _slot_modules())
def test_slot_modules_import_no_configuration_of_another_slot(module: str) -> None:
    folder = module.split(".")[1]
    tree = _tree(module)
    assert not foreign_configs(tree, folder), f"{module} imports {foreign_configs(tree, folder)}"
    if module.rsplit(".", 1)[-1] not in ("factory", folder):  # a system module
        assert not imports_scenario(tree), f"{module} imports Scenario: take your own config"


@pytest.mark.parametrize("module", _slot_modules())
def test_slot_modules_call_no_getattr_on_a_configuration(module: str) -> None:
    found = getattr_on_configs(_tree(module))
    assert not found, f"{module}: {'; '.join(found)}"
