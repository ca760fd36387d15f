"""``drake-uuv variants``: every slot of the loop and the variants it can hold."""

import argparse
import inspect

from drake_uuv.cli.options import add_listing


def variant_table() -> list[tuple[str, str, str, str]]:
    """``(section, diagram system, variant name, one-line description)`` of every variant, each
    slot's default first, in the registry's order."""
    from drake_uuv.diagram import SLOT_REGISTRY
    from drake_uuv.scenario import Scenario, variants

    rows = []
    defaults = Scenario()
    for slot in SLOT_REGISTRY:
        options = variants(Scenario, slot.section)
        default = type(getattr(defaults, slot.section)).__name__
        for tag in sorted(options, key=lambda name: name != default):
            rows.append((slot.section, slot.system, tag, summary(options[tag])))
    return rows


def summary(cls: type) -> str:
    """The first sentence of a class's docstring, without reStructuredText's double quotes."""
    text = " ".join((inspect.getdoc(cls) or "").split("\n\n")[0].split())
    sentence = text.split(". ")[0].rstrip(".")
    return sentence.replace("``", "")


def _variants(args: argparse.Namespace) -> int:
    rows = variant_table()
    width = max(len(tag) for _, _, tag, _ in rows)
    section = None
    for name, system, tag, line in rows:
        if name != section:
            print(f"{name} (system {system!r}; choose with --set {name}=<variant>):")
            section = name
            default = " (default)"
        else:
            default = ""
        print(f"  {tag.ljust(width)}  {line}{default}")
    print("A variant with fields, quoted for the shell: --set 'SECTION=VARIANT {FIELD: VALUE}'")
    return 0


def add_subcommand(subparsers: argparse._SubParsersAction) -> None:
    """Registers ``drake-uuv variants``."""
    add_listing(
        subparsers, "variants", "list every slot's variants with a one-line description", _variants
    )
