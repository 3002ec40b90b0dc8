"""The ``trajectory`` stage: time a ToolPath into TCP poses and write trajectory.csv.

``time_path(toolpath, [FeedLimit(v), CentripetalLimit(a_c), AngularSpeedLimit(w), TangentialAccelLimit(a_t),
FeedProfile(speeds)], links=LinkSettings(...))`` returns a :class:`Trajectory`; see
:mod:`.timing` for how passes are timed, :mod:`.links` for air moves and :mod:`.trajectory` for the
columns of ``trajectory.csv``.
"""

from .constraints import AngularSpeedLimit, CentripetalLimit, FeedLimit, FeedProfile, TangentialAccelLimit
from .links import LinkSettings
from .timing import contact_duration, links_duration_bound, time_passes, time_path
from .trajectory import CSV_COLUMNS, EXTRA_COLUMNS, Trajectory, read_csv

__all__ = ["AngularSpeedLimit", "CSV_COLUMNS", "CentripetalLimit", "EXTRA_COLUMNS", "FeedLimit", "FeedProfile",
           "LinkSettings", "TangentialAccelLimit", "Trajectory", "read_csv", "time_path",
           "time_passes", "contact_duration", "links_duration_bound"]
