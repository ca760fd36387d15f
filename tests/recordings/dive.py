"""A dive recorded by a program that is not drake_uuv: rosbags' own writers, the standard
message types, float32 ranges, real-epoch stamps; and a Kalman filter written from the paper's
equations, for the replay to be compared with.

The dive: a vehicle turning about two axes (so the sonars' baseline is persistently exciting)
under a held world acceleration, a target at constant velocity, ranges with the paper's noise.
``base_link`` is not the sonars' midpoint (the mounting is off by :data:`MIDPOINT`), as on a
real hull.
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

#: A real epoch: 2026-11-27 12:00:00 UTC and a fraction [ns].
EPOCH_NS = 1_795_780_800_123_456_789
T = 0.5
BASELINE = np.array([-0.9, 1.1, 0.2])
MIDPOINT = np.array([0.3, 0.0, -0.1])  # U in base_link
ETA = np.array([0.01, 0.01])


def _rotation(k: float) -> np.ndarray:
    """R_WB at step k: yaw 0.35 k, roll 0.4 sin(0.3 k)."""
    a, b = 0.35 * k, 0.4 * np.sin(0.3 * k)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    return Rz @ Rx


def _quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a rotation matrix, w > 0 (the trace is positive for these)."""
    w = 0.5 * np.sqrt(max(1.0 + np.trace(R), 1e-12))
    return (w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
            (R[1, 0] - R[0, 1]) / (4 * w))  # fmt: skip


@dataclass
class Dive:
    """The dive's per-step truth, commands and float32 ranges; ``missing`` (step, sonar)."""

    steps: int = 80
    seed: int = 4
    missing: tuple[tuple[int, int], ...] = ((37, 1),)
    R: np.ndarray = field(init=False)
    p_WU: np.ndarray = field(init=False)
    v_WU: np.ndarray = field(init=False)
    p_WT: np.ndarray = field(init=False)
    v_WT: np.ndarray = field(init=False)
    u1_W: np.ndarray = field(init=False)
    ranges: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        N = self.steps
        self.R = np.array([_rotation(k) for k in range(N)])
        self.u1_W = 0.05 * np.column_stack([np.sin(0.1 * np.arange(N)), np.cos(0.07 * np.arange(N)),
                                            np.zeros(N)])  # fmt: skip
        self.p_WU, self.v_WU = np.zeros((N, 3)), np.zeros((N, 3))
        self.p_WU[0], self.v_WU[0] = [-2.0, -2.5, 0.5], [0.1, 0.0, 0.0]
        for k in range(N - 1):
            a = self.u1_W[k]
            self.p_WU[k + 1] = self.p_WU[k] + T * self.v_WU[k] + 0.5 * T**2 * a
            self.v_WU[k + 1] = self.v_WU[k] + T * a
        self.v_WT = np.tile([0.05, 0.02, 0.0], (N, 1))
        self.p_WT = np.array([0.5, -0.3, 0.0]) + np.arange(N)[:, None] * T * self.v_WT
        q_s = np.einsum("kij,j->ki", self.R, BASELINE)
        s1 = self.p_WU + 0.5 * q_s - self.p_WT
        s2 = self.p_WU - 0.5 * q_s - self.p_WT
        d = np.column_stack([np.linalg.norm(s1, axis=1), np.linalg.norm(s2, axis=1)])
        self.ranges = (d + np.sqrt(ETA) * rng.standard_normal((N, 2))).astype(np.float32)


