"""The ``trajectory`` stage: time a ToolPath into TCP poses and write trajectory.csv."""

from .timing import FeedLimit, LinkSettings, time_path
from .trajectory import CSV_COLUMNS, Trajectory, read_csv

__all__ = ["CSV_COLUMNS", "FeedLimit", "LinkSettings", "Trajectory", "read_csv", "time_path"]
