"""The study folder on disk: ``study.json``, the chunk parts, resume checks, ``runs.csv``.

Layout of a study folder ``DIR``:

* ``DIR/study.json``: ``{"schema", "name", "scenario"}``, the scenario the runs belong to;
  a resume against a different scenario is refused, naming the first field that differs;
* ``DIR/runs/part-<first seed, 10 digits>-<count>.npz``: one finished chunk of runs
  (``seeds``, ``metric_names``, ``metrics``, ``norms`` and, when exact, ``information_sum``;
  see :func:`drake_uuv.studies.runner.run_seeds`), written atomically through
  :mod:`drake_uuv.io` as soon as the chunk is done, so an interrupted study keeps every
  finished chunk whole and a resume computes only the seeds no part holds;
* ``DIR/runs.csv``: one row per run, ``seed`` then every metric, in seed order;
* ``DIR/summary.json``: the summary (:func:`drake_uuv.studies.statistics.summarize`).
"""

import csv
import dataclasses
import io
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from drake_uuv.io import write_atomic, write_json_atomic, write_text_atomic
from drake_uuv.scenario import scenario_as_dict
from drake_uuv.studies.runner import canonical_metric_names, information_exponent
from drake_uuv.studies.study import MonteCarloError, Study

SCHEMA = 1
STUDY_FILE = "study.json"
PARTS = "runs"
RUNS_CSV = "runs.csv"
SUMMARY_JSON = "summary.json"


def parts_dir(out_dir: Path) -> Path:
    """The folder of a study's chunk parts."""
    return Path(out_dir) / PARTS


def write_part(out_dir: Path, chunk: dict[str, Any]) -> Path:
    """Writes one chunk of :func:`~drake_uuv.studies.runner.run_seeds` atomically."""
    seeds = chunk["seeds"]
    path = parts_dir(out_dir) / f"part-{int(seeds[0]):010d}-{len(seeds)}.npz"
    arrays = {
        "seeds": seeds,
        "metric_names": np.asarray(chunk["metric_names"]),
        "metrics": chunk["metrics"],
        "norms": chunk["norms"],
    }
    if chunk.get("information_sum") is not None:
        arrays["information_sum"] = chunk["information_sum"]
    return write_atomic(path, lambda f: np.savez(f, **arrays))


def read_parts(out_dir: Path) -> Iterator[dict[str, Any]]:
    """Every chunk part of the folder, in file-name (first seed) order."""
    for path in sorted(parts_dir(out_dir).glob("part-*.npz")):
        with np.load(path) as data:
            yield {
                "seeds": data["seeds"],
                "metric_names": [str(n) for n in data["metric_names"]],
                "metrics": data["metrics"],
                "norms": data["norms"],
                "information_sum": data["information_sum"]
                if "information_sum" in data.files
                else None,
            }


def completed_seeds(out_dir: Path) -> set[int]:
    """Seeds whose runs are on disk in ``out_dir/runs/``."""
    done: set[int] = set()
    for path in parts_dir(out_dir).glob("part-*.npz"):
        with np.load(path) as data:
            done.update(int(s) for s in data["seeds"])
    return done


class _Default:
    """A field's default, as JSON data (a leaf of :func:`_defaults`' tree)."""

    def __init__(self, value: Any) -> None:
        self.value = value


def _defaults(value: Any) -> Any:
    """The tree of each dataclass field's default within ``value`` (a scenario), keyed as
    :func:`~drake_uuv.scenario.scenario_as_dict` keys the scenario: a nested dataclass is a
    dict of its fields, a field with a default a :class:`_Default`; others are left out."""
    if not dataclasses.is_dataclass(value):
        return None
    tree: dict[str, Any] = {}
    for field in dataclasses.fields(value):
        current = getattr(value, field.name)
        if dataclasses.is_dataclass(current):
            tree[field.name] = _defaults(current)
            continue
        if field.default is not dataclasses.MISSING:
            default = field.default
        elif field.default_factory is not dataclasses.MISSING:
            default = field.default_factory()
        else:
            continue
        try:  # a default that is not plain data (a dataclass, an array) is never assumed
            tree[field.name] = _Default(json.loads(json.dumps(default)))
        except TypeError:
            continue
    return tree


def _first_difference(a: Any, b: Any, prefix: str = "", defaults: Any = None) -> str | None:
    """The first dotted key where two JSON trees differ, with both values; None if equal.

    A key ``b`` has and ``a`` lacks is no difference where ``b`` holds that field's default
    (from ``defaults``, :func:`_defaults`' tree): ``a`` was written before the field existed,
    and a field added with a default keeps what the package did before it."""
    if isinstance(a, dict) and isinstance(b, dict):
        defaults = defaults if isinstance(defaults, dict) else {}
        # A slot's variant first: a different variant explains every other difference.
        for key in sorted(set(a) | set(b), key=lambda k: (k != "variant", k)):
            default = defaults.get(key)
            if key not in a and isinstance(default, _Default) and b[key] == default.value:
                continue
            found = _first_difference(a.get(key), b.get(key), f"{prefix}{key}.", default)
            if found:
                return found
        return None
    return None if a == b else f"{prefix.rstrip('.')} ({a!r} on disk, {b!r} now)"


