"""Comparison tables: Monte Carlo studies of named scenario variants, side by side.

A :class:`Variant` is a name and a list of ``--set`` overrides applied on top of the base
scenario. :func:`compare` runs every variant it is given as one Monte Carlo batch (one process
pool or Dask cluster for all) and writes ``DIR/compare.md`` (one table per group of variants,
:func:`markdown_table`) and ``DIR/compare.csv`` (one row per variant, :func:`csv_table`), with
each variant's study in ``DIR/studies/<variant>/``. Variants marked ``ratio_table`` (an
estimator × attitude grid) add the ratio tables RMSE / PCRLB (:func:`ratio_tables`) to
``compare.md``, and every row of ``compare.csv`` carries the bounds and ratios of its summary.

This module holds no study: the named groups of variants (the paper's claims, the vehicle,
the estimators' regimes, ...) live in the repository's ``studies/`` folder, found and loaded
by :mod:`drake_uuv.studies.groups`. (The module is ``comparison``, not ``compare``, so that the
:func:`compare` re-exported by :mod:`drake_uuv.studies` does not shadow it:
``import drake_uuv.studies.compare as m`` would otherwise yield the function.)
"""

import csv
import io
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drake_uuv.io import write_text_atomic
from drake_uuv.scenario import ALPHA_PROVEN_INTERVAL, load_scenario
from drake_uuv.studies.execution import run_studies
from drake_uuv.studies.study import Study, StudyResult


@dataclass(frozen=True)
class Variant:
    """A named row of a comparison: ``--set`` overrides on top of the base scenario."""

    name: str
    # The title of the variant's table in compare.md (its group of rows).
    group: str
    overrides: tuple[str, ...]
    # Shown in the Markdown table's "note" column (e.g. whether α is in the proven interval).
    note: str = ""
    # A cell of the RMSE / PCRLB tables (:func:`ratio_tables`): the variant then chooses its
    # estimator and attitude variants by tag (``estimator=!Ekf``, ``attitude=!FixedAttitude``).
    ratio_table: bool = False
    # A shipped scenario (or file) the variant starts from instead of the comparison's base
    # (whose overrides and seed still apply first): e.g. the ``realistic`` scenario's rows.
    scenario: str | None = None
    # The share of the comparison's --runs this row runs (at least one): a row that costs
    # much more a run (the hovering UUV) may run fewer.
    run_fraction: float = 1.0

    def runs(self, runs: int) -> int:
        """The runs of this row at the comparison's ``runs``."""
        return max(1, round(runs * self.run_fraction))


# Short names of variants in row names ("kf-trajectory"); others use their tag in snake case.
SHORT_NAMES = {
    "PaperKf": "kf", "Ekf": "ekf", "Iekf": "iekf",
    "TrajectoryAttitude": "trajectory", "RandomAttitude": "random", "FixedAttitude": "fixed",
    "PaperTracking": "paper", "LqrTracking": "lqr",
}  # fmt: skip


def short_name(tag: str) -> str:
    """A variant's name in row names: :data:`SHORT_NAMES`, or its tag in snake case."""
    return SHORT_NAMES.get(tag) or re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", tag).lower()


# Columns of the tables: (CSV name, Markdown header, summary key, format).
_COLUMNS: list[tuple[str, str, str, str]] = [
    ("position_rmse", "position RMSE [m]", "position_rmse", ".3g"),
    ("velocity_rmse", "velocity RMSE [m/s]", "velocity_rmse", ".3g"),
    ("tracking_rmse", "tracking RMSE [m]", "tracking_rmse", ".3g"),
    ("nees_mean", "mean NEES (6)", "nees_mean", ".3g"),
    ("diverged_fraction", "diverged", "diverged_fraction", ".0%"),
    ("tracking_bounded_fraction", "tracking bounded", "tracking_bounded_fraction", ".0%"),
    ("warned_fraction", "warned", "warned_fraction", ".0%"),
    ("relative_speed_mean", "mean relative speed [m/s]", "relative_speed_mean", ".3g"),
    ("relative_speed_peak", "peak relative speed [m/s]", "relative_speed_peak", ".3g"),
    ("acceleration_mean", "mean acceleration [m/s²]", "acceleration_mean", ".3g"),
    ("acceleration_peak", "peak acceleration [m/s²]", "acceleration_peak", ".3g"),
]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name)


def _number(value: float | None, fmt: str) -> str:
    return "—" if value is None else format(value, fmt)


