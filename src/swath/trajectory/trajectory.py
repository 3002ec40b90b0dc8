"""The :class:`Trajectory` record and the ``trajectory.csv`` format of FORMATS.md.

``trajectory.csv`` has the nine FORMATS.md columns ``t,x,y,z,qw,qx,qy,qz,contact`` and then these
extra columns, in this order:

========  ==========================================================================================
column    meaning
========  ==========================================================================================
``feed``  commanded TCP speed along the path at the sample, m/s: on contact passes the timed speed
          (the feed, or less where a limit slows the tool); on approach, retract and air moves the
          link speed (0 at rest)
``pass``  index (0-based) of the contact pass the sample belongs to; ``-1`` on approach, retract and
          air moves
``wx``    angular velocity of the tool frame about the part frame's x-axis, rad/s (``ω = v · Ω``,
          with ``Ω`` the frame's rotation per metre of travel; see :mod:`swath.trajectory.timing`)
``wy``    the same about the part frame's y-axis, rad/s
``wz``    the same about the part frame's z-axis, rad/s
``force`` (only when the force control was simulated) mean normal contact force while the tool
          passed the sample, N, from :func:`swath.simulate.simulate_force` (added by
          :func:`swath.simulate.force.trajectory_with_force`); ``0`` off contact
``positioner`` (only with a rotary positioner in the cell) the axis angle at the sample, rad
          (:mod:`swath.robot.positioner`); the pose columns stay in the part frame
========  ==========================================================================================

The angular velocity is expressed in the part frame (not the tool frame): between two samples
the orientation advances as ``R(t + dt) ≈ exp([ω]× dt) R(t)``.  Trajectories made by
:func:`swath.trajectory.time_path` always carry ``wx, wy, wz``; :func:`read_csv` reads any
further columns into :attr:`Trajectory.extra`.
"""

from __future__ import annotations

import io as _io
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_file

#: The nine columns every trajectory.csv starts with (FORMATS.md).
CSV_COLUMNS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "contact")

#: Extra columns swath writes after the nine, and what they mean.
EXTRA_COLUMNS = {
    "feed": "commanded TCP speed along the path, m/s",
    "pass": "index of the contact pass this sample belongs to (0-based), -1 on links",
    "wx": "angular velocity of the tool frame about the part x-axis, rad/s (part frame)",
    "wy": "angular velocity of the tool frame about the part y-axis, rad/s (part frame)",
    "wz": "angular velocity of the tool frame about the part z-axis, rad/s (part frame)",
    "force": "simulated normal contact force at the sample, N (0 off contact); only with force control",
    "positioner": "axis angle of a rotary positioner at the sample, rad; only with a positioner in the cell",
}


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Timed TCP poses in the part frame.

    Attributes
    ----------
    t : (n,) float
        Time since start, s, non-decreasing.
    position : (n, 3) float
        TCP position, m.
    quaternion : (n, 4) float
        TCP orientation, unit, scalar first ``(qw, qx, qy, qz)``; tool z points into the part.
    contact : (n,) bool
        True while the pad is pressed on the surface.
    feed : (n,) float
        Commanded speed along the path, m/s.
    pass_index : (n,) int
        Contact pass of each sample, -1 on approach/retract/air links.
    extra : dict of str -> (n,) float
        Further per-sample columns written after ``pass`` (documented by whoever adds them).
    metadata : dict
        JSON-serialisable facts about how it was made (planner, tilt, limits).
    """

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    contact: np.ndarray
    feed: np.ndarray
    pass_index: np.ndarray
    extra: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        n = len(self.t)
        shapes = {"position": (n, 3), "quaternion": (n, 4), "contact": (n,), "feed": (n,), "pass_index": (n,)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise InputError(f"trajectory {name} must have shape {shape}, got {np.shape(getattr(self, name))}")
        for name, col in self.extra.items():
            if np.shape(col) != (n,):
                raise InputError(f"trajectory column {name!r} must have shape ({n},), got {np.shape(col)}")
        if n and np.any(np.diff(self.t) < 0):
            raise InputError("trajectory times must be non-decreasing")

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration(self) -> float:
        """Cycle time, s."""
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def segment_lengths(self) -> np.ndarray:
        """(n−1,) TCP travel between consecutive samples, m."""
        return np.linalg.norm(np.diff(self.position, axis=0), axis=1)

    @property
    def contact_length(self) -> float:
        """TCP travel while in contact (both ends of a step in contact), m."""
        both = self.contact[1:] & self.contact[:-1]
        return float(self.segment_lengths()[both].sum())

    @property
    def air_length(self) -> float:
        """TCP travel not in contact (approach, retract, air moves), m."""
        both = self.contact[1:] & self.contact[:-1]
        return float(self.segment_lengths()[~both].sum())

    def tool_z(self) -> np.ndarray:
        """(n, 3) tool z-axis (into the part) in the part frame."""
        w, x, y, z = self.quaternion.T
        return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)

    def tool_x(self) -> np.ndarray:
        """(n, 3) tool x-axis (feed direction) in the part frame."""
        w, x, y, z = self.quaternion.T
        return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1)

    # --- CSV ------------------------------------------------------------------------------------
    def to_csv_text(self) -> str:
        """The trajectory as ``trajectory.csv`` text (FORMATS.md, plus ``feed``, ``pass`` and extras)."""
        extra_names = list(self.extra)
        header = ",".join(CSV_COLUMNS + ("feed", "pass") + tuple(extra_names))
        cols = [self.t[:, None], self.position, self.quaternion]
        num = np.hstack(cols)
        buf = _io.StringIO()
        buf.write(header + "\n")
        extra = np.column_stack([self.extra[k] for k in extra_names]) if extra_names else np.zeros((len(self), 0))
        fmt_num = "%.9f,%.7f,%.7f,%.7f,%.9f,%.9f,%.9f,%.9f"
        for row, c, f, p, e in zip(num, self.contact, self.feed, self.pass_index, extra):
            line = fmt_num % tuple(row) + f",{int(c)},{f:.6g},{int(p)}"
            if len(e):
                line += "," + ",".join(f"{v:.6g}" for v in e)
            buf.write(line + "\n")
        return buf.getvalue()

    def write_csv(self, path) -> None:
        """Write ``trajectory.csv`` atomically (temporary file, then rename)."""
        with atomic_file(path, "w", encoding="utf-8", newline="") as fh:
            fh.write(self.to_csv_text())


def read_csv(path) -> Trajectory:
    """Read a ``trajectory.csv`` (the nine FORMATS.md columns; ``feed``, ``pass`` and extras if present)."""
    try:
        with open(path, encoding="utf-8") as fh:
            header = fh.readline().strip().split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read trajectory {path}: {exc}") from exc
    if tuple(header[:9]) != CSV_COLUMNS:
        raise InputError(f"trajectory {path}: expected columns {','.join(CSV_COLUMNS)} first, got {','.join(header[:9])}")
    col = {name: data[:, i] for i, name in enumerate(header)}
    n = len(data)
    extra = {k: v for k, v in col.items() if k not in CSV_COLUMNS and k not in ("feed", "pass")}
    return Trajectory(
        t=col["t"], position=data[:, 1:4], quaternion=data[:, 4:8], contact=col["contact"] > 0.5,
        feed=col.get("feed", np.zeros(n)), pass_index=col.get("pass", np.full(n, -1)).astype(int),
        extra=extra,
    )
