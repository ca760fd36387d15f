"""A run written as a ROS 2 bag in the recording layout (:mod:`~drake_uuv.recordings.layout`).

The bag holds what a vehicle would record (the ranges at their ping times, arriving after the
sonar's latency; the navigation; the commands; the sonars' mounting) and what only a
simulation knows (the truth), with the estimate for people's viewers (Foxglove, PlotJuggler,
rviz). :func:`drake_uuv.recordings.replay.replay` of the bag with the same scenario
reproduces the run's filtered estimates.
"""

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from drake_uuv.diagram import make_uuv_diagram
from drake_uuv.models.measurement import NO_ARRIVAL, OUT_OF_RANGE, VALID
from drake_uuv.recordings.layout import (
    ACCELERATION,
    BODY_FRAME,
    ODOMETRY,
    RANGE,
    RANGE64,
    RANGE64_DEFINITION,
    SONAR_FRAMES,
    TARGET_FRAME,
    TF,
    TWIST,
    WORLD_FRAME,
    RecordingError,
    Topics,
)
from drake_uuv.recordings.rotations import quaternion_from_matrices
from drake_uuv.scenario import Scenario

#: Storage formats of a ROS 2 bag, by the name ``--record-format`` takes.
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}

_SECOND = 1_000_000_000
_NAVIGATION = ("p_WU_nav", "v_WU_nav", "R_WB_nav")


