"""The study folder: parts on disk, resume checks, loading runs in seed order, runs.csv.

No simulation here: the chunks are synthetic (study_helpers.synthetic_chunk), so every
value tells which seed it came from.
"""

import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from drake_uuv.studies import MonteCarloError, Study
from drake_uuv.studies.runner import information_exponent
from drake_uuv.studies.storage import (
    completed_seeds,
    load_information,
    load_runs,
    missing_seeds,
    prepare,
    read_parts,
    runs_csv,
    write_outputs,
    write_part,
)
from tests.studies.study_helpers import synthetic_chunk


def _prepared(folder, short, runs=3) -> Study:
    study = Study("test", short, runs, folder)
    prepare(study, resume=False)
    return study


def test_a_part_round_trips_and_is_named_by_its_first_seed_and_count(tmp_path):
    chunk = synthetic_chunk([3, 4])
    path = write_part(tmp_path, chunk)
    assert path == tmp_path / "runs" / "part-0000000003-2.npz"
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [path.name]  # no temp file
    write_part(tmp_path, synthetic_chunk([0], information=False))
    first, second = read_parts(tmp_path)  # in seed order, whatever the writing order
    assert first["seeds"].tolist() == [0] and first["information_sum"] is None
    assert second["metric_names"] == ["position_rmse", "failed"]
    for key in ("seeds", "metrics", "norms", "information_sum"):
        np.testing.assert_array_equal(second[key], chunk[key])
    assert completed_seeds(tmp_path) == {0, 3, 4}


def test_prepare_writes_the_study_file_and_clears_old_runs(tmp_path, short):
    write_part(tmp_path, synthetic_chunk([0, 1]))
    (tmp_path / "runs" / ".part-0000000002-1.npz.abc.tmp").write_bytes(b"half")
    study = _prepared(tmp_path, short)
    assert list((tmp_path / "runs").iterdir()) == []
    stored = json.loads((tmp_path / "study.json").read_text())
    assert stored["schema"] == 1 and stored["name"] == "test"
    assert stored["scenario"]["steps"] == 80 and stored["scenario"]["random_seed"] == 0
    assert missing_seeds(study, resume=False) == [0, 1, 2]


def test_resume_keeps_runs_of_the_same_scenario_and_drops_half_written_parts(tmp_path, short):
    study = _prepared(tmp_path, short)
    write_part(tmp_path, synthetic_chunk([1]))
    (tmp_path / "runs" / ".part-0000000002-1.npz.abc.tmp").write_bytes(b"half")
    prepare(study, resume=True)
    assert [p.name for p in (tmp_path / "runs").iterdir()] == ["part-0000000001-1.npz"]
    assert missing_seeds(study, resume=True) == [0, 2]
    assert missing_seeds(study, resume=False) == [0, 1, 2]


def test_resume_refuses_a_folder_of_another_scenario_naming_the_field(tmp_path, short):
    _prepared(tmp_path, short)
    other = Study("test", dataclasses.replace(short, steps=90), 3, tmp_path)
    with pytest.raises(
        MonteCarloError,
        match=r"^--resume: .* holds runs of another scenario: steps \(80 on disk, 90 now\)$",
    ):
        prepare(other, resume=True)


def test_resume_takes_a_field_newer_than_the_runs_at_its_default_only(tmp_path, short):
    """Runs stored before a field existed: resumed where the field is at its default (a
    field added with a default keeps what the package did before it), refused otherwise."""
    study = _prepared(tmp_path, short)
    marker = tmp_path / "study.json"
    stored = json.loads(marker.read_text())
    del stored["scenario"]["sonar"]["latency"]  # as written before sonar.latency existed
    del stored["scenario"]["steps"]  # 80 here, not its default (500): a difference
    marker.write_text(json.dumps(stored))
    with pytest.raises(MonteCarloError, match=r"holds runs of another scenario: steps \(None on"):
        prepare(study, resume=True)
    stored["scenario"]["steps"] = short.steps
    marker.write_text(json.dumps(stored))
    prepare(study, resume=True)
    marker.write_text(json.dumps(stored))
    later = Study("test", dataclasses.replace(
        short, sonar=dataclasses.replace(short.sonar, latency=0.1)), 3, tmp_path
    )  # fmt: skip
    with pytest.raises(
        MonteCarloError,
        match=r"holds runs of another scenario: sonar\.latency \(None on disk, 0\.1 now\)$",
    ):
        prepare(later, resume=True)