def _cell(summary: dict[str, Any], key: str, fmt: str) -> str:
    text = _number(summary.get(key), fmt)
    interval = summary.get(f"{key}_ci95")
    if interval is not None and key.endswith(("rmse", "nees_mean")):
        text += f" [{_number(interval[0], fmt)}, {_number(interval[1], fmt)}]"
    return text


def markdown_table(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """One Markdown table per group: variant, overrides, runs, then :data:`_COLUMNS`."""
    out: list[str] = []
    groups = list(dict.fromkeys(variant.group for variant, _ in rows))
    for group in groups:
        out.append(f"### {group}\n")
        members = [(variant, summary) for variant, summary in rows if variant.group == group]
        notes = any(variant.note for variant, _ in members)
        headers = ["variant", *(["note"] if notes else []), "runs"]
        headers += [header for _, header, _, _ in _COLUMNS]
        out.append("| " + " | ".join(headers) + " |")
        aligns = ["---"] * (2 if notes else 1) + ["---:"] * (len(headers) - (2 if notes else 1))
        out.append("|" + "|".join(aligns) + "|")
        for variant, summary in members:
            cells = [variant.name, *([variant.note] if notes else []), str(summary["runs"])]
            cells += [_cell(summary, key, fmt) for _, _, key, fmt in _COLUMNS]
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


# The bound columns of the CSV (summary keys, see drake_uuv.studies.statistics.summarize).
_BOUND_COLUMNS = [
    "pcrlb_position_rmse",
    "pcrlb_velocity_rmse",
    "pcrlb_per_run_position_rmse",
    "pcrlb_per_run_velocity_rmse",
    "kf_riccati_position_rmse",
    "kf_riccati_velocity_rmse",
    "position_rmse_over_pcrlb",
    "velocity_rmse_over_pcrlb",
    "position_rmse_over_per_run_pcrlb",
    "velocity_rmse_over_per_run_pcrlb",
]


def _settings(variant: Variant) -> dict[str, str]:
    return dict(override.split("=", 1) for override in variant.overrides)


def ratio_tables(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """Markdown: estimator × attitude mode → RMSE / PCRLB, position and velocity.

    Two tables from the rows whose variant is marked ``ratio_table`` (empty string if there
    are none): against the Monte Carlo PCRLB (the proven bound) and against the mean of the
    per-run bounds (what a run-by-run efficient estimator attains; see
    :mod:`drake_uuv.models.pcrlb`). Each cell is ``position / velocity``.
    """
    cells: dict[tuple[str, str], dict[str, Any]] = {}
    for variant, summary in rows:
        if variant.ratio_table:
            settings = _settings(variant)
            if "estimator" not in settings or "attitude" not in settings:
                raise ValueError(
                    f"ratio_table: variant {variant.name!r} must set both estimator=!Tag and "
                    f"attitude=!Tag, got {' '.join(variant.overrides)!r}"
                )
            estimator = short_name(settings["estimator"].removeprefix("!"))
            cells[estimator, short_name(settings["attitude"].removeprefix("!"))] = summary
    if not cells:
        return ""
    estimators = list(dict.fromkeys(estimator for estimator, _ in cells))
    modes = list(dict.fromkeys(mode for _, mode in cells))
    out = []
    for suffix, title in (
        ("pcrlb", "RMSE / PCRLB (Monte Carlo bound: information averaged over runs)"),
        ("per_run_pcrlb", "RMSE / mean of per-run bounds (each along its own trajectory)"),
    ):
        out.append(f"### {title}, position / velocity\n")
        out.append("| estimator | " + " | ".join(modes) + " |")
        out.append("|---|" + "|".join("---:" for _ in modes) + "|")
        for estimator in estimators:
            row = [estimator]
            for mode in modes:
                summary = cells.get((estimator, mode), {})
                row.append(
                    f"{_number(summary.get(f'position_rmse_over_{suffix}'), '.3g')} / "
                    f"{_number(summary.get(f'velocity_rmse_over_{suffix}'), '.3g')}"
                )
            out.append("| " + " | ".join(row) + " |")
        out.append("")
    return "\n".join(out)


def csv_table(rows: Sequence[tuple[Variant, dict[str, Any]]]) -> str:
    """One CSV row per variant with every number of its summary and the 95 % bounds."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    names = [name for name, _, _, _ in _COLUMNS]
    header = ["group", "variant", "note", "overrides", "runs"]
    for name in names:
        header.append(name)
        if name.endswith(("rmse", "nees_mean", "fraction")):
            header += [f"{name}_ci95_low", f"{name}_ci95_high"]
    header += _BOUND_COLUMNS
    writer.writerow(header)
    for variant, summary in rows:
        row: list[Any] = [variant.group, variant.name, variant.note, " ".join(variant.overrides)]
        row.append(summary["runs"])
        for name in names:
            row.append(summary.get(name))
            if name.endswith(("rmse", "nees_mean", "fraction")):
                row += list(summary.get(f"{name}_ci95", [None, None]))
        row += [summary.get(name) for name in _BOUND_COLUMNS]
        writer.writerow(["" if v is None else v for v in row])
    return buffer.getvalue()


@dataclass(frozen=True)
class BaseScenario:
    """What every variant of a comparison starts from: a scenario (shipped name or YAML path),
    ``--set`` overrides applied before the variant's own, and a ``random_seed`` override."""

    name: str = "paper"
    overrides: tuple[str, ...] = ()
    seed: int | None = None

    def command(self, runs: int, groups: Sequence[str]) -> str:
        """The ``drake-uuv compare`` line that repeats a comparison of named groups."""
        command = "drake-uuv compare" + ("" if self.name == "paper" else f" --scenario {self.name}")
        command += f" --runs {runs}" + ("" if self.seed is None else f" --seed {self.seed}")
        command += "".join(f" --set {o}" for o in self.overrides)
        return command + "".join(f" --group {name}" for name in groups)


def variant_studies(
    variants: Sequence[Variant], out_dir: Path, runs: int, base: BaseScenario = BaseScenario()
) -> list[Study]:
    """The study of each variant: ``base`` and then the variant's overrides, ``runs`` runs
    (its share of them, :meth:`Variant.runs`) in ``out_dir/studies/<variant>``."""
    return [
        Study(
            variant.name,
            load_scenario(
                variant.scenario or base.name,
                [*base.overrides, *variant.overrides],
                seed=base.seed,
            ),
            variant.runs(runs),
            Path(out_dir) / "studies" / _slug(variant.name),
        )
        for variant in variants
    ]


def compare(
    variants: Sequence[Variant],
    out_dir: Path,
    runs: int,
    base: BaseScenario = BaseScenario(),
    groups: Sequence[str] = (),
    **execution: Any,
) -> list[tuple[Variant, StudyResult]]:
    """Runs every variant's study; writes ``compare.md`` and ``compare.csv`` in ``out_dir``.

    ``groups``: the names of the groups the variants come from, for the command that
    ``compare.md`` says made it (``drake-uuv compare ... --group NAME``); without them it names
    this function. ``execution``: keywords of :func:`drake_uuv.studies.execution.run_studies`
    (workers, scheduler, resume, progress).
    """
    out_dir = Path(out_dir)
    studies = variant_studies(variants, out_dir, runs, base)
    execution.setdefault("figures", False)
    results = run_studies(studies, **execution)
    rows = [(variant, result.summary) for variant, result in zip(variants, results, strict=True)]
    low, high = ALPHA_PROVEN_INTERVAL
    made_by = (
        f"`{base.command(runs, groups)}`"
        if groups
        else f"`drake_uuv.studies.compare` ({len(variants)} variants)"
    )
    header = (
        f"# Comparison ({base.name} scenario, {runs} runs per variant)\n\n"
        f"Made by {made_by}. Metrics over the steady-state window; brackets are 95 % "
        "intervals (bootstrap over runs). *diverged*: final position error > 10 m; "
        "*tracking bounded*: steady-state tracking error stays < 10 m. The paper proves "
        f"bounded tracking for α in ({low:.4f}, {high:.4f}).\n\n"
    )
    ratios = ratio_tables(rows)
    if ratios:
        ratios = (
            "\n## Estimators against the posterior Cramér–Rao bound\n\n"
            "Steady-state RMSE over the bound's RMS (√ mean trace), position / velocity. "
            "The bound is for the raw two-range measurement with all f samples, evaluated on "
            "each variant's own true trajectories.\n\n" + ratios
        )
    write_text_atomic(out_dir / "compare.md", header + markdown_table(rows) + ratios)
    write_text_atomic(out_dir / "compare.csv", csv_table(rows))
    return list(zip(variants, results, strict=True))
