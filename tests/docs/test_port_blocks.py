"""The reference's port blocks: the extension reads every ``pydrake_system`` block of the
package's docstrings, and each block says what the built system has."""

import importlib
import inspect
import pkgutil
import sys
from pathlib import Path

import pytest

import drake_uuv

DOCS = Path(__file__).resolve().parents[2] / "docs"
sys.path.insert(0, str(DOCS / "_ext"))
uuv_sphinx = pytest.importorskip("uuv_sphinx", reason="the test extra: pip install -e '.[test]'")


@pytest.mark.parametrize(
    "entries, ports",
    [
        (["p_WU", "R_WB"], [("p_WU", None), ("R_WB", None)]),
        (["v_WU (with timing)"], [("v_WU", "with timing")]),
        ("measurement", [("measurement", None)]),
        (None, []),
        (["fault_uniform (with dropouts or outliers)"],
         [("fault_uniform", "with dropouts or outliers")]),
        (["<each signal of the channel>"], [("<each signal of the channel>", None)]),
    ],
)  # fmt: skip
def test_ports_and_their_conditions(entries, ports) -> None:
    assert uuv_sphinx.parse_ports(entries) == ports


def test_a_flow_list_spanning_lines() -> None:
    text = """
        name: SonarMeasurement
        input_ports: [p_WU, R_WB, v_WU (with timing),
                      fault_uniform (with dropouts or outliers)]
        output_ports: [measurement]
    """
    block = uuv_sphinx.parse_system_block(text)
    assert block["name"] == "SonarMeasurement"
    assert block["input_ports"] == [("p_WU", None), ("R_WB", None), ("v_WU", "with timing"),
                                    ("fault_uniform", "with dropouts or outliers")]  # fmt: skip
    assert block["output_ports"] == [("measurement", None)]


def test_a_block_without_a_name_is_refused() -> None:
    with pytest.raises(ValueError, match="name"):
        uuv_sphinx.parse_system_block("input_ports: [a]")


def _package_classes() -> list[type]:
    classes = []
    for info in pkgutil.walk_packages(drake_uuv.__path__, "drake_uuv."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and obj.__module__ == info.name and not name.startswith("_"):
                classes.append(obj)
    return classes


def test_every_block_names_the_class_whose_docstring_holds_it() -> None:
    found = 0
    for cls in _package_classes():
        for block in uuv_sphinx.system_blocks(cls.__doc__ or ""):
            found += 1
            assert block["name"] == cls.__name__, f"{cls.__qualname__}'s block: {block['name']}"
    assert found >= 18


def _slot_variants() -> list[tuple[str, str, type, type]]:
    from drake_uuv.diagram import SLOT_REGISTRY

    return [(slot.section, slot.system, variant, system)
            for slot in SLOT_REGISTRY for variant, system in slot.table.items()]  # fmt: skip


@pytest.mark.parametrize(
    "section, name, variant, system", _slot_variants(), ids=lambda v: getattr(v, "__name__", v)
)
def test_the_block_of_each_variant_is_the_built_system(section, name, variant, system) -> None:
    """The ports drawn are the ports built: every port of the variant's system (paper
    scenario otherwise) is in its block, and every port the block states without a condition
    is built."""
    from drake_uuv.diagram import make_uuv_diagram
    from drake_uuv.scenario import load_scenario

    blocks = [b for b in uuv_sphinx.system_blocks(system.__doc__) if b["name"] == system.__name__]
    assert blocks, f"{system.__qualname__} has no pydrake_system block"
    block = blocks[0]
    built = make_uuv_diagram(load_scenario("paper", [f"{section}=!{variant.__name__}"]), log=False)
    unit = built.systems[name]
    for kind, count, port in (("input_ports", unit.num_input_ports(), unit.get_input_port),
                              ("output_ports", unit.num_output_ports(), unit.get_output_port)):  # fmt: skip
        ports = {port(i).get_name() for i in range(count)}
        drawn = {p for p, _ in block[kind]}
        required = {p for p, condition in block[kind] if not condition}
        assert ports <= drawn, f"{kind} built but not drawn: {sorted(ports - drawn)}"
        assert required <= ports, f"{kind} drawn but not built: {sorted(required - ports)}"


def test_units_are_read_from_the_comments() -> None:
    from drake_uuv.scenario import HoveringAuv, RawRangeOptions, SonarConfig

    units = {row.name: row.unit for row in uuv_sphinx.field_rows(SonarConfig)}
    assert units["baseline"] == "m" and units["noise_variances"] == "m²"
    assert units["beam_half_angle_deg"] == "deg" and units["latency"] == "s"
    # "... an excess of mean outlier_scale [m]" in outlier_probability's comment: outlier_scale's.
    assert units["outlier_probability"] == "" and units["outlier_scale"] == "m"
    hull = {row.name: row for row in uuv_sphinx.field_rows(HoveringAuv)}
    assert hull["inertia"].unit == "kg m²" and hull["controller_rate"].unit == "Hz"
    assert hull["inertia"].comment.startswith("Inertia about the centre of gravity")
    assert hull["linear_damping"].unit == "N s/m; N m s"  # its force's and its moment's
    # From the class's docstring (``handover_angle`` [rad]), and inherited with their comments.
    ranges = {row.name: row for row in uuv_sphinx.field_rows(RawRangeOptions)}
    assert ranges["handover_angle"].unit == "rad"
    assert ranges["added_acceleration_variance"].unit == "m²/s⁴"
    assert ranges["added_acceleration_variance"].owner == "EstimatorOptions"


def test_defaults_and_types_as_written() -> None:
    from drake_uuv.scenario import Scenario, SonarConfig

    rows = {row.name: row for row in uuv_sphinx.field_rows(SonarConfig)}
    assert rows["baseline"].default == "[-1, 1, 0]" and rows["baseline"].type == "list[float]"
    assert rows["max_range"].default == "None" and rows["max_range"].type == "float | None"
    scenario = {row.name: row for row in uuv_sphinx.field_rows(Scenario)}
    assert scenario["plant"].type == "KinematicUuv | HoveringAuv"
    assert scenario["plant"].default == "KinematicUuv()"
