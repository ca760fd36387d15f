"""``drake-uuv scenarios``: the scenario files shipped with the package, each with the line
that describes it (its ``# description:`` comment, so that a new file needs no code edit)."""

import argparse

from drake_uuv.cli.options import add_listing


def scenario_table() -> list[tuple[str, str]]:
    """``(name, description)`` of every shipped scenario, by name."""
    from drake_uuv.scenario import builtin_scenarios, scenario_description

    return [(name, scenario_description(name)) for name in builtin_scenarios()]


def _scenarios(args: argparse.Namespace) -> int:
    from drake_uuv.scenario import resolve_scenario_path

    rows = scenario_table()
    width = max(len(name) for name, _ in rows)
    print(f"Shipped scenarios (the files in {resolve_scenario_path(rows[0][0]).parent}):")
    for name, description in rows:
        print(f"  {name.ljust(width)}  {description or '(no # description: line)'}")
    print("Run one with any command by its name: drake-uuv run --scenario NAME")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv scenarios``."""
    add_listing(
        subparsers,
        "scenarios",
        "list the shipped scenarios with a one-line description",
        _scenarios,
    )
