"""Moved: Monte Carlo studies now live in :mod:`drake_uuv.studies`; this module re-exports them.

Kept for one release so that ``from drake_uuv.montecarlo import Study, run_study`` keeps
working; import from :mod:`drake_uuv.studies` instead. Where things went:

* running seeds (``run_seeds``, ``information_exponent``, ``NORMS``):
  :mod:`drake_uuv.studies.runner`;
* the study folder (``completed_seeds``, ``load_runs``, ``load_information``):
  :mod:`drake_uuv.studies.storage`;
* ``summarize``, ``bound_summary``, ``monte_carlo_bound`` and the thresholds:
  :mod:`drake_uuv.studies.statistics`;
* ``format_summary``: :mod:`drake_uuv.studies.report`;
* ``run_studies``, ``run_study``, ``finish_study``, ``default_workers``:
  :mod:`drake_uuv.studies.execution`;
* ``Study``, ``StudyResult``, ``MonteCarloError``: :mod:`drake_uuv.studies.study`;
* the ``drake-uuv montecarlo`` subcommand and ``add_execution_options``,
  ``execution_options``: :mod:`drake_uuv.cli.montecarlo` and :mod:`drake_uuv.cli.options`
  (not re-exported here: the studies layer does not import the command line).
"""

from drake_uuv.studies.execution import default_workers, finish_study, run_studies, run_study
from drake_uuv.studies.report import format_summary
from drake_uuv.studies.runner import NORMS, information_exponent, run_seeds
from drake_uuv.studies.statistics import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
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
    "BOOTSTRAP_RESAMPLES",
    "BOOTSTRAP_SEED",
    "BOUNDED_TRACKING_THRESHOLD",
    "BOUND_METHOD",
    "DIVERGENCE_THRESHOLD",
    "INTERVAL_METHOD",
    "NEEDED_METRICS",
    "NORMS",
    "MonteCarloError",
    "Study",
    "StudyResult",
    "bound_summary",
    "completed_seeds",
    "default_workers",
    "finish_study",
    "format_summary",
    "information_exponent",
    "load_information",
    "load_runs",
    "monte_carlo_bound",
    "run_seeds",
    "run_studies",
    "run_study",
    "summarize",
]
