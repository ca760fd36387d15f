"""A recording's layout: its topics, their message types, its frames, and its errors.

The default layout (the topics of :class:`Topics`, renamed by a ``topics.yaml``):

- ``/sonar_1/range``, ``/sonar_2/range`` (``sensor_msgs/msg/Range``): one message per range
  sample, ``header.stamp`` the ping time (the f samples of a ping share it), the bag's log
  time when it arrived.
- ``/navigation/odometry`` (``nav_msgs/msg/Odometry``): the navigated pose of ``base_link``
  in ``world`` and its twist in ``base_link``, at each step or faster.
- ``/control/acceleration`` (``geometry_msgs/msg/AccelStamped``): the commanded world
  acceleration ``u1_W``, held until the next message (for ``vehicle_motion: commanded``).
- ``/tf_static`` (``tf2_msgs/msg/TFMessage``): ``base_link`` → ``sonar_1`` and ``sonar_2``,
  the sonars' mounting: the baseline ``b = p_s1 − p_s2``.
- ``/truth/vehicle/odometry``, ``/truth/target/odometry`` (``nav_msgs/msg/Odometry``):
  optional truth for the metrics.

A recording of drake_uuv's adds ``/sonar_i/range/float64`` (``drake_uuv_msgs/msg/Range64``,
each sample in float64: ``Range.range`` is float32, 0.5 µm at 10 m, where a replay reproduces
a run to 1e-9), ``/estimate/target/odometry`` (the estimated target, its covariance),
``/control/angular_velocity`` (``u2_W``) and the truth.

**Frames** (REP-103, REP-105). drake_uuv's world W (z up) *is* the ENU frame ``world``
(x east, y north, z up), and its body frame B *is* ``base_link`` (x forward, y left, z up),
with U (the sonars' midpoint) its origin: no rotation between them. An Odometry's pose is
in ``header.frame_id`` (``world``): ``p_WU`` and ``R_WB`` as a quaternion; its twist in
``child_frame_id`` (``base_link``): ``v_B = R_WBᵀ v_WU``. The target's truth and estimate
have child frame ``target`` with the identity orientation, so their twist is ``v_WT`` in W.
A ``sensor_msgs/msg/Imu`` for the attitude (``--topics``) gives ``R_WB`` from its
orientation, in the same ``world``.
"""

from dataclasses import dataclass, fields
from pathlib import Path

import yaml

RANGE = "sensor_msgs/msg/Range"
RANGE64 = "drake_uuv_msgs/msg/Range64"
ODOMETRY = "nav_msgs/msg/Odometry"
ACCELERATION = "geometry_msgs/msg/AccelStamped"
TWIST = "geometry_msgs/msg/TwistStamped"
TF = "tf2_msgs/msg/TFMessage"
IMU = "sensor_msgs/msg/Imu"

#: drake_uuv's own message: a range sample in float64 (the ``sensor_msgs`` one is float32).
RANGE64_DEFINITION = "std_msgs/Header header\nfloat64 range\n"

WORLD_FRAME = "world"
BODY_FRAME = "base_link"
TARGET_FRAME = "target"
SONAR_FRAMES = ("sonar_1", "sonar_2")


class RecordingError(ValueError):
    """A recording (or its topics file) that cannot be replayed: one line naming why."""


@dataclass(frozen=True)
class Topics:
    """The topics of a recording, by role. A ``topics.yaml`` renames any of them (keys are
    these fields); ``attitude`` names a ``sensor_msgs/msg/Imu`` topic whose orientation is the
    navigated attitude (None: the navigation's pose)."""

    sonar_1: str = "/sonar_1/range"
    sonar_2: str = "/sonar_2/range"
    navigation: str = "/navigation/odometry"
    attitude: str | None = None
    acceleration: str = "/control/acceleration"
    tf_static: str = "/tf_static"
    truth_vehicle: str = "/truth/vehicle/odometry"
    truth_target: str = "/truth/target/odometry"
    estimate: str = "/estimate/target/odometry"
    angular_velocity: str = "/control/angular_velocity"

    @property
    def sonars(self) -> tuple[str, str]:
        return (self.sonar_1, self.sonar_2)

    @staticmethod
    def precise(topic: str) -> str:
        """The float64 companion of a sonar's topic."""
        return f"{topic}/float64"


def load_topics(path: str | Path | None) -> Topics:
    """The layout of a ``topics.yaml`` (a mapping of :class:`Topics` fields to topic names),
    the default without one; a bad file is a :class:`RecordingError` naming the key."""
    if path is None:
        return Topics()
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as e:
        raise RecordingError(f"--topics: cannot read {str(path)!r}: {e.strerror}") from e
    except yaml.YAMLError as e:
        reason = " ".join(str(e).split())
        raise RecordingError(f"--topics: {str(path)!r} is not YAML: {reason}") from e
    data = data or {}
    if not isinstance(data, dict):
        raise RecordingError(f"--topics: must map roles to topic names, got {data!r}")
    known = [f.name for f in fields(Topics)]
    for key, value in data.items():
        if key not in known:
            raise RecordingError(f"--topics: unknown role {key!r} (known: {', '.join(known)})")
        if not (isinstance(value, str) and value.startswith("/")) and not (
            key == "attitude" and value is None
        ):
            raise RecordingError(f"--topics: {key}: must be a topic name like /a/b, got {value!r}")
    return Topics(**data)
