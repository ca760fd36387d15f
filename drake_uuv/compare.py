"""Moved: comparison tables now live in :mod:`drake_uuv.studies.comparison`; re-exported here.

Kept for one release so that ``from drake_uuv.compare import Variant, compare`` keeps
working; import from :mod:`drake_uuv.studies` instead. The ``drake-uuv compare`` subcommand
moved to :mod:`drake_uuv.cli.compare`.
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

__all__ = [
    "ALPHAS",
    "ESTIMATOR_GROUP",
    "VARIANT_GROUPS",
    "Variant",
    "alpha_sweep_variants",
    "attitude_noise_variants",
    "compare",
    "csv_table",
    "estimator_attitude_variants",
    "markdown_table",
    "ratio_tables",
    "selected_variants",
    "tracking_law_variants",
]
