"""A recording read onto the estimator's clock: what each tick's estimator inputs hold.

A bag in the layout of :mod:`~drake_uuv.recordings.layout` (ROS 2 MCAP or sqlite3, or a ROS 1
``.bag``, all through ``rosbags``' :class:`~rosbags.highlevel.AnyReader`) becomes per-tick
arrays. The clock: the first header stamp of the navigation, attitude, commands and ranges
is step 0 (stamps may be a real epoch: times are integer nanoseconds until the last step);
tick k is ``t0 + k t``; the last such stamp ends the recording.

- **Navigation, attitude, commands**: at tick k, the latest message stamped at or before it
  (held before the first).
- **Ranges**: the messages of one sonar sharing a stamp are one ping (its ``f`` samples, in
  the order recorded); the ping's time is the stamp, and it reaches the estimator at the
  first tick at or after its log time (when it arrived). The ping offsets are the median of
  the pings' stamps past their step's tick, the latency the largest delay from a ping to its
  arrival: with them, the estimator's window of late ranges is the recording's. A tick whose
  due ping has no message is a dropout (DROPPED, NaN samples); before a sonar's first due
  ping, NO_ARRIVAL. A finite range inside ``[min_range, max_range]`` is VALID, ``+inf`` is
  OUT_OF_RANGE, anything else (NaN, ``-inf``) DROPPED.
- **Mounting**: ``/tf_static``'s ``base_link`` → ``sonar_1``, ``sonar_2`` translations give the
  baseline ``b = p_s1 − p_s2`` and U, their midpoint, from which the navigated ``base_link``
  is moved (``p_WU = p + R r``, ``v_WU = R (v_B + ω_B × r)``).

A recording that cannot be replayed raises :class:`~drake_uuv.recordings.layout.RecordingError`
in one line (a missing topic naming those present, a wrong message type, no mounting, shorter
than one step); stamps out of order are sorted with a warning (:attr:`Recording.warnings`).
"""

import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError

from drake_uuv.models.measurement import DROPPED, NO_ARRIVAL, OUT_OF_RANGE, VALID
from drake_uuv.models.timing import PingSchedule
from drake_uuv.recordings.layout import (
    ACCELERATION,
    BODY_FRAME,
    IMU,
    ODOMETRY,
    RANGE,
    RANGE64,
    SONAR_FRAMES,
    TF,
    RecordingError,
    Topics,
)
from drake_uuv.recordings.rotations import matrices_from_quaternions

_SECOND = 1_000_000_000


@dataclass
class Recording:
    """A recording on the estimator's clock: N ticks from ``start_ns``, every step ``t``.

    Per tick (row k): ``R_WB_nav`` (N×9, row-major), ``p_WU_nav``, ``v_WU_nav``, ``u1_W``
    (N×3; ``u1_W`` zero without a commands topic), ``range_samples`` (N×2f, sonar 1's then
    sonar 2's), ``sonar_status`` (N×2), ``ping_time`` (N×2, seconds from ``start_ns``; NaN
    with NO_ARRIVAL). ``baseline`` b (3) from the mounting, ``ping_offsets`` (2) and
    ``latency`` [s] from the stamps; ``initial`` the navigation the estimator starts from;
    ``truth`` the recorded truth at each tick (``p_WU``,
    ``v_WU``, ``R_WB``, ``p_WT``, ``v_WT``) or empty; ``warnings`` what was mended.
    """

    path: Path
    start_ns: int
    time_step: float
    R_WB_nav: np.ndarray
    p_WU_nav: np.ndarray
    v_WU_nav: np.ndarray
    u1_W: np.ndarray
    range_samples: np.ndarray
    sonar_status: np.ndarray
    ping_time: np.ndarray
    baseline: np.ndarray
    ping_offsets: tuple[float, float]
    latency: float
    truth: dict[str, np.ndarray] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    has_commands: bool = True
    # The navigation the estimator starts from (rows of p_WU_nav, v_WU_nav, R_WB_nav):
    # the first navigation message when two share the first stamp, else step 0's.
    initial: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def steps(self) -> int:
        return len(self.p_WU_nav)


