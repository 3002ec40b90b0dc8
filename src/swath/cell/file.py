"""The cell file (TOML): the robot, the part's placement, the tool, the table and the fixtures.

Example (lengths take ``mm``/``m``/``in``, bare numbers are metres; angles take ``deg``/``rad``,
bare numbers are degrees; every pose is ``"x,y,z,rx,ry,rz"`` or a 4x4 matrix, named ``A2B``)::

    robot = "ur10e"                            # or a URDF file: "arms/ur10e.urdf" (read from this file's folder)
    part2base = "900mm,0,-200mm,0,0,90deg"     # the part's pose in the robot base frame

    [tool]
    tcp2flange = "0,0,175mm,0,0,0"             # the TCP's pose in the flange frame
    [[tool.body]]
    name = "spindle"
    shape = "cylinder"                          # box | cylinder | capsule | mesh
    radius = "35mm"
    length = "120mm"
    pose = "0,0,60mm,0,0,0"                     # body2flange: centre of the cylinder, axis along z

    [table]                                     # or `table = false` for none
    top_z = "-200mm"
    centre = ["900mm", "0"]
    size = ["1.2", "0.8"]

    [[fixture]]
    name = "clamp"
    shape = "box"
    size = ["100mm", "60mm", "80mm"]
    pose = "1.1,0.25,-160mm,0,0,0"              # body2base: centre of the box

A ``[positioner]`` table puts the part on a rotary positioner instead of at ``part2base``
(see :mod:`swath.cell.positioner`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import parse_quantity
from .bodies import Body, Box, Capsule, Cylinder, Mesh, Table
from .cell import Cell
from .frames import parse_pose
from .positioner import positioner_from_mapping
from .tool import ToolBody

_TOP_KEYS = {"robot", "part2base", "tool", "table", "fixture", "positioner"}
_BODY_KEYS = {"name", "shape", "size", "radius", "length", "pose", "file", "units"}


def read_cell_file(path) -> Cell:
    """Read a cell file.

    Parameters
    ----------
    path : path-like
        The TOML file.

    Returns
    -------
    Cell
        ``tool`` is None when the file has no ``[tool]`` table (the caller puts the default tool
        on); ``table`` is None when the file has no ``[table]`` (``auto_table`` True: the caller
        assumes the default table, :func:`swath.cell.default_table`) or says ``table = false``
        (``auto_table`` False: no table).

    Raises
    ------
    InputError
        Unknown keys, bad lengths or poses, a missing mesh file — naming the key and the fix.
    """
    import tomllib

    path = Path(path)
    if not path.is_file():
        raise InputError(f"cell file {path} not found; give --cell an existing .toml file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"cell file {path} is not valid TOML: {exc}") from None
    return cell_from_mapping(data, where=str(path), root=path.parent)


def cell_from_mapping(data: dict, *, where: str = "cell", root: Path | None = None) -> Cell:
    """A :class:`Cell` from the cell file's parsed mapping (see the module docstring)."""
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(_TOP_KEYS))}")
    part2base = parse_pose(data["part2base"], name=f"{where}: part2base") if "part2base" in data else np.eye(4)
    tool = None
    if "tool" in data:
        t = data["tool"]
        if not isinstance(t, dict) or set(t) - {"tcp2flange", "body"}:
            raise InputError(f"{where}: [tool] takes tcp2flange and [[tool.body]] entries, got {t!r}")
        tcp2flange = parse_pose(t.get("tcp2flange", "0,0,0,0,0,0"), name=f"{where}: tool.tcp2flange")
        bodies = tuple(_body(b, f"{where}: tool.body[{i}]", root, prefix="tool ")
                       for i, b in enumerate(t.get("body", [])))
        tool = ToolBody(bodies=bodies, tcp2flange=tcp2flange, description=f"the tool of {where}")
    table = None
    if "table" in data:
        table = _table(data["table"], f"{where}: table")
    fixtures = tuple(_body(b, f"{where}: fixture[{i}]", root, prefix="fixture ")
                     for i, b in enumerate(data.get("fixture", [])))
    robot = data.get("robot")
    if robot is not None and not isinstance(robot, str):
        raise InputError(f"{where}: robot must be a catalogue name such as \"ur10e\" or a .urdf file, got {robot!r}")
    if robot is not None and robot.strip().lower().endswith(".urdf"):
        urdf = Path(robot.strip())
        if not urdf.is_absolute() and root is not None:
            urdf = root / urdf
        if not urdf.is_file():
            raise InputError(f"{where}: robot URDF file {urdf} not found (relative paths are read from the cell "
                             "file's folder)")
        robot = str(urdf)
    positioner = None
    if "positioner" in data:
        if "part2base" in data:
            raise InputError(f"{where}: give either part2base (a fixed part) or [positioner] (its part2faceplate "
                             "places the part), not both")
        positioner = positioner_from_mapping(data["positioner"], where=f"{where}: positioner")
    return Cell(part2base=part2base, tcp2flange=np.eye(4) if tool is None else tool.tcp2flange, tool=tool,
                table=table, fixtures=fixtures, robot=robot, positioner=positioner,
                auto_table=data.get("table", positioner is None) is not False)


