"""Visualization of drake_uuv runs: the 3-D Meshcat scene, live and recorded."""

from drake_uuv.visualization.animation import (
    LiveMeshcatVisualizer,
    MeshcatScene,
    SceneFrame,
    SceneStyle,
    add_live_meshcat_visualizer,
    record_animation,
)

__all__ = [
    "LiveMeshcatVisualizer",
    "MeshcatScene",
    "SceneFrame",
    "SceneStyle",
    "add_live_meshcat_visualizer",
    "record_animation",
]
