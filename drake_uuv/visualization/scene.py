"""3-D Meshcat scene of the UUV, its two sonars and the target, drawn live or recorded.

One :class:`MeshcatScene` draws everything (what it draws, as plain data, is
:mod:`~drake_uuv.visualization.scene_content`). It is driven in two ways that share
every drawing call:

* :func:`record_animation` replays a simulation log (``log.npz``) into a Meshcat
  recording and writes it as one self-contained HTML page (``StaticHtml``) that
  plays offline;
* :class:`LiveMeshcatVisualizer` is a Drake ``LeafSystem`` whose periodic publish
  event draws the same scene from its input ports while a simulation runs.

The scene (colours in :class:`SceneStyle`):

* the UUV body, an orange ellipsoid, with its sonars s1 (blue) and s2 (green) at
  ``±½ b`` in the body frame and the baseline between them (dark grey);
* the target, a red sphere;
* the two range beams, thin cylinders from each sonar to the target, in the
  colour of their sonar;
* the trails of both trajectories, the last ``trail_length`` steps (UUV
  yellow, target light red);
* for a thruster-driven vehicle (a :class:`ThrusterLayout`), its thrusters' efforts: one
  thin cyan cylinder per thruster from its position along the force it applies, as long as
  ``thruster_length`` at full thrust (``log["thrust"]``, held over each step);
* the estimated target position ``p_UUV − q̂`` (magenta) with the 3-σ ellipsoid
  of the position block of P (translucent surface plus its three principal
  ellipses). The UUV position is known exactly, so the covariance of the
  estimated target position is the covariance of q̂, ``P[:3, :3]``.

By default the view follows the target (``follow_target=True``): the whole scene
is translated by ``−p_target(k)`` so the target stays at the centre of the
screen and the vehicle is seen turning its baseline around it. Meshcat's grid
and axes are then screen-fixed and would mislead, so they are hidden and a
world-fixed cloud of small white particles ("marine snow") shows the motion
through the water instead. With ``follow_target=False`` the camera is fixed in
the world and frames the whole run.

Meshcat recordings animate transforms and properties but not geometry, so
everything that changes shape is a fixed unit shape with an animated pose and
``scale`` property (beams: unit-length cylinders; ellipsoid: unit sphere), and
each trail segment is its own object whose ``visible`` property is switched on
when it is drawn and off ``trail_length`` steps later (in live mode the segment
is deleted instead).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Cylinder, Ellipsoid, Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.perception import BaseField, Fields, PointCloud

from drake_uuv.visualization.scene_content import (
    LOG_KEYS,
    SceneFrame,
    SceneStyle,
    ThrusterLayout,
    thruster_jets,
    world_particles,
)

__all__ = [
    "LOG_KEYS",
    "SCENE_ROOT",
    "MeshcatScene",
    "SceneFrame",
    "SceneStyle",
    "ThrusterLayout",
    "thruster_jets",
    "world_particles",
]

#: Root path of the scene in the Meshcat tree (absolute, so it never collides
#: with Drake's own ``/drake/...`` visualizers).
SCENE_ROOT = "/uuv_scene"

#: Meshcat's default perspective camera: vertical field of view in degrees.
MESHCAT_DEFAULT_FOV_DEG = 75.0


def _rgba(rgb: tuple[float, float, float], alpha: float = 1.0) -> Rgba:
    return Rgba(rgb[0], rgb[1], rgb[2], alpha)


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def _covariance_axes(
    P_qq: np.ndarray, sigma: float, floor: float = 1e-4
) -> tuple[RotationMatrix, list[float]]:
    """Rotation and semi-axes of the ``sigma``-σ ellipsoid of ``P_qq``.

    The unit sphere mapped by ``R diag(radii)`` is ``{x : xᵀ P⁻¹ x = sigma²}``.
    Radii are floored at ``floor`` so the transform stays invertible.
    """
    P_sym = 0.5 * (P_qq + P_qq.T)
    eigenvalues, V = np.linalg.eigh(P_sym)
    if np.linalg.det(V) < 0:
        V[:, 0] = -V[:, 0]
    radii = sigma * np.sqrt(np.clip(eigenvalues, 0.0, None))
    radii = np.maximum(radii, floor)
    return RotationMatrix(V), [float(r) for r in radii]


def _unit_circles(segments: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (3×M) of the three principal circles of the unit sphere."""
    theta = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    c, s, z = np.cos(theta), np.sin(theta), np.zeros_like(theta)
    circles = [np.vstack([c, s, z]), np.vstack([z, c, s]), np.vstack([s, z, c])]
    starts = np.hstack([ci[:, :-1] for ci in circles])
    ends = np.hstack([ci[:, 1:] for ci in circles])
    return np.asfortranarray(starts), np.asfortranarray(ends)