def typestore() -> Typestore:
    """ROS 2 Humble's message types and drake_uuv's ``Range64``."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(RANGE64_DEFINITION, RANGE64))
    return store


def nanoseconds(seconds: float | np.ndarray) -> np.ndarray:
    """Seconds as integer nanoseconds (rounded)."""
    return np.rint(np.asarray(seconds, dtype=float) * _SECOND).astype(np.int64)


class _Messages:
    """The message constructors of a typestore."""

    def __init__(self, store: Typestore) -> None:
        self.store = store
        types = store.types
        self.Time = types["builtin_interfaces/msg/Time"]
        self.Header = types["std_msgs/msg/Header"]
        self.Vector3 = types["geometry_msgs/msg/Vector3"]
        self.Point = types["geometry_msgs/msg/Point"]
        self.Quaternion = types["geometry_msgs/msg/Quaternion"]
        self.Pose = types["geometry_msgs/msg/Pose"]
        self.PoseCov = types["geometry_msgs/msg/PoseWithCovariance"]
        self.Twist = types["geometry_msgs/msg/Twist"]
        self.TwistCov = types["geometry_msgs/msg/TwistWithCovariance"]
        self.Accel = types["geometry_msgs/msg/Accel"]
        self.Transform = types["geometry_msgs/msg/Transform"]
        self.TransformStamped = types["geometry_msgs/msg/TransformStamped"]
        self.types = types

    def header(self, stamp_ns: int, frame: str) -> object:
        sec, nanosec = divmod(int(stamp_ns), _SECOND)
        return self.Header(stamp=self.Time(sec=sec, nanosec=nanosec), frame_id=frame)

    def vector(self, v: np.ndarray) -> object:
        return self.Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def odometry(
        self,
        stamp_ns: int,
        child: str,
        p: np.ndarray,
        quaternion: np.ndarray,
        v_child: np.ndarray,
        pose_covariance: np.ndarray | None = None,
        twist_covariance: np.ndarray | None = None,
    ) -> object:
        zero = np.zeros(36)
        pose = self.Pose(
            position=self.Point(x=float(p[0]), y=float(p[1]), z=float(p[2])),
            orientation=self.Quaternion(
                x=float(quaternion[1]),
                y=float(quaternion[2]),
                z=float(quaternion[3]),
                w=float(quaternion[0]),
            ),
        )
        twist = self.Twist(linear=self.vector(v_child), angular=self.vector(np.zeros(3)))
        return self.types[ODOMETRY](
            header=self.header(stamp_ns, WORLD_FRAME),
            child_frame_id=child,
            pose=self.PoseCov(pose=pose, covariance=_covariance(pose_covariance, zero)),
            twist=self.TwistCov(twist=twist, covariance=_covariance(twist_covariance, zero)),
        )


def _covariance(position_block: np.ndarray | None, zero: np.ndarray) -> np.ndarray:
    """A ROS 6×6 covariance (x, y, z, then rotations) with ``position_block`` (3×3) first."""
    if position_block is None:
        return zero
    covariance = np.zeros((6, 6))
    covariance[:3, :3] = position_block
    return covariance.ravel()


def write_recording(
    path: str | Path,
    log: Mapping[str, np.ndarray],
    scenario: Scenario,
    *,
    storage: str = "mcap",
    start_ns: int = 0,
    topics: Topics | None = None,
    initial_navigation: Mapping[str, np.ndarray] | None = None,
) -> Path:
    """Writes a run's ``log`` (of ``scenario``) at ``path`` as a ROS 2 bag (MCAP or sqlite3).

    ``initial_navigation`` (``p_WU_nav``, ``v_WU_nav``, ``R_WB_nav``), when given, is the
    navigation the estimator started from (:func:`navigation_at_initialization`): written as
    the first navigation message, at the first step's stamp, before the step's own.

    Step k is stamped ``start_ns + k t``. Each range is one ``sensor_msgs/msg/Range`` stamped
    with its ping time and logged when it arrived (ping time + latency); a return the sonar
    dropped is NaN, one out of range +inf (REP-117); a tick without an arrival has none.
    ``path`` must not exist (rosbags' writer refuses it).
    """
    path = Path(path)
    if path.exists():
        raise RecordingError(f"--record: {str(path)!r} exists (a recording is a new folder)")
    if storage not in STORAGES:
        raise RecordingError(f"storage: must be one of {', '.join(STORAGES)}, got {storage!r}")
    f = scenario.sonar.samples_per_step
    if f != 1:  # the log holds each ping's first sample only
        raise RecordingError(f"--record: sonar.samples_per_step must be 1, got {f}")
    topics = topics or Topics()
    store = typestore()
    make = _Messages(store)
    t = scenario.time_step
    steps = len(log["k"])
    ticks = start_ns + nanoseconds(np.arange(steps) * t)
    latency = int(nanoseconds(scenario.sonar.latency))
    messages = []
    if initial_navigation is not None:
        start = {name: np.asarray(initial_navigation[name])[None] for name in _NAVIGATION}
        R = start["R_WB_nav"].reshape(1, 3, 3)
        v_B = R[0].T @ start["v_WU_nav"][0]
        message = make.odometry(
            int(ticks[0]), BODY_FRAME, start["p_WU_nav"][0], quaternion_from_matrices(R)[0], v_B
        )
        messages.append((topics.navigation, int(ticks[0]), message))
    messages += _vehicle(make, log, scenario, topics, ticks)
    messages += _ranges(make, log, scenario, topics, ticks, latency)
    messages += _truth(make, log, topics, ticks)
    messages += _estimate(make, log, topics, ticks)

    connections = {
        RANGE: [*topics.sonars],
        RANGE64: [Topics.precise(s) for s in topics.sonars],
        ODOMETRY: [topics.navigation, topics.truth_vehicle, topics.truth_target, topics.estimate],
        ACCELERATION: [topics.acceleration],
        TWIST: [topics.angular_velocity],
        TF: [topics.tf_static],
    }
    messages.sort(key=lambda m: m[1])  # a bag is in log-time order
    with Writer(path, version=8, storage_plugin=STORAGES[storage]) as writer:
        writer.set_custom_data("drake_uuv.seed", str(scenario.random_seed))
        handle = {
            topic: writer.add_connection(topic, msgtype, typestore=store)
            for msgtype, names in connections.items()
            for topic in names
        }
        for topic, time_ns, message in messages:
            msgtype = message.__msgtype__
            writer.write(handle[topic], time_ns, store.serialize_cdr(message, msgtype))
    return path


def navigation_at_initialization(scenario: Scenario) -> dict[str, np.ndarray]:
    """What the run's estimator starts from (its initialization event reads the navigation
    before the navigation's own initialization latches its biases): the navigation's outputs
    on the seeded context before ``Simulator.Initialize``, as a run of ``scenario`` has it."""
    built = make_uuv_diagram(scenario, log=False)
    context = built.diagram.CreateDefaultContext()
    built.set_random_context(context, scenario.random_seed)
    navigation = built.systems["navigation"]
    mine = navigation.GetMyContextFromRoot(context)
    return {name: navigation.GetOutputPort(name).Eval(mine).copy() for name in _NAVIGATION}


def record_run(
    path: str | Path, log: Mapping[str, np.ndarray], scenario: Scenario, storage: str = "mcap"
) -> Path:
    """Writes a run of ``scenario`` (its ``log``) as :func:`write_recording` does (``storage``
    mcap or sqlite3), with the navigation its estimator started from: a replay then starts
    where the run did."""
    return write_recording(
        path,
        log,
        scenario,
        storage=storage,
        initial_navigation=navigation_at_initialization(scenario),
    )


def _vehicle(
    make: _Messages,
    log: Mapping[str, np.ndarray],
    scenario: Scenario,
    topics: Topics,
    ticks: np.ndarray,
) -> list[tuple[str, int, object]]:
    """What the vehicle knows of itself: the sonars' mounting, its navigation, its commands."""
    store, steps = make.store, len(ticks)
    R_nav = log["R_WB_nav"].reshape(steps, 3, 3)
    q_nav = quaternion_from_matrices(R_nav)
    v_nav_B = np.einsum("kji,kj->ki", R_nav, log["v_WU_nav"])
    b = np.asarray(scenario.sonar.baseline, dtype=float)
    messages: list[tuple[str, int, object]] = []
    transforms = [
        make.TransformStamped(
            header=make.header(int(ticks[0]), BODY_FRAME),
            child_frame_id=frame,
            transform=make.Transform(
                translation=make.vector(sign * 0.5 * b),
                rotation=make.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        for frame, sign in zip(SONAR_FRAMES, (1.0, -1.0), strict=True)
    ]
    messages.append((topics.tf_static, int(ticks[0]), store.types[TF](transforms=transforms)))
    for k in range(steps):
        stamp = int(ticks[k])
        messages.append(
            (topics.navigation, stamp,
             make.odometry(stamp, BODY_FRAME, log["p_WU_nav"][k], q_nav[k], v_nav_B[k]))
        )  # fmt: skip
        header = make.header(stamp, WORLD_FRAME)
        accel = make.Accel(linear=make.vector(log["u1_W"][k]), angular=make.vector(np.zeros(3)))
        messages.append((topics.acceleration, stamp, store.types[ACCELERATION](header, accel)))
        twist = make.Twist(linear=make.vector(np.zeros(3)), angular=make.vector(log["u2_W"][k]))
        rate = store.types[TWIST](make.header(stamp, WORLD_FRAME), twist)
        messages.append((topics.angular_velocity, stamp, rate))
    return messages


def _ranges(
    make: _Messages,
    log: Mapping[str, np.ndarray],
    scenario: Scenario,
    topics: Topics,
    ticks: np.ndarray,
    latency: int,
) -> list[tuple[str, int, object]]:
    """Each arrived range as a float32 Range and its float64 companion."""
    Range = make.types[RANGE]
    Range64 = make.types[RANGE64]
    max_range = scenario.sonar.max_range
    max_range = math.inf if max_range is None else float(max_range)
    start = int(ticks[0])
    ping_ns = start + nanoseconds(np.nan_to_num(log["ping_time"], nan=0.0))
    messages = []
    for k in range(len(ticks)):
        for i in range(2):
            status = int(log["sonar_status"][k, i])
            if status == NO_ARRIVAL:
                continue
            if status == VALID:
                value = float(log["ranges"][k, i])
            elif status == OUT_OF_RANGE:
                value = math.inf
            else:
                value = math.nan
            stamp = int(ping_ns[k, i]) if np.isfinite(log["ping_time"][k, i]) else int(ticks[k])
            # The arrival, no later than the tick that took it.
            arrival = min(stamp + latency, int(ticks[k]))
            frame = SONAR_FRAMES[i]
            header = make.header(stamp, frame)
            message = Range(
                header=header, radiation_type=Range.ULTRASOUND, field_of_view=0.0,
                min_range=0.0, max_range=max_range, range=value,
            )  # fmt: skip
            messages.append((topics.sonars[i], arrival, message))
            precise = Range64(header=make.header(stamp, frame), range=value)
            messages.append((Topics.precise(topics.sonars[i]), arrival, precise))
    return messages


def _truth(
    make: _Messages, log: Mapping[str, np.ndarray], topics: Topics, ticks: np.ndarray
) -> list[tuple[str, int, object]]:
    steps = len(ticks)
    R = log["R_WB"].reshape(steps, 3, 3)
    q = quaternion_from_matrices(R)
    v_B = np.einsum("kji,kj->ki", R, log["v_WU"])
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    messages = []
    for k in range(steps):
        stamp = int(ticks[k])
        vehicle = make.odometry(stamp, BODY_FRAME, log["p_WU"][k], q[k], v_B[k])
        target = make.odometry(stamp, TARGET_FRAME, log["p_WT"][k], identity, log["v_WT"][k])
        messages += [(topics.truth_vehicle, stamp, vehicle), (topics.truth_target, stamp, target)]
    return messages


def _estimate(
    make: _Messages, log: Mapping[str, np.ndarray], topics: Topics, ticks: np.ndarray
) -> list[tuple[str, int, object]]:
    """The estimated target, ``p_WU_nav − q̂`` and ``v_WU_nav − ϑ̂``, with P's blocks."""
    steps = len(ticks)
    x = log["x_TU_hat"]
    P = log["P_TU"].reshape(steps, 6, 6)
    p_WT = log["p_WU_nav"] - x[:, :3]
    v_WT = log["v_WU_nav"] - x[:, 3:]
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    return [
        (
            topics.estimate,
            int(ticks[k]),
            make.odometry(
                int(ticks[k]), TARGET_FRAME, p_WT[k], identity, v_WT[k], P[k, :3, :3], P[k, 3:, 3:]
            ),
        )
        for k in range(steps)
    ]