def _length(value, key: str) -> float:
    v = parse_quantity(value, "length")
    if not v > 0:
        raise InputError(f"{key} must be a positive length, got {value!r}")
    return v


def _table(t, where: str) -> Table | None:
    if t is False:
        return None
    if not isinstance(t, dict) or set(t) - {"top_z", "centre", "center", "size", "thickness"} or "top_z" not in t:
        raise InputError(f"{where}: [table] takes top_z (required), centre, size, thickness; or `table = false`; "
                         f"got {t!r}")
    centre = t.get("centre", t.get("center", [0, 0]))
    size = t.get("size", [2, 2])
    if not isinstance(centre, list) or not isinstance(size, list) or len(centre) != 2 or len(size) != 2:
        raise InputError(f"{where}: centre and size take two lengths (x, y), got {centre!r}, {size!r}")
    return Table(top_z=parse_quantity(t["top_z"], "length"),
                 centre_xy=tuple(parse_quantity(v, "length") for v in centre),
                 size_xy=tuple(_length(v, f"{where}.size") for v in size),
                 thickness=_length(t.get("thickness", 0.04), f"{where}.thickness"))


def _body(b, where: str, root: Path | None, *, prefix: str) -> Body:
    if not isinstance(b, dict):
        raise InputError(f"{where}: expected a table of name, shape, sizes and pose, got {b!r}")
    unknown = set(b) - _BODY_KEYS
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(_BODY_KEYS))}")
    kind = str(b.get("shape", "")).lower()
    name = prefix + str(b.get("name", where.rsplit(": ", 1)[-1]))
    pose = parse_pose(b.get("pose", "0,0,0,0,0,0"), name=f"{where}.pose")

    def need(key):
        if key not in b:
            raise InputError(f"{where}: a {kind} needs `{key}`")
        return b[key]

    shape: Box | Cylinder | Capsule | Mesh
    if kind == "box":
        size = need("size")
        if not isinstance(size, list) or len(size) != 3:
            raise InputError(f"{where}: a box's size takes three lengths [x, y, z], got {size!r}")
        shape = Box(tuple(_length(v, f"{where}.size") for v in size))
    elif kind in ("cylinder", "capsule"):
        cls = Cylinder if kind == "cylinder" else Capsule
        shape = cls(_length(need("radius"), f"{where}.radius"), _length(need("length"), f"{where}.length"))
    elif kind == "mesh":
        from ..io.mesh_read import read_mesh_file

        file = Path(need("file"))
        if not file.is_absolute() and root is not None:
            file = root / file
        if not file.is_file():
            raise InputError(f"{where}: mesh file {file} not found (relative paths are read from the cell file's folder)")
        scale = parse_quantity(f"1{b.get('units', 'm')}", "length")
        if file.suffix.lower() not in (".stl", ".ply", ".obj"):
            raise InputError(f"{where}: a mesh body reads .stl, .ply or .obj files, got {file.name}")
        v, f, _ = read_mesh_file(file, file.suffix.lower())
        shape = Mesh(np.asarray(v, dtype=float) * scale, f)
    else:
        raise InputError(f"{where}: shape must be box, cylinder, capsule or mesh, got {b.get('shape')!r}")
    return Body(name, shape, pose)
