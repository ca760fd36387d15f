"""Field data: a run written as a ROS bag, and a recording replayed through the estimator.

:func:`write_recording` writes a run's log in the recording layout (:mod:`.layout`);
:func:`read_recording` reads a ROS 2 (MCAP, sqlite3) or ROS 1 bag in that layout onto the
estimator's clock; :func:`replay` runs the scenario's estimator on it. Reading and writing go
through ``rosbags`` (pure Python: no ROS install).
"""

from drake_uuv.recordings.layout import RecordingError, Topics, load_topics
from drake_uuv.recordings.reader import Recording, read_recording
from drake_uuv.recordings.replay import RecordingSource, make_replay_diagram, replay
from drake_uuv.recordings.writer import (
    navigation_at_initialization,
    record_run,
    write_recording,
)

__all__ = [
    "Recording",
    "RecordingError",
    "RecordingSource",
    "Topics",
    "load_topics",
    "make_replay_diagram",
    "navigation_at_initialization",
    "record_run",
    "read_recording",
    "replay",
    "write_recording",
]
