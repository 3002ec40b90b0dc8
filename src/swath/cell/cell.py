"""The robot cell record: where the part sits in front of the robot, the tool on the flange, the table
and the fixtures.

Every transform is named ``A2B`` in pytransform3d's convention (:mod:`swath.cell.frames`):
``p_B = A2B @ p_A``, i.e. ``A2B`` is the pose of frame A expressed in frame B.

* ``part2base`` — the part's pose in the robot base frame (``p_base = part2base @ p_part``).
* ``tcp2flange`` — the TCP's pose in the flange frame (FORMATS.md tool frame: z into the part).
* A TCP pose of the trajectory is ``tcp2part``; the flange pose the robot must reach is
  ``flange2base = part2base @ tcp2part @ inv(tcp2flange)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .bodies import Body, Table
from .frames import check_transform, format_pose, invert_transform, parse_pose
from .positioner import Positioner
from .tool import ToolBody

__all__ = ["Cell", "format_pose", "parse_pose"]


@dataclass(frozen=True, eq=False)
class Cell:
    """A robot cell: part placement, tool, table and fixtures (all lengths m).

    Attributes
    ----------
    part2base : (4, 4) float
        The part's pose in the robot base frame.  Default: the part frame on the base frame.
    tcp2flange : (4, 4) float
        The TCP's pose in the flange frame.  Default: the TCP on the flange face, axes aligned.
    tool : ToolBody or None
        The tool's collision bodies in the flange frame (the pad itself is never a collision body:
        it is meant to touch the part).  None: no tool body is checked.
    table : Table or None
        The table the part stands on (base frame); None: no table.
    fixtures : tuple of Body
        Clamps, walls and other obstacles, each posed in the base frame.
    auto_table : bool
        With no ``table``: True assumes the default table under the part (:func:`default_table`),
        False means the cell has no table.
    robot : str or None
        The robot named by the cell file (the CLI's ``--robot`` wins).
    notes : tuple of str
        What was assumed while building the cell (default tool, default table), one sentence each.
    positioner : Positioner or None
        A rotary positioner that carries the part (:mod:`swath.cell.positioner`); then the part's
        pose in the base frame follows the axis angle and ``part2base`` is not used.
    """

    part2base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tcp2flange: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool: ToolBody | None = None
    table: Table | None = None
    fixtures: tuple[Body, ...] = ()
    auto_table: bool = True
    robot: str | None = None
    notes: tuple[str, ...] = ()
    positioner: Positioner | None = None

    def __post_init__(self):
        object.__setattr__(self, "part2base", check_transform(self.part2base, name="part2base"))
        object.__setattr__(self, "tcp2flange", check_transform(self.tcp2flange, name="tcp2flange"))
        object.__setattr__(self, "fixtures", tuple(self.fixtures))
        object.__setattr__(self, "notes", tuple(self.notes))

    @classmethod
    def from_text(cls, base: str | None = None, tcp: str | None = None) -> Cell:
        """A cell from ``--base`` (``part2base``) and ``--tcp`` (``tcp2flange``) texts (see :func:`parse_pose`)."""
        return cls(part2base=np.eye(4) if base is None else parse_pose(base, name="part2base"),
                   tcp2flange=np.eye(4) if tcp is None else parse_pose(tcp, name="tcp2flange"))

    @property
    def base2part(self) -> np.ndarray:
        """(4, 4) the base's pose in the part frame, the inverse of :attr:`part2base`."""
        return invert_transform(self.part2base)

    @property
    def flange2tcp(self) -> np.ndarray:
        """(4, 4) the flange's pose in the TCP frame, the inverse of :attr:`tcp2flange`."""
        return invert_transform(self.tcp2flange)

    def flange2base(self, tcp2part) -> np.ndarray:
        """(n, 4, 4) flange poses in the base frame for TCP poses ``tcp2part`` (n, 4, 4) in the part frame."""
        return self.part2base @ np.asarray(tcp2part) @ self.flange2tcp

    def tcp2part(self, flange2base) -> np.ndarray:
        """(n, 4, 4) TCP poses in the part frame for flange poses ``flange2base`` (n, 4, 4) in the base frame."""
        return self.base2part @ np.asarray(flange2base) @ self.tcp2flange

    def with_base(self, part2base) -> Cell:
        """The same cell with the part at another pose ``part2base`` (4, 4) in the base frame."""
        return replace(self, part2base=np.asarray(part2base, dtype=float))

    def as_record(self) -> dict:
        """Text record for metrics/JSON (mm, deg): ``part2base``, ``tcp2flange`` and the cell's bodies."""
        rec: dict = {"part2base": format_pose(self.part2base), "tcp2flange": format_pose(self.tcp2flange)}
        if self.tool is not None:
            rec["tool_bodies"] = [b.as_record() for b in self.tool.bodies]
        if self.table is not None:
            rec["table"] = self.table.as_record()
        if self.fixtures:
            rec["fixtures"] = [b.as_record() for b in self.fixtures]
        if self.positioner is not None:
            rec["positioner"] = self.positioner.as_record()
        return rec
