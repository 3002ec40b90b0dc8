"""The ``trajectory`` stage: time a ToolPath into TCP poses and write trajectory.csv."""

from .trajectory import CSV_COLUMNS, Trajectory, read_csv

__all__ = ["CSV_COLUMNS", "Trajectory", "read_csv"]