def write_dive(
    path: Path,
    dive: Dive,
    *,
    storage: str = "mcap",
    skip: tuple[str, ...] = (),
    tf_children: tuple[str, ...] = ("sonar_1", "sonar_2"),
    navigation_type: str = "nav_msgs/msg/Odometry",
    swap_stamps: tuple[int, ...] = (),
    steps: int | None = None,
    rename: dict[str, str] | None = None,
    imu: str | None = None,
) -> Path:
    """Writes ``dive`` with rosbags' own writer: ``storage`` mcap, sqlite3 or ros1; ``skip``
    leaves topics out; ``tf_children`` the sonars /tf_static mounts; ``navigation_type``
    another type on the navigation's topic; ``swap_stamps`` navigation messages logged
    after the next one (their stamps out of order in the bag); ``steps`` fewer steps; ``rename``
    topics renamed; ``imu`` a topic for the attitude as a ``sensor_msgs/msg/Imu`` too."""
    ros1 = storage == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:  # ROS 1's tf2_msgs is not in rosbags' Noetic store
        tf = "geometry_msgs/TransformStamped[] transforms\n"
        store.register(get_types_from_msg(tf, "tf2_msgs/msg/TFMessage"))
    ty = store.types
    N = steps or dive.steps
    stamps = EPOCH_NS + np.arange(N, dtype=np.int64) * int(T * 1e9)

    def header(ns: int, frame: str) -> object:
        time = ty["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))
        if ros1:
            return ty["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)
        return ty["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def vector(v: np.ndarray) -> object:
        return ty["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    messages: list[tuple[str, str, int, object]] = []
    identity = ty["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    transforms = [
        ty["geometry_msgs/msg/TransformStamped"](
            header=header(int(stamps[0]), "base_link"),
            child_frame_id=child,
            transform=ty["geometry_msgs/msg/Transform"](
                translation=vector(MIDPOINT + (0.5 if child == "sonar_1" else -0.5) * BASELINE),
                rotation=identity,
            ),
        )
        for child in tf_children
    ]
    messages.append(("/tf_static", "tf2_msgs/msg/TFMessage", int(stamps[0]),
                     ty["tf2_msgs/msg/TFMessage"](transforms=transforms)))  # fmt: skip
    nav_stamps = stamps.copy()
    for k in swap_stamps:
        nav_stamps[[k, k + 1]] = nav_stamps[[k + 1, k]]
    omega_B = np.array([0.02, -0.01, 0.7])  # body rate: U moves about base_link
    for k in range(N):
        R = dive.R[k]
        p_base = dive.p_WU[k] - R @ MIDPOINT
        v_B = R.T @ dive.v_WU[k] - np.cross(omega_B, MIDPOINT)
        w, x, y, z = _quaternion(R)
        pose = ty["geometry_msgs/msg/Pose"](
            position=ty["geometry_msgs/msg/Point"](x=p_base[0], y=p_base[1], z=p_base[2]),
            orientation=ty["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        )
        twist = ty["geometry_msgs/msg/Twist"](linear=vector(v_B), angular=vector(omega_B))
        odometry = ty["nav_msgs/msg/Odometry"](
            header=header(int(stamps[k]), "world"),
            child_frame_id="base_link",
            pose=ty["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=ty["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
        )
        zero9 = np.zeros(9)
        attitude = ty["sensor_msgs/msg/Imu"](
            header=header(int(stamps[k]), "world"), orientation=pose.orientation,
            orientation_covariance=zero9, angular_velocity=vector(omega_B),
            angular_velocity_covariance=zero9, linear_acceleration=vector(np.zeros(3)),
            linear_acceleration_covariance=zero9,
        )  # fmt: skip
        if imu is not None:
            messages.append((imu, "sensor_msgs/msg/Imu", int(stamps[k]), attitude))
        if navigation_type == "sensor_msgs/msg/Imu":
            odometry = attitude
        messages.append(("/navigation/odometry", navigation_type, int(nav_stamps[k]), odometry))
        accel = ty["geometry_msgs/msg/AccelStamped"](
            header=header(int(stamps[k]), "world"),
            accel=ty["geometry_msgs/msg/Accel"](linear=vector(dive.u1_W[k]),
                                                 angular=vector(np.zeros(3))),
        )  # fmt: skip
        messages.append(("/control/acceleration", "geometry_msgs/msg/AccelStamped",
                         int(stamps[k]), accel))  # fmt: skip
        for i in range(2):
            if (k, i) in dive.missing:
                continue
            Range = ty["sensor_msgs/msg/Range"]
            message = Range(header=header(int(stamps[k]), f"sonar_{i + 1}"), radiation_type=0,
                            field_of_view=0.1, min_range=0.1, max_range=200.0,
                            range=np.float32(dive.ranges[k, i]))  # fmt: skip
            messages.append((f"/sonar_{i + 1}/range", "sensor_msgs/msg/Range", int(stamps[k]),
                             message))  # fmt: skip
    messages = [((rename or {}).get(m[0], m[0]), *m[1:]) for m in messages if m[0] not in skip]
    messages.sort(key=lambda m: m[2])  # a bag is in log-time order
    _write(path, store, messages, storage)
    return path


def _write(path: Path, store: object, messages: list, storage: str) -> None:
    types = {topic: msgtype for topic, msgtype, _, _ in messages}
    if storage == "ros1":
        with Writer1(path) as writer:
            handle = {t: writer.add_connection(t, m, typestore=store) for t, m in types.items()}
            for topic, msgtype, time, message in messages:
                writer.write(handle[topic], time, store.serialize_ros1(message, msgtype))
        return
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    with Writer(path, version=8, storage_plugin=plugin) as writer:
        handle = {t: writer.add_connection(t, m, typestore=store) for t, m in types.items()}
        for topic, msgtype, time, message in messages:
            writer.write(handle[topic], time, store.serialize_cdr(message, msgtype))


def paper_kf(dive: Dive, W: np.ndarray, P0: np.ndarray) -> np.ndarray:
    """The paper's KF (eq. 9) on the dive's float32 ranges: the filtered x(k|k) per step.

    Y = ½(d1² − d2²) = q_sᵀ q + v̄ with the derived noise m = ½(η1 − η2),
    Γ = η1 (d1² − η1)⁺ + η2 (d2² − η2)⁺ + ½(η1² + η2²); a step missing a range only predicts;
    the prediction is x ← A x + B u1_W, P ← A P Aᵀ + B W Bᵀ.
    """
    I3 = np.eye(3)
    A = np.block([[I3, T * I3], [np.zeros((3, 3)), I3]])
    B = np.vstack([0.5 * T**2 * I3, T * I3])
    x, P = np.zeros(6), P0.copy()
    out = np.zeros((dive.steps, 6))
    for k in range(dive.steps):
        d = dive.ranges[k].astype(np.float64)
        if not any((k, i) in dive.missing for i in range(2)):
            C = np.concatenate([dive.R[k] @ BASELINE, np.zeros(3)])
            Y = 0.5 * (d[0] ** 2 - d[1] ** 2)
            m = 0.5 * (ETA[0] - ETA[1])
            gamma = ETA @ np.maximum(d**2 - ETA, 0.0) + 0.5 * ETA @ ETA
            S = C @ P @ C + gamma
            K = P @ C / S
            x = x + K * (Y - m - C @ x)
            P = P - np.outer(K, C @ P)
        out[k] = x
        x = A @ x + B @ dive.u1_W[k]
        P = A @ P @ A.T + B @ W @ B.T
    return out