def test_resume_refuses_runs_without_a_study_file(tmp_path, short):
    write_part(tmp_path, synthetic_chunk([0]))
    with pytest.raises(MonteCarloError, match=r"^--resume: .* has runs but no study\.json$"):
        prepare(Study("test", short, 3, tmp_path), resume=True)


def test_load_runs_in_seed_order_ignoring_runs_outside_the_study(tmp_path, short):
    study = _prepared(tmp_path, short)
    write_part(tmp_path, synthetic_chunk([2, 3]))  # seed 3 is beyond the study's three runs
    write_part(tmp_path, synthetic_chunk([0], names=("failed",)))  # a failed run only
    write_part(tmp_path, synthetic_chunk([1]))
    seeds, names, metrics, norms = load_runs(study)
    assert seeds.tolist() == [0, 1, 2]
    assert names == ["position_rmse", "failed"]  # a completed run's names, not the failed one's
    np.testing.assert_array_equal(metrics[1:], [[1.0, 1.1], [2.0, 2.1]])
    assert math.isnan(metrics[0, 0]) and metrics[0, 1] == 0.0  # seed 0's only metric: 0 + 0/10
    np.testing.assert_array_equal(norms[:, 0, 0], [0.0, 1.0, 2.0])


def test_load_runs_names_how_many_runs_are_missing(tmp_path, short):
    study = _prepared(tmp_path, short)
    write_part(tmp_path, synthetic_chunk([0, 2]))
    with pytest.raises(MonteCarloError, match=r": 1 of 3 runs are missing$"):
        load_runs(study)


def test_load_information_adds_the_parts_exactly_and_scales_them(tmp_path, short):
    study = _prepared(tmp_path, short)
    write_part(tmp_path, synthetic_chunk([0, 1]))
    assert load_information(study) is None  # seed 2 is missing
    write_part(tmp_path, synthetic_chunk([2]))
    information = load_information(study)
    assert information.shape == (4, 6, 6)
    unit = 2.0 ** -information_exponent(short)
    np.testing.assert_array_equal(information[:, :3, :3], np.full((4, 3, 3), 3 * unit))
    assert not information[:, 3:, :].any() and not information[:, :, 3:].any()


@pytest.mark.parametrize(
    ("runs", "parts"),
    [
        (3, [[0, 1], [2, 3]]),  # the last part reaches beyond the study: its sum cannot be split
        (2, [[0, 1, 2]]),  # one part holding the whole study and one more run
    ],
)
def test_load_information_is_none_when_a_part_straddles_the_study(tmp_path, short, runs, parts):
    study = _prepared(tmp_path, short, runs=runs)
    for seeds in parts:
        write_part(tmp_path, synthetic_chunk(seeds))
    assert load_information(study) is None


def test_load_information_is_none_when_a_part_has_none(tmp_path, short):
    study = _prepared(tmp_path, short)
    write_part(tmp_path, synthetic_chunk([0, 1]))
    write_part(tmp_path, synthetic_chunk([2], information=False))
    assert load_information(study) is None


def test_runs_csv_round_trips_every_float(tmp_path):
    values = np.array([[0.1 + 0.2, math.nan], [1e-300, -math.inf]])
    text = runs_csv(np.array([5, 6]), ["a", "b"], values)
    assert text.splitlines()[0] == "seed,a,b"
    rows = list(csv.reader(text.splitlines()[1:]))
    assert [row[0] for row in rows] == ["5", "6"]
    read = np.array([[float(v) for v in row[1:]] for row in rows])
    np.testing.assert_array_equal(read, values)  # bit for bit, NaN and inf included
    write_outputs(tmp_path, np.array([5, 6]), ["a", "b"], values, {"runs": 2})
    assert (tmp_path / "runs.csv").read_text() == text
    assert json.loads((tmp_path / "summary.json").read_text()) == {"runs": 2}


def test_a_default_that_is_not_plain_data_is_never_assumed():
    """A field whose default is an array is left out of the defaults tree (a run stored
    without it is then a difference), as is a field without a default."""
    from drake_uuv.studies.storage import _Default, _defaults

    @dataclasses.dataclass
    class Section:
        required: int
        array: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))
        plain: tuple[float, ...] = (1.0, 2.0)

    tree = _defaults(Section(required=3))
    assert set(tree) == {"plain"}
    assert isinstance(tree["plain"], _Default) and tree["plain"].value == [1.0, 2.0]
