"""The studies of drake_uuv: the named groups of ``drake-uuv compare`` and the results page.

Not part of the installed package: ``drake-uuv compare`` finds this folder beside the
``drake_uuv`` package of a checkout (or takes ``--studies DIR``) and imports it from its path
(:func:`drake_uuv.studies.load_groups`); ``scripts/make_results_page.py`` does the same. The
modules may import each other relatively and import anything from ``drake_uuv``; nothing in
``drake_uuv`` imports them.

* :mod:`.paper`: the paper's groups (``attitude_noise``, ``alpha``, ``tracking``, run by
  ``drake-uuv compare`` without ``--group``) and ``estimator``;
* :mod:`.vehicle`: the ``vehicle`` group and the vehicle's limits it derives;
* :mod:`.regimes`: the ``regimes`` group (noise and standoff × estimator);
* :mod:`.attitude`: the ``attitude`` and ``attitude_vehicle`` groups;
* :mod:`.navigation`: the ``navigation`` group (navigation errors and sonar timing);
* :mod:`.robustness`: the ``robustness`` group (does any run get lost, over many seeds);
* :mod:`.paired`: the paired per-seed comparison of two study folders (a script too);
* :mod:`.results_sections`: the results page's sections beyond the paper's claims.

To add a group: write a function returning its :class:`~drake_uuv.studies.Variant` list, wrap
it in a :class:`~drake_uuv.studies.Group` (name, one-line description) and add it to
:data:`GROUPS`.
"""

from drake_uuv.studies import Group

from .attitude import ATTITUDE_GROUP, ATTITUDE_VEHICLE_GROUP
from .navigation import NAVIGATION_GROUP
from .paper import ALPHA_GROUP, ATTITUDE_NOISE_GROUP, ESTIMATOR_GROUP, TRACKING_GROUP
from .regimes import REGIMES_GROUP
from .robustness import ROBUSTNESS_GROUP
from .vehicle import VEHICLE_GROUP

# Every group of `drake-uuv compare --group NAME`, in the order `--group list` shows them.
GROUPS: list[Group] = [
    ATTITUDE_NOISE_GROUP,
    ALPHA_GROUP,
    ESTIMATOR_GROUP,
    TRACKING_GROUP,
    VEHICLE_GROUP,
    REGIMES_GROUP,
    ATTITUDE_GROUP,
    ATTITUDE_VEHICLE_GROUP,
    NAVIGATION_GROUP,
    ROBUSTNESS_GROUP,
]