@dataclass
class _Trail:
    path: str
    rgba: Rgba
    previous: np.ndarray | None = None
    count: int = 0
    live: deque = field(default_factory=deque)


class MeshcatScene:
    """Draws the UUV/target scene into a Meshcat instance.

    Construct it once (it sets all objects), then call :meth:`draw` for every
    step. With ``time_in_recording=None`` a draw changes the live scene; with a
    time it also adds key frames to the Meshcat recording in progress (see
    :func:`record_animation`).

    Args:
        meshcat: the Meshcat instance to draw into.
        baseline_B: sonar baseline ``b = p_s1 − p_s2`` in the body frame (3,);
            the sonars sit at ``±½ b``.
        trail_length: how many steps of each trajectory stay visible (0: none).
        follow_target: keep the target at the centre of the view (see module
            docstring); otherwise the camera is fixed in the world.
        style: sizes and colours.
        thrusters: draw these thrusters' efforts from each frame's ``thrust``.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        baseline_B: np.ndarray,
        trail_length: int = 50,
        follow_target: bool = True,
        style: SceneStyle | None = None,
        thrusters: ThrusterLayout | None = None,
    ) -> None:
        baseline_B = np.asarray(baseline_B, dtype=float).reshape(-1)
        if baseline_B.shape != (3,):
            raise ValueError(f"baseline_B must have 3 entries, got {baseline_B.shape}")
        if trail_length < 0:
            raise ValueError(f"trail_length must be >= 0, got {trail_length}")
        self.meshcat = meshcat
        self.baseline_B = baseline_B
        self.trail_length = int(trail_length)
        self.follow_target = bool(follow_target)
        self.style = style or SceneStyle()
        self.thrusters = thrusters
        #: Camera position and look-at point set by the last :meth:`set_camera`,
        #: in Meshcat's (z-up) world, i.e. after the follow translation.
        self.camera_position: np.ndarray | None = None
        self.camera_target: np.ndarray | None = None
        self._particle_tile: tuple[int, ...] | None = None
        self._trails = {
            "uuv": _Trail(f"{SCENE_ROOT}/trails/uuv", _rgba(self.style.uuv_trail_rgb)),
            "target": _Trail(f"{SCENE_ROOT}/trails/target", _rgba(self.style.target_trail_rgb)),
        }
        self._add_objects()

    # ------------------------------------------------------------------ paths
    @staticmethod
    def animated_paths() -> list[str]:
        """Paths whose pose (or scale) :meth:`draw` changes every step."""
        return [
            f"{SCENE_ROOT}/uuv",
            f"{SCENE_ROOT}/target",
            f"{SCENE_ROOT}/estimate",
            f"{SCENE_ROOT}/estimate/ellipsoid",
            f"{SCENE_ROOT}/beams/s1",
            f"{SCENE_ROOT}/beams/s2",
        ]

    # ---------------------------------------------------------------- objects
    def _add_objects(self) -> None:
        m, st, b = self.meshcat, self.style, self.baseline_B
        m.Delete(SCENE_ROOT)
        root = SCENE_ROOT
        m.SetObject(f"{root}/uuv/body", Ellipsoid(*st.body_semi_axes), _rgba(st.body_rgb))
        m.SetObject(f"{root}/uuv/s1", Sphere(st.sonar_radius), _rgba(st.s1_rgb))
        m.SetTransform(f"{root}/uuv/s1", RigidTransform(0.5 * b))
        m.SetObject(f"{root}/uuv/s2", Sphere(st.sonar_radius), _rgba(st.s2_rgb))
        m.SetTransform(f"{root}/uuv/s2", RigidTransform(-0.5 * b))
        length = float(np.linalg.norm(b))
        if length > 0:
            m.SetObject(
                f"{root}/uuv/baseline",
                Cylinder(st.baseline_radius, length),
                _rgba(st.baseline_rgb),
            )
            m.SetTransform(
                f"{root}/uuv/baseline",
                RigidTransform(RotationMatrix.MakeFromOneVector(b, 2), np.zeros(3)),
            )
        m.SetObject(f"{root}/target", Sphere(st.target_radius), _rgba(st.target_rgb))
        m.SetObject(f"{root}/estimate/point", Sphere(st.estimate_radius), _rgba(st.estimate_rgb))
        m.SetObject(
            f"{root}/estimate/ellipsoid/surface",
            Sphere(1.0),
            _rgba(st.estimate_rgb, st.covariance_opacity),
        )
        starts, ends = _unit_circles()
        m.SetLineSegments(
            f"{root}/estimate/ellipsoid/outline",
            starts,
            ends,
            line_width=2.0,
            rgba=_rgba(st.estimate_rgb),
        )
        # Unit-length beams along z, centred: posed and stretched by draw().
        m.SetObject(f"{root}/beams/s1", Cylinder(st.beam_radius, 1.0), _rgba(st.s1_rgb))
        m.SetObject(f"{root}/beams/s2", Cylinder(st.beam_radius, 1.0), _rgba(st.s2_rgb))
        # Unit-length thruster jets in the body frame, stretched by draw() like the beams.
        for i in range(self.thrusters.count if self.thrusters else 0):
            path = f"{root}/uuv/thrusters/{i}"
            m.SetObject(path, Cylinder(st.thruster_radius, 1.0), _rgba(st.thruster_rgb))
        # Screen-fixed grid and axes mislead when the view follows the target.
        m.SetProperty("/Grid", "visible", not self.follow_target)
        m.SetProperty("/Axes", "visible", not self.follow_target)

    def add_particles(self, lower: np.ndarray, upper: np.ndarray) -> int:
        """Show the world-fixed particles (:func:`world_particles`) in a box.

        They give a sense of motion through the water when the view follows the
        target. Returns how many are drawn.
        """
        points = world_particles(lower, upper, self.style)
        path = f"{SCENE_ROOT}/particles"
        if len(points) == 0:
            self.meshcat.Delete(path)
            return 0
        cloud = PointCloud(len(points), Fields(BaseField.kXYZs))
        cloud.mutable_xyzs()[:] = points.T
        st = self.style
        self.meshcat.SetObject(path, cloud, st.particle_size, _rgba(st.particle_rgb))
        return len(points)

    def _follow_particles(self, p_WT: np.ndarray) -> None:
        """Live mode: keep particles around the target, redrawn when it changes cube."""
        tile = tuple(np.floor(p_WT / self.style.particle_tile).astype(int))
        if tile != self._particle_tile:
            self._particle_tile = tile
            half = np.full(3, self.style.particle_live_radius)
            self.add_particles(p_WT - half, p_WT + half)

    # ----------------------------------------------------------------- camera
    def set_camera(self, center_W: np.ndarray, radius: float, toward: np.ndarray) -> None:
        """Point Meshcat's default camera at a sphere so that it fills the view.

        Args:
            center_W: centre of the sphere to frame, world frame *before* the
                follow translation (it is applied here).
            radius: radius of that sphere (metres).
            toward: a direction the camera should look across (its horizontal
                part is kept perpendicular to the line of sight), e.g. the
                relative position UUV − target, so both are seen side by side.
        """
        st = self.style
        center = np.zeros(3) if self.follow_target else np.asarray(center_W, float)
        half_fov = np.deg2rad(MESHCAT_DEFAULT_FOV_DEG) / 2.0
        distance = st.camera_margin * max(float(radius), 0.5) / np.sin(half_fov)
        t = np.asarray(toward, dtype=float)
        horizontal = np.array([-t[1], t[0], 0.0])
        if np.linalg.norm(horizontal) < 1e-9:
            horizontal = np.array([1.0, -1.0, 0.0])
        horizontal = _unit(horizontal)
        el = np.deg2rad(st.camera_elevation_deg)
        direction = np.cos(el) * horizontal + np.array([0.0, 0.0, np.sin(el)])
        self.camera_position = center + distance * direction
        self.camera_target = center
        self.meshcat.SetCameraPose(self.camera_position, self.camera_target)

    def frame_log(self, log: Mapping[str, np.ndarray]) -> None:
        """Frame the camera on a whole run and add the particles around it."""
        p_uuv = np.asarray(log["p_WU"], dtype=float)
        p_target = np.asarray(log["p_WT"], dtype=float)
        q = p_uuv - p_target
        extent = self._vehicle_extent()
        if self.follow_target:
            distances = np.linalg.norm(q, axis=1)
            reach = max(
                float(distances[0]),
                float(np.percentile(distances, self.style.camera_reach_percentile)),
            )
            self.set_camera(p_target[0], reach + extent, q[0])
        else:
            points = np.vstack([p_uuv, p_target])
            lo, hi = points.min(axis=0), points.max(axis=0)
            radius = 0.5 * float(np.linalg.norm(hi - lo)) + extent
            self.set_camera(0.5 * (lo + hi), radius, q[0])
        if self.follow_target:
            points = np.vstack([p_uuv, p_target])
            margin = 2.0 * self.camera_distance()
            self.add_particles(points.min(axis=0) - margin, points.max(axis=0) + margin)

    def frame_first(self, frame: SceneFrame) -> None:
        """Frame the camera on one step (live mode, where the run is unknown)."""
        q = frame.p_WU - frame.p_WT
        radius = float(np.linalg.norm(q)) + self._vehicle_extent()
        self.set_camera(frame.p_WT if self.follow_target else frame.p_WU - 0.5 * q, radius, q)
        if self.follow_target:
            self._particle_tile = None
            self._follow_particles(frame.p_WT)

    def camera_distance(self) -> float:
        """Distance from the camera to its look-at point (after :meth:`set_camera`)."""
        if self.camera_position is None or self.camera_target is None:
            raise RuntimeError("set_camera() has not been called")
        return float(np.linalg.norm(self.camera_position - self.camera_target))

    def _vehicle_extent(self) -> float:
        st = self.style
        return max(
            max(st.body_semi_axes),
            0.5 * float(np.linalg.norm(self.baseline_B)) + st.sonar_radius,
        )

    # ------------------------------------------------------------------- draw
    def reset_trails(self) -> None:
        """Forget the trails (e.g. when a new simulation starts)."""
        for trail in self._trails.values():
            self.meshcat.Delete(trail.path)
            trail.previous = None
            trail.count = 0
            trail.live.clear()

    def draw(self, frame: SceneFrame, time_in_recording: float | None = None) -> None:
        """Show one step; with ``time_in_recording`` also record it at that time."""
        m, t, root = self.meshcat, time_in_recording, SCENE_ROOT
        if self.follow_target:
            m.SetTransform(root, RigidTransform(-frame.p_WT), t)
        else:
            m.SetTransform(root, RigidTransform(), t)
        m.SetTransform(f"{root}/uuv", RigidTransform(RotationMatrix(frame.R_WB), frame.p_WU), t)
        m.SetTransform(f"{root}/target", RigidTransform(frame.p_WT), t)

        q_s = frame.R_WB @ self.baseline_B
        for name, p_sonar in (("s1", frame.p_WU + 0.5 * q_s), ("s2", frame.p_WU - 0.5 * q_s)):
            self._set_stretched(f"{root}/beams/{name}", p_sonar, frame.p_WT, t)

        m.SetTransform(f"{root}/estimate", RigidTransform(frame.p_WT_hat), t)
        R_E, radii = _covariance_axes(frame.P_qq, self.style.covariance_sigma)
        m.SetTransform(f"{root}/estimate/ellipsoid", RigidTransform(R_E, np.zeros(3)), t)
        m.SetProperty(f"{root}/estimate/ellipsoid", "scale", radii, t)

        if self.thrusters is not None and frame.thrust is not None:
            starts, ends = thruster_jets(self.thrusters, frame.thrust, self.style.thruster_length)
            for i, (start, end) in enumerate(zip(starts, ends, strict=True)):
                self._set_stretched(f"{root}/uuv/thrusters/{i}", start, end, t)

        self._extend_trail(self._trails["uuv"], frame.p_WU, t)
        self._extend_trail(self._trails["target"], frame.p_WT, t)
        if t is None and self.follow_target:
            self._follow_particles(frame.p_WT)

    def _set_stretched(
        self, path: str, start: np.ndarray, end: np.ndarray, t: float | None
    ) -> None:
        """Pose a unit z-cylinder at ``path`` so that it spans ``start → end``."""
        d = end - start
        length = float(np.linalg.norm(d))
        R = RotationMatrix.MakeFromOneVector(d, 2) if length > 1e-9 else RotationMatrix()
        self.meshcat.SetTransform(path, RigidTransform(R, 0.5 * (start + end)), t)
        self.meshcat.SetProperty(path, "scale", [1.0, 1.0, max(length, 1e-6)], t)

    def _extend_trail(self, trail: _Trail, point: np.ndarray, t: float | None) -> None:
        """Add the segment from the previous point to ``point``; retire old ones."""
        previous, trail.previous = trail.previous, np.array(point, dtype=float)
        if previous is None or self.trail_length == 0:
            return
        m = self.meshcat
        path = f"{trail.path}/{trail.count:06d}"
        trail.count += 1
        vertices = np.asfortranarray(np.column_stack([previous, point]))
        m.SetLine(path, vertices, self.style.trail_width, trail.rgba)
        if t is not None:
            m.SetProperty(path, "visible", False, 0.0)
            m.SetProperty(path, "visible", True, t)
        trail.live.append(path)
        while len(trail.live) > self.trail_length:
            old = trail.live.popleft()
            if t is None:
                m.Delete(old)
            else:
                m.SetProperty(old, "visible", False, t)
