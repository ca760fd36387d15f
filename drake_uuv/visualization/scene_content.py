"""What the 3-D scene shows, as plain data: its style, one step's frame, a vehicle's thrusters
and the world-fixed particle field (numpy only; :mod:`drake_uuv.visualization.scene` draws
them into Meshcat)."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from drake_uuv.scenario.plants import HoveringAuv

__all__ = [
    "LOG_KEYS",
    "LegendEntry",
    "SceneFrame",
    "SceneStyle",
    "ThrusterLayout",
    "legend_entries",
    "thruster_jets",
    "world_particles",
]

#: Log entries :meth:`SceneFrame.from_log` reads.
LOG_KEYS = ("p_WU", "R_WB", "p_WT", "x_TU_hat", "P_TU")


@dataclass(frozen=True)
class SceneStyle:
    """Sizes (metres) and colours (RGB in [0, 1]) of the scene objects.

    The target red and vehicle orange are hues found nowhere else in the scene
    (Meshcat's background is grey or blue, the trails are yellow and pale
    red, the estimate magenta), so a screenshot can be checked by colour.
    """

    body_semi_axes: tuple[float, float, float] = (0.7, 0.3, 0.25)
    sonar_radius: float = 0.12
    baseline_radius: float = 0.025
    target_radius: float = 0.3
    estimate_radius: float = 0.12
    beam_radius: float = 0.012
    trail_width: float = 3.0
    covariance_sigma: float = 3.0
    covariance_opacity: float = 0.15
    particle_spacing: float = 3.0
    particle_tile: float = 10.0
    particle_live_radius: float = 25.0
    particle_size: float = 0.025
    max_particles: int = 30000
    camera_elevation_deg: float = 25.0
    camera_margin: float = 1.05
    #: The follow camera frames this percentile of the UUV's distance to the
    #: target over the run (and the distance at load), not the maximum: one
    #: transient excursion would otherwise make everything small.
    camera_reach_percentile: float = 90.0
    #: Thruster jets: radius, and length at full thrust (scaled by |f| / f_max).
    thruster_radius: float = 0.03
    thruster_length: float = 0.6

    body_rgb: tuple[float, float, float] = (1.0, 0.55, 0.0)
    target_rgb: tuple[float, float, float] = (0.9, 0.05, 0.05)
    s1_rgb: tuple[float, float, float] = (0.1, 0.3, 1.0)
    s2_rgb: tuple[float, float, float] = (0.1, 0.8, 0.2)
    baseline_rgb: tuple[float, float, float] = (0.15, 0.15, 0.15)
    estimate_rgb: tuple[float, float, float] = (0.9, 0.0, 0.9)
    uuv_trail_rgb: tuple[float, float, float] = (0.95, 0.85, 0.1)
    target_trail_rgb: tuple[float, float, float] = (1.0, 0.55, 0.55)
    particle_rgb: tuple[float, float, float] = (0.95, 0.95, 1.0)
    thruster_rgb: tuple[float, float, float] = (0.0, 0.8, 0.85)


@dataclass(frozen=True)
class ThrusterLayout:
    """Where a vehicle's thrusters sit and push, in the body frame, and their force limit.

    Attributes:
        positions: n×3 thruster positions from the body origin [m].
        directions: n×3 directions of positive thrust (normalised here).
        max_thrust: largest |thrust| of each thruster [N].
    """

    positions: np.ndarray
    directions: np.ndarray
    max_thrust: float

    def __post_init__(self) -> None:
        positions = np.asarray(self.positions, dtype=float)
        directions = np.asarray(self.directions, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 3 or directions.shape != positions.shape:
            raise ValueError(
                f"directions: must be n×3 like positions {positions.shape}, got {directions.shape}"
            )
        norms = np.linalg.norm(directions, axis=1)
        if np.any(norms <= 0.0):
            raise ValueError(f"directions: must be non-zero, got {directions.tolist()}")
        if not self.max_thrust > 0.0:
            raise ValueError(f"max_thrust: must be > 0, got {self.max_thrust!r}")
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "directions", directions / norms[:, None])

    @classmethod
    def from_config(cls, config: HoveringAuv) -> ThrusterLayout:
        """The layout of a plant config with ``thruster_positions``, ``thruster_directions``
        and ``max_thrust`` (``!HoveringAuv``)."""
        return cls(
            np.asarray(config.thruster_positions, dtype=float),
            np.asarray(config.thruster_directions, dtype=float),
            float(config.max_thrust),
        )

    @property
    def count(self) -> int:
        return len(self.positions)


def thruster_jets(
    layout: ThrusterLayout, thrust: np.ndarray, length: float
) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame start and end points (n×3 each) of the thrusters' jets: from each
    thruster's position along the force it applies, ``length · f / f_max`` long (a thrust
    beyond the limit is drawn at the limit)."""
    thrust = np.asarray(thrust, dtype=float).reshape(-1)
    if thrust.shape != (layout.count,):
        raise ValueError(f"thrust: must have {layout.count} entries, got {thrust.shape}")
    fraction = np.clip(thrust / layout.max_thrust, -1.0, 1.0)
    return layout.positions, layout.positions + length * fraction[:, None] * layout.directions


