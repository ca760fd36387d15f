"""`drake-uuv variants`: every registered variant, each slot's default marked, read from the
registry so that a new variant appears without an edit."""

from drake_uuv.cli import main
from drake_uuv.cli.variants import summary, variant_table
from drake_uuv.diagram import SLOT_REGISTRY
from drake_uuv.scenario import Scenario, variants


def test_lists_every_variant_of_every_slot_with_its_default(capsys) -> None:
    assert main(["variants"]) == 0
    out = capsys.readouterr().out
    for slot in SLOT_REGISTRY:
        assert f"{slot.section} (system {slot.system!r}" in out
        for tag in variants(Scenario, slot.section):
            assert f"\n  {tag} " in out
        assert f"--set {slot.section}=<variant>" in out
    assert "!" not in out  # the tag form is history expansion in an interactive bash
    assert out.count("(default)") == len(SLOT_REGISTRY)
    rows = variant_table()
    assert {name for _, _, name, _ in rows} == {
        tag for slot in SLOT_REGISTRY for tag in variants(Scenario, slot.section)
    }


def test_the_description_is_the_docstrings_first_sentence() -> None:
    class Probe:
        """A probe, with ``code``. More words here.

        A second paragraph."""

    assert summary(Probe) == "A probe, with code"