@dataclass
class _Stamped:
    """One topic's messages, sorted by header stamp: stamps (ns), log times (ns), messages."""

    stamps: np.ndarray
    times: np.ndarray
    messages: list


def _stamp(message: object) -> int:
    stamp = message.header.stamp
    return int(stamp.sec) * _SECOND + int(stamp.nanosec)


class _Bag:
    """An open recording: its topics and types, and the messages of a topic."""

    def __init__(self, reader: AnyReader, path: Path) -> None:
        self.reader = reader
        self.path = path
        self.types: dict[str, str] = {}
        for connection in reader.connections:
            self.types.setdefault(connection.topic, connection.msgtype)
        self.warnings: list[str] = []
        self._loaded: dict[str, tuple[list, list]] = {}

    def fail(self, message: str) -> RecordingError:
        return RecordingError(f"recording {str(self.path)!r}: {message}")

    def check(self, topic: str, expected: tuple[str, ...], holds: str) -> None:
        """Refuses a missing topic (naming those present) or one of another type."""
        if topic not in self.types:
            present = ", ".join(sorted(self.types)) or "none"
            raise self.fail(f"no topic {topic} ({holds}, {expected[0]}); its topics: {present}")
        if self.types[topic] not in expected:
            raise self.fail(
                f"topic {topic} is {self.types[topic]}, expected {' or '.join(expected)} ({holds})"
            )

    def load(self, topics: list[str]) -> None:
        """Reads the messages of ``topics`` (those present) in one pass over the bag."""
        connections = [c for c in self.reader.connections if c.topic in topics]
        for connection, time, raw in self.reader.messages(connections=connections):
            times, messages = self._loaded.setdefault(connection.topic, ([], []))
            times.append(time)
            messages.append(self.reader.deserialize(raw, connection.msgtype))

    def read(self, topic: str, stamped: bool = True) -> _Stamped:
        """The topic's messages sorted by header stamp (a warning if they were not)."""
        if topic not in self._loaded:
            self.load([topic])
        times, messages = self._loaded.get(topic, ([], []))
        times = np.asarray(times, dtype=np.int64)
        if not stamped:
            return _Stamped(times, times, messages)
        stamps = np.fromiter((_stamp(m) for m in messages), dtype=np.int64, count=len(messages))
        if np.any(np.diff(stamps) < 0):
            late = int(np.sum(np.diff(stamps) < 0))
            self.warnings.append(
                f"{topic}: {late} header stamps out of order in the recording; sorted by stamp"
            )
            order = np.argsort(stamps, kind="stable")
            stamps, times = stamps[order], times[order]
            messages = [messages[i] for i in order]
        return _Stamped(stamps, times, messages)


def read_recording(
    path: str | Path,
    *,
    time_step: float,
    samples_per_step: int = 1,
    topics: Topics | None = None,
    commands: bool = True,
) -> Recording:
    """Reads the recording at ``path`` (a ROS 2 bag's folder, or a ROS 1 ``.bag``) onto the
    clock of ``time_step``, each ping's first ``samples_per_step`` samples; ``commands``:
    whether the commanded acceleration is needed (``vehicle_motion: commanded``)."""
    path = Path(path)
    topics = topics or Topics()
    if not path.exists():
        raise RecordingError(f"recording {str(path)!r}: no such file or folder")
    try:
        with AnyReader([path]) as reader:
            return _read(_Bag(reader, path), time_step, samples_per_step, topics, commands)
    except AnyReaderError as e:
        reason = " ".join(str(e).split())
        raise RecordingError(f"recording {str(path)!r}: not a ROS bag ({reason})") from e


