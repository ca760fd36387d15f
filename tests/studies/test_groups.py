"""The registry of groups: loading a studies folder by its path, choosing groups, listing them."""

import sys
from pathlib import Path

import numpy as np
import pytest

import drake_uuv
from drake_uuv.studies import BaseScenario, Group, MonteCarloError, StudyResult, Variant
from drake_uuv.studies import comparison as comparison_module
from drake_uuv.studies import groups as registry
from tests.conftest import STUDIES
from tests.studies.study_helpers import SHORT

# A studies folder of two groups, one in a sibling module imported relatively.
INIT = """
from drake_uuv.studies import Group, Variant

from .more import SECOND

def first():
    return [Variant("a", "first", ("attitude=!FixedAttitude",)), Variant("b", "first", ())]

GROUPS = [Group("first", "the first group", first, paper=True), SECOND]
"""
MORE = """
from drake_uuv.studies import Group, Variant

SECOND = Group("second", "the second one", lambda: [Variant("c", "second", ())])
"""


def _folder(root: Path, init: str = INIT, **modules: str) -> Path:
    folder = root / "my_studies"
    folder.mkdir(exist_ok=True)
    (folder / "__init__.py").write_text(init)
    for name, text in {"more": MORE, **modules}.items():
        (folder / f"{name}.py").write_text(text)
    return folder


def test_a_folder_is_loaded_by_its_path_once_without_touching_sys_path(tmp_path):
    folder = _folder(tmp_path)
    path = list(sys.path)
    groups = registry.load_groups(folder)
    assert sys.path == path
    assert list(groups) == ["first", "second"]
    assert [v.name for v in registry.group_variants(list(groups.values()))] == ["a", "b", "c"]
    module = registry.load_studies(folder)
    assert module is registry.load_studies(
        folder / ".." / folder.name
    )  # the same folder: loaded once
    assert module.__name__.startswith("studies_") and not module.__name__.startswith("drake_uuv")
    assert Path(module.__file__) == (folder / "__init__.py").resolve()


def test_a_folder_that_fails_to_load_is_forgotten_and_loads_once_mended(tmp_path):
    folder = _folder(tmp_path, more="raise RuntimeError('broken sibling')\n")
    with pytest.raises(RuntimeError, match="^broken sibling$"):
        registry.load_groups(folder)
    (folder / "more.py").write_text(MORE)
    assert list(registry.load_groups(folder)) == ["first", "second"]


@pytest.mark.parametrize(
    ("init", "why"),
    [
        ("X = 1\n", "its __init__.py defines no GROUPS"),
        ("GROUPS = []\n", "its __init__.py defines no GROUPS"),
        ("GROUPS = ['alpha']\n", "GROUPS holds 'alpha', not a drake_uuv.studies.Group"),
        (
            "from drake_uuv.studies import Group\n"
            "GROUPS = [Group('g', 'one', list), Group('g', 'two', list)]\n",
            "GROUPS names 'g' twice",
        ),
        (
            "from drake_uuv.studies import Group\nGROUPS = [Group('list', 'one', list)]\n",
            "GROUPS names 'list', which --group reserves for listing the groups",
        ),
    ],
)
def test_a_folder_without_valid_groups_is_refused_naming_it(tmp_path, init, why):
    folder = tmp_path / "studies"
    folder.mkdir()
    (folder / "__init__.py").write_text(init)
    with pytest.raises(MonteCarloError) as error:
        registry.load_groups(folder)
    assert str(error.value) == f"--studies: no study groups in {folder.resolve()} ({why})"


def test_a_missing_folder_is_refused_naming_it(tmp_path):
    with pytest.raises(MonteCarloError) as error:
        registry.load_groups(tmp_path / "nowhere")
    assert str(error.value) == (
        f"--studies: no study groups in {tmp_path / 'nowhere'} "
        "(no __init__.py there; pass --studies DIR)"
    )


def test_the_default_folder_is_the_checkout_s_studies_beside_the_package():
    assert (
        registry.default_studies_folder()
        == Path(drake_uuv.__file__).resolve().parents[1] / "studies"
    )
    assert registry.default_studies_folder() == STUDIES.resolve()


def _groups() -> dict[str, Group]:
    one = Group("one", "first", lambda: [Variant("x", "one", ())], paper=True)
    two = Group("two", "second, longer", lambda: [Variant(f"y{i}", "two", ()) for i in range(3)])
    three = Group("three", "third", lambda: [], paper=True)
    return {g.name: g for g in (one, two, three)}


def test_select_groups_defaults_to_the_paper_s_and_refuses_unknown_names():
    groups = _groups()
    assert [g.name for g in registry.select_groups(groups, None)] == ["one", "three"]
    assert [g.name for g in registry.select_groups(groups, [])] == ["one", "three"]
    assert [g.name for g in registry.select_groups(groups, ["two", "one", "two"])] == ["two", "one"]
    with pytest.raises(
        MonteCarloError, match=r"^--group: unknown group 'bogus' \(known: one, two, three\)$"
    ):
        registry.select_groups(groups, ["one", "bogus"])
    unmarked = {"two": groups["two"]}
    with pytest.raises(
        MonteCarloError,
        match=r"^--group: no group is marked as the paper's; name one \(known: two\)$",
    ):
        registry.select_groups(unmarked, None)


def test_group_list_gives_variants_runs_and_description_and_marks_the_paper_s():
    assert registry.format_group_list(_groups(), 25) == (
        "group   variants    runs  description\n"
        "one*           1      25  first\n"
        "two            3      75  second, longer\n"
        "three*         0       0  third\n"
        "runs at --runs 25; * the paper's groups, run when no --group is given"
    )


def test_compare_groups_names_its_groups_in_compare_md(tmp_path, monkeypatch):
    def fake_run_studies(studies, **options):
        return [
            StudyResult(s, np.arange(s.runs), [], np.empty((s.runs, 0)), None, {"runs": 1}, 1)
            for s in studies
        ]

    monkeypatch.setattr(comparison_module, "run_studies", fake_run_studies)
    groups = _groups()
    result = registry.compare_groups(
        [groups["two"], groups["one"]], tmp_path, 1, base=BaseScenario(overrides=SHORT), workers=1
    )
    assert [variant.name for variant, _ in result] == ["y0", "y1", "y2", "x"]
    command = "drake-uuv compare --runs 1 --set steps=80 --set steady_state_start=40"
    assert f"Made by `{command} --group two --group one`." in (tmp_path / "compare.md").read_text()
