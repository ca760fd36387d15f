"""A LeafSystem that draws the 3-D scene live while a simulation runs."""

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from drake_uuv.visualization.scene import MeshcatScene, SceneFrame, SceneStyle


class LiveMeshcatVisualizer(LeafSystem):
    """Draws the :class:`MeshcatScene` live from its input ports.

    A periodic publish event (every ``publish_period`` seconds, from t = 0)
    reads the inputs and draws one step; an initialization event clears the
    trails and frames the camera on the first step.

    Its inputs are named like the closed loop's outputs, so the builder wires them by name.

    .. pydrake_system::

        name: LiveMeshcatVisualizer
        input_ports:
        - p_WU
        - R_WB
        - p_WT
        - x_TU_hat
        - P_TU

    - ``p_WU`` (3): UUV position; ``R_WB`` (9): its attitude, row-major 3×3.
    - ``p_WT`` (3): the true target position.
    - ``x_TU_hat`` (6): estimated relative state ``[q̂, ϑ̂]``; ``P_TU`` (36) its covariance.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        *,
        baseline_B: np.ndarray,
        publish_period: float,
        trail_length: int = 50,
        follow_target: bool = True,
        style: SceneStyle | None = None,
    ) -> None:
        super().__init__()
        if publish_period <= 0:
            raise ValueError(f"publish_period must be > 0, got {publish_period}")
        self._meshcat = meshcat
        self._scene_args = (baseline_B, trail_length, follow_target, style)
        self._scene: MeshcatScene | None = None
        self._p_WU_port = self.DeclareVectorInputPort("p_WU", 3)
        self._R_WB_port = self.DeclareVectorInputPort("R_WB", 9)
        self._p_WT_port = self.DeclareVectorInputPort("p_WT", 3)
        self._x_hat_port = self.DeclareVectorInputPort("x_TU_hat", 6)
        self._P_port = self.DeclareVectorInputPort("P_TU", 36)
        self.DeclareInitializationPublishEvent(self._Initialize)
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._Publish)

    @property
    def scene(self) -> MeshcatScene:
        """The scene drawn into (created on first use)."""
        if self._scene is None:
            self._scene = MeshcatScene(self._meshcat, *self._scene_args)
        return self._scene

    def _frame(self, context: Context) -> SceneFrame:
        x_hat = self._x_hat_port.Eval(context)
        return SceneFrame(
            p_WU=np.array(self._p_WU_port.Eval(context)),
            R_WB=np.array(self._R_WB_port.Eval(context)).reshape(3, 3),
            p_WT=np.array(self._p_WT_port.Eval(context)),
            q_hat=np.array(x_hat[:3]),
            P_qq=np.array(self._P_port.Eval(context)).reshape(6, 6)[:3, :3],
        )

    def _Initialize(self, context: Context) -> EventStatus:
        scene = self.scene
        scene.reset_trails()
        scene.frame_first(self._frame(context))
        return EventStatus.Succeeded()

    def _Publish(self, context: Context) -> EventStatus:
        self.scene.draw(self._frame(context))
        self._meshcat.SetSimulationTime(context.get_time())
        return EventStatus.Succeeded()
