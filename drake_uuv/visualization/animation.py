"""A recorded 3-D animation of a run: the :class:`~drake_uuv.visualization.scene.MeshcatScene`
replayed from a log into a Meshcat recording, written as one self-contained HTML page with a
key to the scene's colours (:func:`legend_html`)."""

import html
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat

from drake_uuv.io import write_text_atomic
from drake_uuv.visualization.scene import (
    LOG_KEYS,
    MeshcatScene,
    SceneFrame,
    SceneStyle,
    ThrusterLayout,
)
from drake_uuv.visualization.scene_content import LegendEntry, legend_entries

#: The id of the key's element in the page.
LEGEND_ID = "drake-uuv-legend"


def _check_log(log: Mapping[str, np.ndarray]) -> int:
    missing = [k for k in LOG_KEYS if k not in log]
    if missing:
        raise ValueError(f"log is missing {missing}; it needs {list(LOG_KEYS)}")
    n = len(log["p_WU"])
    shapes = {"p_WU": (n, 3), "R_WB": (n, 3, 3), "p_WT": (n, 3), "x_TU_hat": (n, 6)}
    for key, shape in shapes.items():
        if np.shape(log[key]) != shape:
            raise ValueError(f"log[{key!r}] has shape {np.shape(log[key])}, expected {shape}")
    if np.shape(log["P_TU"]) not in ((n, 6, 6), (n, 36)):
        raise ValueError(f"log['P_TU'] has shape {np.shape(log['P_TU'])}, expected ({n}, 6, 6)")
    if n == 0:
        raise ValueError("log has no steps")
    return n


def recording_meshcat() -> Meshcat:
    """A Meshcat instance to record into. Its server's "listening for connections at
    localhost" line, logged at start, would read as where the animation is; it is held back
    (Drake's log is quieted while the server starts)."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.WARNING)
    try:
        return Meshcat()
    finally:
        logger.setLevel(level)


def legend_html(entries: Sequence[LegendEntry]) -> str:
    """A key to the scene's colours: a box fixed at the page's bottom left (clear of
    Meshcat's controls at the top right), one coloured swatch and label per entry."""
    rows = "".join(
        '<div style="display:flex;align-items:center;margin:2px 0">'
        f'<span style="display:inline-block;width:14px;height:14px;margin-right:7px;'
        f"border:1px solid #555;background:rgba({', '.join(f'{round(255 * c)}' for c in e.rgb)},"
        f'{max(e.opacity, 0.3):g})"></span>{html.escape(e.label)}</div>'
        for e in entries
    )
    return (
        f'<div id="{LEGEND_ID}" style="position:fixed;left:10px;bottom:10px;z-index:10;'
        "padding:6px 10px;background:rgba(255,255,255,0.85);border-radius:4px;"
        'font:13px sans-serif;color:#222;pointer-events:none">'
        f"<b>drake_uuv scene</b>{rows}</div>"
    )


def record_animation(
    log: Mapping[str, np.ndarray],
    baseline_B: np.ndarray,
    time_step: float,
    out_html: Path,
    playback_speed: float = 1.0,
    trail_length: int = 50,
    meshcat: Meshcat | None = None,
    follow_target: bool = True,
    style: SceneStyle | None = None,
    thrusters: ThrusterLayout | None = None,
) -> Path:
    """Replay a simulation log into a Meshcat recording; write it as one HTML page.

    Args:
        log: one row per step k (the arrays of ``log.npz``); reads ``p_WU``
            (N×3), ``R_WB`` (N×3×3), ``p_WT`` (N×3), ``x_TU_hat`` (N×6) and
            ``P_TU`` (N×6×6).
        baseline_B: sonar baseline in the body frame (3,).
        time_step: sampling period t of the log (seconds per row).
        out_html: file to write; its folder is created. Written atomically.
        playback_speed: simulated seconds per second of playback.
        trail_length: steps of each trajectory kept visible (0: no trails).
        meshcat: draw into this instance (its scene under ``/uuv_scene`` and its
            recording are replaced); by default a new one is started.
        follow_target: keep the target at the centre of the view.
        style: sizes and colours.
        thrusters: for a thruster-driven vehicle (``!HoveringAuv``:
            ``ThrusterLayout.from_config(scenario.plant)``), draw each thruster's
            effort from ``log["thrust"]`` (N×n).

    Returns:
        ``out_html``. The page embeds all scripts and data (no network needed)
        and autoplays the recording once; Meshcat's "Animations" panel replays
        and scrubs it. A key at the bottom left names the colours.
    """
    n = _check_log(log)
    if thrusters is not None and np.shape(log.get("thrust")) != (n, thrusters.count):
        raise ValueError(
            f"log['thrust'] has shape {np.shape(log.get('thrust'))}, expected "
            f"({n}, {thrusters.count}) for the thrusters"
        )
    if time_step <= 0:
        raise ValueError(f"time_step must be > 0, got {time_step}")
    if playback_speed <= 0:
        raise ValueError(f"playback_speed must be > 0, got {playback_speed}")
    out_html = Path(out_html)
    if meshcat is None:
        meshcat = recording_meshcat()
    meshcat.DeleteRecording()
    scene = MeshcatScene(meshcat, baseline_B, trail_length, follow_target, style, thrusters)
    scene.frame_log(log)

    # One animation frame per step; key times sit mid-frame because Drake
    # floors time × fps to the frame number.
    fps = playback_speed / time_step
    meshcat.StartRecording(frames_per_second=fps)
    for k in range(n):
        scene.draw(SceneFrame.from_log(log, k), time_in_recording=(k + 0.5) / fps)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    page = meshcat.StaticHtml()
    key = legend_entries(
        scene.style,
        trail_length=trail_length,
        thrusters=thrusters is not None,
        follow_target=follow_target,
    )
    if "</body>" not in page:
        raise RuntimeError("Meshcat's StaticHtml has no </body>: nowhere to put the legend")
    page = page.replace("</body>", legend_html(key) + "\n</body>", 1)
    return write_text_atomic(out_html, page)
