"""Visualization of drake_uuv runs: the 3-D Meshcat scene (live and recorded) and the
diagram's Graphviz export."""

from drake_uuv.visualization.animation import record_animation
from drake_uuv.visualization.live_visualizer import LiveMeshcatVisualizer
from drake_uuv.visualization.scene import MeshcatScene, SceneFrame, SceneStyle

__all__ = [
    "LiveMeshcatVisualizer",
    "MeshcatScene",
    "SceneFrame",
    "SceneStyle",
    "record_animation",
]