def _check_topics(bag: _Bag, topics: Topics, commands: bool) -> None:
    """Refuses a missing topic, a wrong type or no mounting topic, before reading any."""
    for i, topic in enumerate(topics.sonars):
        bag.check(topic, (RANGE,), f"sonar {i + 1}'s ranges")
    bag.check(topics.navigation, (ODOMETRY,), "the navigated pose and twist")
    if topics.attitude is not None:
        bag.check(topics.attitude, (IMU,), "the navigated attitude")
    if commands:
        bag.check(topics.acceleration, (ACCELERATION,), "the commanded world acceleration")
    if topics.tf_static not in bag.types:
        present = ", ".join(sorted(bag.types)) or "none"
        raise bag.fail(
            f"no sonar mounting: no topic {topics.tf_static} ({TF}, base_link → sonar_1, "
            f"sonar_2); its topics: {present}"
        )
    bag.check(topics.tf_static, (TF,), "the sonars' mounting")


def _read(bag: _Bag, t: float, f: int, topics: Topics, commands: bool) -> Recording:
    _check_topics(bag, topics, commands)
    bag.load(
        [*topics.sonars, *(Topics.precise(topic) for topic in topics.sonars), topics.navigation,
         topics.attitude, topics.acceleration if commands else None, topics.tf_static,
         topics.truth_vehicle, topics.truth_target]
    )  # fmt: skip
    offset, baseline = _mounting(bag, topics.tf_static)
    navigation = bag.read(topics.navigation)
    attitude = bag.read(topics.attitude) if topics.attitude is not None else None
    acceleration = bag.read(topics.acceleration) if commands else None
    sonars = [_sonar(bag, topic) for topic in topics.sonars]
    named = zip((topics.navigation, *topics.sonars), (navigation, *sonars), strict=True)
    for topic in (topic for topic, read in named if len(read.stamps) == 0):
        raise bag.fail(f"topic {topic} has no messages")
    clocked = [navigation, *sonars] + [r for r in (attitude, acceleration) if r is not None]
    start = min(int(r.stamps[0]) for r in clocked if len(r.stamps))
    end = max(int(r.stamps[-1]) for r in clocked if len(r.stamps))
    step = int(round(t * _SECOND))
    if end - start < step:
        raise bag.fail(
            f"its stamps span {(end - start) / _SECOND:g} s, shorter than one step "
            f"(time_step {t:g} s)"
        )
    ticks = start + step * np.arange((end - start) // step + 1, dtype=np.int64)
    p, R, v_B, w_B = _odometry(navigation.messages)
    at = _latest(navigation.stamps, ticks)
    R_WB = R[at]
    if attitude is not None:
        R_WB = _imu(attitude.messages)[_latest(attitude.stamps, ticks)]
    # From base_link to U, the sonars' midpoint.
    p_WU = p[at] + np.einsum("kij,j->ki", R_WB, offset)
    v_WU = np.einsum("kij,kj->ki", R_WB, v_B[at] + np.cross(w_B[at], offset))
    initial = {"p_WU_nav": p_WU[0], "v_WU_nav": v_WU[0], "R_WB_nav": R_WB[0].ravel()}
    if len(navigation.stamps) > 1 and navigation.stamps[0] == navigation.stamps[1]:
        # Two messages at the first stamp: the first is the state the estimator starts from.
        R0 = R_WB[0] if attitude is not None else R[0]
        initial = {
            "p_WU_nav": p[0] + R0 @ offset,
            "v_WU_nav": R0 @ (v_B[0] + np.cross(w_B[0], offset)),
            "R_WB_nav": R0.ravel(),
        }

    u1_W = np.zeros((len(ticks), 3))
    if acceleration is not None and len(acceleration.stamps):
        linear = np.array([_xyz(m.accel.linear) for m in acceleration.messages])
        held = _latest(acceleration.stamps, ticks, before=-1)
        u1_W = np.where(held[:, None] >= 0, linear[np.maximum(held, 0)], 0.0)
    offsets, latency = _schedule(sonars, start, step)
    schedule = PingSchedule(t, offsets, latency)
    samples = np.full((len(ticks), 2, f), np.nan)
    status = np.full((len(ticks), 2), NO_ARRIVAL, dtype=np.int8)
    ping_time = np.full((len(ticks), 2), np.nan)
    for i, sonar in enumerate(sonars):
        _place_pings(bag, topics.sonars[i], sonar, i, f, start, step, schedule, offsets[i],
                     samples, status, ping_time)  # fmt: skip

    truth = {}
    if topics.truth_vehicle in bag.types and topics.truth_target in bag.types:
        truth = _truth(bag, topics, ticks, offset)
    return Recording(
        path=bag.path,
        start_ns=start,
        time_step=t,
        R_WB_nav=R_WB.reshape(len(ticks), 9),
        p_WU_nav=p_WU,
        v_WU_nav=v_WU,
        u1_W=u1_W,
        range_samples=samples.reshape(len(ticks), 2 * f),
        sonar_status=status,
        ping_time=ping_time,
        baseline=baseline,
        ping_offsets=offsets,
        latency=latency,
        truth=truth,
        warnings=bag.warnings,
        has_commands=commands,
        initial=initial,
    )


def _xyz(v: object) -> tuple[float, float, float]:
    return (v.x, v.y, v.z)


def _latest(stamps: np.ndarray, ticks: np.ndarray, before: int = 0) -> np.ndarray:
    """Per tick, the index of the latest stamp at or before it (``before`` if none)."""
    index = np.searchsorted(stamps, ticks, side="right") - 1
    return np.where(index < 0, before, index)


def _odometry(messages: list) -> tuple[np.ndarray, ...]:
    """Positions, attitudes, body-frame linear and angular velocities of Odometry messages."""
    p = np.array([_xyz(m.pose.pose.position) for m in messages])
    q = np.array([(o.w, o.x, o.y, o.z) for o in (m.pose.pose.orientation for m in messages)])
    v = np.array([_xyz(m.twist.twist.linear) for m in messages])
    w = np.array([_xyz(m.twist.twist.angular) for m in messages])
    return p, matrices_from_quaternions(q), v, w


def _imu(messages: list) -> np.ndarray:
    q = np.array([(o.w, o.x, o.y, o.z) for o in (m.orientation for m in messages)])
    return matrices_from_quaternions(q)


def _mounting(bag: _Bag, topic: str) -> tuple[np.ndarray, np.ndarray]:
    """U in base_link (the sonars' midpoint) and the baseline b = p_s1 − p_s2."""
    found: dict[str, np.ndarray] = {}
    for message in bag.read(topic, stamped=False).messages:
        for transform in message.transforms:
            parent = transform.header.frame_id.lstrip("/")
            child = transform.child_frame_id.lstrip("/")
            if parent == BODY_FRAME and child in SONAR_FRAMES:
                found[child] = np.array(_xyz(transform.transform.translation))
    missing = [frame for frame in SONAR_FRAMES if frame not in found]
    if missing:
        raise bag.fail(
            f"no sonar mounting: {topic} has no transform {BODY_FRAME} → {', '.join(missing)}"
        )
    s1, s2 = (found[frame] for frame in SONAR_FRAMES)
    return 0.5 * (s1 + s2), s1 - s2


@dataclass
class _Sonar:
    """One sonar's pings: stamps (ns), arrivals (ns), samples (list of arrays), status."""

    stamps: np.ndarray
    arrivals: np.ndarray
    samples: list[np.ndarray]
    status: np.ndarray


def _sonar(bag: _Bag, topic: str) -> _Sonar:
    """A sonar topic's pings; float64 samples from its companion where they round to it."""
    read = bag.read(topic)
    values = np.array([m.range for m in read.messages], dtype=np.float64)
    low = np.array([m.min_range for m in read.messages], dtype=np.float64)
    high = np.array([m.max_range for m in read.messages], dtype=np.float64)
    precise = Topics.precise(topic)
    if bag.types.get(precise) == RANGE64:
        companion = bag.read(precise)
        by_stamp: dict[int, list[float]] = defaultdict(list)
        for stamp, message in zip(companion.stamps, companion.messages, strict=True):
            by_stamp[int(stamp)].append(float(message.range))
        used: dict[int, int] = defaultdict(int)
        for j, stamp in enumerate(read.stamps):
            candidates = by_stamp.get(int(stamp), [])
            n = used[int(stamp)]
            if n < len(candidates):
                value = candidates[n]
                if np.float32(value) == np.float32(values[j]) or (
                    math.isnan(value) and math.isnan(values[j])
                ):
                    values[j] = value
            used[int(stamp)] += 1
    status = np.where(
        np.isfinite(values) & (values >= low) & (values <= high),
        VALID,
        np.where(values == math.inf, OUT_OF_RANGE, DROPPED),
    )
    cuts = np.flatnonzero(np.diff(read.stamps)) + 1
    groups = np.split(np.arange(len(values)), cuts) if len(values) else []
    return _Sonar(
        stamps=np.array([read.stamps[g[0]] for g in groups], dtype=np.int64),
        arrivals=np.array(
            [max(int(read.times[g].max()), int(read.stamps[g[0]])) for g in groups],
            dtype=np.int64,
        ),
        samples=[values[g] for g in groups],
        status=np.array([status[g[0]] for g in groups], dtype=np.int8),
    )


def _schedule(sonars: list[_Sonar], start: int, step: int) -> tuple[tuple[float, float], float]:
    """Each sonar's ping offset (the median past its step's tick) and the latency (the
    largest delay from a ping to its arrival), in seconds, from the stamps."""
    offsets = tuple(
        int(np.median((s.stamps - start) % step)) / _SECOND if len(s.stamps) else 0.0
        for s in sonars
    )
    delays = [int(np.max(s.arrivals - s.stamps)) for s in sonars if len(s.stamps)]
    return offsets, (max(delays) if delays else 0) / _SECOND  # type: ignore[return-value]


def _place_pings(
    bag: _Bag,
    topic: str,
    sonar: _Sonar,
    i: int,
    f: int,
    start: int,
    step: int,
    schedule: PingSchedule,
    offset: float,
    samples: np.ndarray,
    status: np.ndarray,
    ping_time: np.ndarray,
) -> None:
    """Puts each ping at the tick it arrived by; a due ping that did not arrive is DROPPED."""
    N = len(status)
    delay = schedule.delays[i]
    due = np.arange(N) - delay >= 0
    status[due, i] = DROPPED
    ping_time[due, i] = (
        (np.arange(N)[due] - delay) * step + int(round(offset * _SECOND))
    ) / _SECOND
    arrival_ticks = -((start - sonar.arrivals) // step)  # ceil((arrival − start) / step)
    short = 0
    for j in np.argsort(sonar.stamps, kind="stable"):
        k = int(arrival_ticks[j])
        if k >= N:
            continue
        values = sonar.samples[j]
        if len(values) < f:
            short += 1
        row = np.full(f, np.nan)
        row[: min(f, len(values))] = values[:f]
        ok = sonar.status[j]
        samples[k, i] = row if ok == VALID else np.nan
        status[k, i] = ok
        ping_time[k, i] = (int(sonar.stamps[j]) - start) / _SECOND
    if short:
        bag.warnings.append(
            f"{topic}: {short} pings with fewer than {f} samples (NaN for the rest)"
        )


def _truth(bag: _Bag, topics: Topics, ticks: np.ndarray, offset: np.ndarray) -> dict:
    """The recorded truth of the vehicle (moved to U) and the target at each tick."""
    for topic in (topics.truth_vehicle, topics.truth_target):
        bag.check(topic, (ODOMETRY,), "the truth")
    vehicle = bag.read(topics.truth_vehicle)
    target = bag.read(topics.truth_target)
    if not (len(vehicle.stamps) and len(target.stamps)):
        return {}
    p, R, v_B, w_B = _odometry(vehicle.messages)
    at = _latest(vehicle.stamps, ticks)
    pt, Rt, vt, _ = _odometry(target.messages)
    at_t = _latest(target.stamps, ticks)
    R_WB = R[at]
    return {
        "p_WU": p[at] + np.einsum("kij,j->ki", R_WB, offset),
        "v_WU": np.einsum("kij,kj->ki", R_WB, v_B[at] + np.cross(w_B[at], offset)),
        "R_WB": R_WB.reshape(len(ticks), 9),
        "p_WT": pt[at_t],
        "v_WT": np.einsum("kij,kj->ki", Rt[at_t], vt[at_t]),
    }
