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
* :mod:`~drake_uuv.studies.comparison`: variants, groups and tables (:func:`compare`).

None of them imports the command line (:mod:`drake_uuv.cli`).
"""

from drake_uuv.studies.comparison import (
    ALPHAS,
    ESTIMATOR_GROUP,
    VARIANT_GROUPS,
    Variant,
    alpha_sweep_variants,
    attitude_noise_variants,
    compare,
    csv_table,
    estimator_attitude_variants,
    markdown_table,
    ratio_tables,
    selected_variants,
    tracking_law_variants,
)
from drake_uuv.studies.execution import default_workers, finish_study, run_studies, run_study
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
    "ALPHAS",
    "BOUNDED_TRACKING_THRESHOLD",
    "BOUND_METHOD",
    "DIVERGENCE_THRESHOLD",
    "ESTIMATOR_GROUP",
    "INTERVAL_METHOD",
    "NEEDED_METRICS",
    "NORMS",
    "VARIANT_GROUPS",
    "MonteCarloError",
    "Study",
    "StudyResult",
    "Variant",
    "alpha_sweep_variants",
    "attitude_noise_variants",
    "bound_summary",
    "compare",
    "completed_seeds",
    "csv_table",
    "default_workers",
    "estimator_attitude_variants",
    "finish_study",
    "format_summary",
    "information_exponent",
    "load_information",
    "load_runs",
    "markdown_table",
    "monte_carlo_bound",
    "ratio_tables",
    "run_seeds",
    "run_studies",
    "run_study",
    "selected_variants",
    "summarize",
    "tracking_law_variants",
]
