"""Monte Carlo studies: many seeded runs of a scenario, their statistics, and comparisons.

Run ``i`` of a study uses seed ``scenario.random_seed + i``; a study gives bit-identical
``runs.csv`` and ``summary.json`` on one core, many, or a Dask cluster, and a resumed study
computes only the runs not yet on disk. The modules, lowest first (each imports only modules
before it in this list):

* :mod:`~drake_uuv.studies.study`: :class:`Study`, :class:`StudyResult`,
  :class:`MonteCarloError`;
* :mod:`~drake_uuv.studies.runner`: running seeds in one process (:func:`run_seeds`);
* :mod:`~drake_uuv.studies.storage`: the study folder (parts, resume, ``runs.csv``);
* :mod:`~drake_uuv.studies.statistics`: :func:`summarize` and the Monte Carlo PCRLB;
* :mod:`~drake_uuv.studies.report`: the terminal text (:func:`format_summary`);
* :mod:`~drake_uuv.studies.execution`: chunks, the process pool, Dask (:func:`run_studies`);
* :mod:`~drake_uuv.studies.comparison`: variants and tables (:func:`compare`);
* :mod:`~drake_uuv.studies.estimate`: the wall time of a batch, from one timed run of each
  configuration (:func:`estimate_wall_time`);
* :mod:`~drake_uuv.studies.groups`: named groups of variants (:class:`Group`) and the loader
  of a studies folder (:func:`load_groups`).

None of them holds a study: the groups of ``drake-uuv compare`` and the results page's
sections live in the repository's ``studies/`` folder, beside the package.

None of them imports the command line (:mod:`drake_uuv.cli`).
"""

from drake_uuv.studies.comparison import (
    BaseScenario,
    Variant,
    compare,
    csv_table,
    markdown_table,
    ratio_tables,
    short_name,
    variant_studies,
)
from drake_uuv.studies.estimate import (
    WallTimeEstimate,
    configuration,
    estimate_wall_time,
    format_estimate,
)
from drake_uuv.studies.execution import default_workers, finish_study, run_studies, run_study
from drake_uuv.studies.groups import (
    LIST,
    Group,
    compare_groups,
    default_studies_folder,
    format_group_list,
    group_variants,
    load_groups,
    load_studies,
    select_groups,
)
from drake_uuv.studies.report import format_summary
from drake_uuv.studies.runner import NORMS, information_exponent, run_seeds
from drake_uuv.studies.statistics import (
    BOUND_METHOD,
    BOUNDED_TRACKING_THRESHOLD,
    DIVERGENCE_THRESHOLD,
    INTERVAL_METHOD,
    NEEDED_METRICS,
    bound_summary,
    monte_carlo_bound,
    summarize,
)
from drake_uuv.studies.storage import completed_seeds, load_information, load_runs
from drake_uuv.studies.study import MonteCarloError, Study, StudyResult

__all__ = [
    "BaseScenario",
    "BOUNDED_TRACKING_THRESHOLD",
    "BOUND_METHOD",
    "DIVERGENCE_THRESHOLD",
    "Group",
    "INTERVAL_METHOD",
    "LIST",
    "MonteCarloError",
    "NEEDED_METRICS",
    "NORMS",
    "Study",
    "StudyResult",
    "Variant",
    "WallTimeEstimate",
    "bound_summary",
    "compare",
    "compare_groups",
    "completed_seeds",
    "configuration",
    "csv_table",
    "default_studies_folder",
    "default_workers",
    "estimate_wall_time",
    "finish_study",
    "format_estimate",
    "format_group_list",
    "format_summary",
    "group_variants",
    "information_exponent",
    "load_groups",
    "load_information",
    "load_runs",
    "load_studies",
    "markdown_table",
    "monte_carlo_bound",
    "ratio_tables",
    "run_seeds",
    "run_studies",
    "run_study",
    "select_groups",
    "short_name",
    "summarize",
    "variant_studies",
]
