"""The paper's navigation: the vehicle knows its true attitude, velocity and position."""

from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import PassThrough

from drake_uuv.navigation.base import NavigationSetting
from drake_uuv.primitives.batch import batch_size_field
from drake_uuv.scenario.navigation import PerfectNavigation

#: Each truth input → its navigated output, and their size.
PORTS = (("p_WU", "p_WU_nav", 3), ("v_WU", "v_WU_nav", 3), ("R_WB", "R_WB_nav", 9))


class PerfectNavigationSystem(Diagram):
    """``p_WU_nav = p_WU``, ``v_WU_nav = v_WU``, ``R_WB_nav = R_WB``: the inputs, copied.

    One Drake ``PassThrough`` per signal (systems ``p_WU``, ``v_WU``, ``R_WB`` inside), so
    every output is the input itself, bit for bit, evaluated without a Python call: a run
    with this navigation is the paper's run, whatever reads the navigation.

    .. pydrake_system::

        name: PerfectNavigationSystem
        input_ports:
        - p_WU
        - v_WU
        - R_WB
        output_ports:
        - p_WU_nav
        - v_WU_nav
        - R_WB_nav

    - ``p_WU``, ``v_WU`` (3 each), ``R_WB`` (9, row-major): the vehicle's true state (the
      plant's outputs).
    - ``p_WU_nav``, ``v_WU_nav`` (3 each), ``R_WB_nav`` (9, row-major): the same values.

    Sizes are per run: with ``batch_size`` B every port holds B runs row-major
    (:mod:`drake_uuv.primitives.batch`), each copied.

    ``config`` (:class:`~drake_uuv.scenario.PerfectNavigation`) has no parameters, and the
    ``setting`` is not needed.
    """

    def __init__(
        self, config: PerfectNavigation, *, setting: NavigationSetting, batch_size: int = 1
    ) -> None:
        super().__init__()
        self.batch_size = B = batch_size_field(batch_size)
        builder = DiagramBuilder()
        for truth, navigated, size in PORTS:
            copy = builder.AddNamedSystem(truth, PassThrough(size * B))
            builder.ExportInput(copy.get_input_port(), truth)
            builder.ExportOutput(copy.get_output_port(), navigated)
        builder.BuildInto(self)