@dataclass(frozen=True)
class SceneFrame:
    """What the scene shows at one step (all in the world frame).

    Attributes:
        p_WU: UUV position (3,).
        R_WB: UUV attitude, body to world (3, 3).
        p_WT: true target position (3,).
        q_hat: estimated relative position ``p_WU − p̂_WT`` (3,).
        P_qq: covariance of ``q_hat``, the 3×3 position block of P (3, 3).
        thrust: the thrusters' forces [N] (n,), or None for a vehicle without them.
    """

    p_WU: np.ndarray
    R_WB: np.ndarray
    p_WT: np.ndarray
    q_hat: np.ndarray
    P_qq: np.ndarray
    thrust: np.ndarray | None = None

    @property
    def p_WT_hat(self) -> np.ndarray:
        """Estimated target position ``p_WU − q̂``."""
        return self.p_WU - self.q_hat

    @classmethod
    def from_log(cls, log: Mapping[str, np.ndarray], k: int) -> SceneFrame:
        """The frame at row ``k`` of a simulation log (see :data:`LOG_KEYS`; ``thrust`` too
        if the log has it)."""
        P = np.asarray(log["P_TU"][k], dtype=float)
        thrust = np.asarray(log["thrust"][k], dtype=float) if "thrust" in log else None
        return cls(
            p_WU=np.asarray(log["p_WU"][k], dtype=float),
            R_WB=np.asarray(log["R_WB"][k], dtype=float).reshape(3, 3),
            p_WT=np.asarray(log["p_WT"][k], dtype=float),
            q_hat=np.asarray(log["x_TU_hat"][k][:3], dtype=float),
            P_qq=P.reshape(6, 6)[:3, :3],
            thrust=thrust,
        )


def world_particles(lower: np.ndarray, upper: np.ndarray, style: SceneStyle) -> np.ndarray:
    """Particles of a world-fixed random field that lie in the cubes meeting a box.

    Space is cut into cubes of ``style.particle_tile`` metres, each holding its own
    uniformly scattered particles (one per ``particle_spacing³``) seeded by the
    cube's integer index, so every box shows the same particles where boxes
    overlap. Beyond ``style.max_particles`` a regularly thinned subset is
    returned. Returns an (n, 3) array.
    """
    st = style
    first = np.floor(np.asarray(lower, dtype=float) / st.particle_tile).astype(int)
    last = np.floor(np.asarray(upper, dtype=float) / st.particle_tile).astype(int)
    per_tile = max(1, round((st.particle_tile / st.particle_spacing) ** 3))
    offset = 1 << 31  # seed entropy must be non-negative
    chunks = [
        st.particle_tile
        * (np.array(tile) + np.random.default_rng([offset + i for i in tile]).random((per_tile, 3)))
        for tile in itertools.product(*(range(a, b + 1) for a, b in zip(first, last, strict=True)))
    ]
    if not chunks:
        return np.zeros((0, 3))
    points = np.vstack(chunks)
    if len(points) > st.max_particles:
        points = points[:: int(np.ceil(len(points) / st.max_particles))]
    return points


@dataclass(frozen=True)
class LegendEntry:
    """One line of the scene's key: a colour (RGB in [0, 1], drawn at ``opacity``) and what
    it shows."""

    rgb: tuple[float, float, float]
    label: str
    opacity: float = 1.0


def legend_entries(
    style: SceneStyle, *, trail_length: int, thrusters: bool, follow_target: bool
) -> list[LegendEntry]:
    """The key to the scene's colours, one entry per kind of object it draws."""
    entries = [
        LegendEntry(style.body_rgb, "UUV body"),
        LegendEntry(style.s1_rgb, "sonar s1 and its range beam to the target"),
        LegendEntry(style.s2_rgb, "sonar s2 and its range beam to the target"),
        LegendEntry(style.baseline_rgb, "sonar baseline s1–s2"),
        LegendEntry(style.target_rgb, "target (true position)"),
        LegendEntry(style.estimate_rgb, "estimated target position p_WU − q̂"),
        LegendEntry(
            style.estimate_rgb,
            f"{style.covariance_sigma:g}σ ellipsoid of the estimate (position block of P)",
            style.covariance_opacity,
        ),
    ]
    if trail_length > 0:
        entries += [
            LegendEntry(style.uuv_trail_rgb, f"UUV trail, last {trail_length} steps"),
            LegendEntry(style.target_trail_rgb, f"target trail, last {trail_length} steps"),
        ]
    if thrusters:
        entries.append(LegendEntry(style.thruster_rgb, "thruster effort, length ∝ thrust"))
    if follow_target:
        entries.append(
            LegendEntry(style.particle_rgb, "world-fixed particles: the view follows the target")
        )
    return entries