def prepare(study: Study, resume: bool) -> None:
    """Creates the folder; on resume checks the scenario, otherwise clears old runs. A field
    the stored scenario lacks (runs written before the field existed) matches its default.

    Raises :class:`MonteCarloError` when resuming a folder of another scenario's runs, or
    one with runs but no ``study.json``.
    """
    out_dir = Path(study.out_dir)
    parts = parts_dir(out_dir)
    parts.mkdir(parents=True, exist_ok=True)
    for leftover in parts.glob(".part-*.tmp"):  # an interrupted atomic write
        leftover.unlink(missing_ok=True)
    # Through JSON so tuples compare equal to the lists read back from disk.
    scenario = json.loads(json.dumps(scenario_as_dict(study.scenario)))
    marker = out_dir / STUDY_FILE
    if resume and marker.exists():
        stored = json.loads(marker.read_text())
        difference = _first_difference(
            stored.get("scenario"), scenario, defaults=_defaults(study.scenario)
        )
        if difference:
            raise MonteCarloError(
                f"--resume: {out_dir} holds runs of another scenario: {difference}"
            )
    elif resume and any(parts.glob("part-*.npz")):
        raise MonteCarloError(f"--resume: {out_dir} has runs but no {STUDY_FILE}")
    if not resume:
        for old in parts.glob("part-*.npz"):
            old.unlink()
    write_json_atomic(marker, {"schema": SCHEMA, "name": study.name, "scenario": scenario})


def missing_seeds(study: Study, resume: bool) -> list[int]:
    """The study's seeds still to compute: all of them, or on resume those not on disk."""
    done = completed_seeds(study.out_dir) if resume else set()
    return [seed for seed in study.seeds() if seed not in done]


def load_runs(study: Study) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Seeds, metric names, metrics and norms of the study's runs, in seed order.

    Runs on disk outside the study (after a resume with fewer runs) are ignored; raises
    :class:`MonteCarloError` if any of the study's runs is missing.
    """
    wanted = set(study.seeds())
    by_seed: dict[int, tuple[dict[str, float], np.ndarray]] = {}
    name_lists: list[list[str]] = []
    for part in read_parts(study.out_dir):
        name_lists.append(part["metric_names"])
        for row, seed in enumerate(part["seeds"]):
            if int(seed) in wanted:
                values = dict(zip(part["metric_names"], part["metrics"][row], strict=True))
                by_seed[int(seed)] = (values, part["norms"][row])
    if len(by_seed) != len(wanted):
        raise MonteCarloError(
            f"{study.out_dir}: {len(wanted) - len(by_seed)} of {len(wanted)} runs are missing"
        )
    seeds = np.array(sorted(by_seed), dtype=np.int64)
    names = canonical_metric_names(name_lists)
    metrics = np.array([[by_seed[int(s)][0].get(n, math.nan) for n in names] for s in seeds])
    norms = np.stack([by_seed[int(s)][1] for s in seeds])
    return seeds, names, metrics, norms


def load_information(study: Study) -> np.ndarray | None:
    """Σ over the study's runs of the measurement information ``M(k)`` (steps × 6 × 6).

    Only the position block is stored and filled (the ranges depend on the position alone).
    None when it cannot be had exactly: a part without it (written before it
    existed, or with a non-finite or failed run) or a part that also holds runs outside the
    study (after a ``--resume`` with fewer runs).
    """
    wanted = set(study.seeds())
    total: np.ndarray | None = None
    seen: set[int] = set()
    for part in read_parts(study.out_dir):
        seeds = {int(seed) for seed in part["seeds"]}
        if not seeds & wanted:
            continue
        if part["information_sum"] is None or not seeds <= wanted or seeds & seen:
            return None
        seen |= seeds
        total = part["information_sum"] if total is None else total + part["information_sum"]
    if total is None or seen != wanted:
        return None
    information = np.zeros((total.shape[0], 6, 6))
    information[:, :3, :3] = np.ldexp(total.astype(float), -information_exponent(study.scenario))
    return information


def runs_csv(seeds: np.ndarray, names: list[str], metrics: np.ndarray) -> str:
    """The text of ``runs.csv``: ``seed`` then ``names``; floats by ``repr`` (round-trip)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["seed", *names])
    for seed, row in zip(seeds, metrics, strict=True):
        writer.writerow([int(seed), *(repr(float(v)) for v in row)])
    return buffer.getvalue()


def write_outputs(
    out_dir: Path,
    seeds: np.ndarray,
    names: list[str],
    metrics: np.ndarray,
    summary: dict[str, Any],
) -> None:
    """Writes ``runs.csv`` and ``summary.json`` atomically."""
    out_dir = Path(out_dir)
    write_text_atomic(out_dir / RUNS_CSV, runs_csv(seeds, names, metrics))
    write_json_atomic(out_dir / SUMMARY_JSON, summary)
