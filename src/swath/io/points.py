"""Load point clouds (scans) for surface fitting: XYZ/TXT/CSV, PLY and PCD.

Returns plain arrays in metres: points ``(n, 3)`` and, when the file has them, unit normals
``(n, 3)``.  The same checks as for meshes apply at the edge: empty or unreadable files, NaN
coordinates, implausible sizes for the chosen unit, and too few points.
"""

from __future__ import annotations

import io
import logging
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import canonical_length_unit, length_unit_factor
from .checks import check_extent, check_file
from .ply_read import read_ply

log = logging.getLogger("swath.io")

#: Point-cloud file extensions load_points reads.
POINT_EXTENSIONS = (".xyz", ".txt", ".csv", ".pts", ".ply", ".pcd")
#: Fewest points accepted.
MIN_POINTS = 10

_NORMAL_NAMES = (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z"), ("n_x", "n_y", "n_z"))
_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4", ("I", 8): "i8",
              ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}


def load_points(path, *, units: str = "m", force_units: bool = False):
    """Load a point cloud in metres.

    Parameters
    ----------
    path : str or Path
        ``.xyz``, ``.txt``, ``.csv``, ``.pts`` (rows ``x y z [nx ny nz ...]``, whitespace or comma
        separated, ``#`` comments, an optional header line naming the columns), ``.ply``
        (vertices; faces are ignored) or ``.pcd`` (ASCII or binary; ``binary_compressed`` is
        refused).
    units : str
        The file's length unit: ``m``, ``mm``, ``cm``, ``in`` or a spelled-out name in any case.
    force_units : bool
        Accept a cloud whose largest extent is outside 5 mm .. 20 m.

    Returns
    -------
    points : (n, 3) float
        Positions, m.
    normals : (n, 3) float or None
        Unit normals from the file (as stored, not re-oriented), or None when it has none.  Text
        files without a header give normals when columns 4-6 are unit vectors.

    Raises
    ------
    InputError
        For a missing, empty, unreadable or unsupported file, NaN or infinite coordinates (an
        organised PCD's NaN "no return" points are dropped with a warning instead), fewer than 10
        points, or an implausible size (naming the likely unit).
    """
    path = Path(path)
    ext = check_file(path, POINT_EXTENSIONS, "point cloud")
    units = canonical_length_unit(units)
    factor = length_unit_factor(units)
    label = path.name
    if ext == ".ply":
        pts, nrm = _read_ply(path)
        drop_nan = False
    elif ext == ".pcd":
        pts, nrm, drop_nan = _read_pcd(path)
    else:
        pts, nrm = _read_text(path)
        drop_nan = False

    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        if not drop_nan:
            raise InputError(f"{label}: {int(bad.sum())} of {len(pts)} points have NaN or infinite coordinates; "
                             "remove them or re-export the cloud")
        log.warning("%s: dropped %d NaN points (no-return pixels of an organised cloud)", label, int(bad.sum()))
        pts = pts[~bad]
        nrm = None if nrm is None else nrm[~bad]
    if len(pts) < MIN_POINTS:
        raise InputError(f"{label} has {len(pts)} points; at least {MIN_POINTS} are needed to fit a surface")
    pts = pts * factor
    check_extent(float(np.ptp(pts, axis=0).max()) / factor, units, force_units, label)
    if nrm is not None:
        nrm = _unit_normals(nrm, label)
    log.info("%s: %d points%s, extents %s m", label, len(pts), " with normals" if nrm is not None else "",
             np.round(np.ptp(pts, axis=0), 4).tolist())
    return pts, nrm


# --------------------------------------------------------------------------------------------
def _unit_normals(n: np.ndarray, label: str):
    """Normalise file normals; None (with a warning) when any is zero or not finite."""
    length = np.linalg.norm(n, axis=1)
    ok = np.isfinite(length) & (length > 0)
    if not ok.all():
        log.warning("%s: %d normals are zero or not finite; ignoring the file's normals", label,
                    int((~ok).sum()))
        return None
    return n / length[:, None]


def _read_ply(path: Path):
    """Vertices ``(n, 3)`` and vertex normals ``(n, 3)`` or None of a PLY (faces, if any, are ignored)."""
    pts, _, nrm = read_ply(path.read_bytes(), path.name)
    return pts, nrm


def _read_text(path: Path):
    """x y z [nx ny nz ...] rows, whitespace or comma (or semicolon) separated."""
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path.name} is not a text point cloud (it is not UTF-8 text); check the file") from None
    lines = [ln.split("#", 1)[0].split("//", 1)[0].strip() for ln in text.splitlines()]
    lines = [re.sub(r"[,;\t]", " ", ln) for ln in lines if ln]
    if not lines:
        raise InputError(f"{path.name} holds no points; check the file")
    names = None
    if not _numeric(lines[0]):
        names = [t.lower() for t in lines[0].split()]
        lines = lines[1:]
    if not lines:
        raise InputError(f"{path.name} holds a header but no points; check the file")
    try:
        table = np.loadtxt(io.StringIO("\n".join(lines)), dtype=float, ndmin=2)
    except ValueError as exc:
        raise InputError(f"could not read {path.name} as rows of numbers x y z [nx ny nz]: {exc}; "
                         "check the file") from None
    if table.shape[1] < 3:
        raise InputError(f"{path.name} has {table.shape[1]} columns; expected x y z [nx ny nz]")
    if names is not None and len(names) == table.shape[1]:
        col = {n: i for i, n in enumerate(names)}
        xyz: list = [col.get(c) for c in ("x", "y", "z")]
        if None in xyz:
            xyz = [0, 1, 2]
        pts = table[:, xyz]
        for trio in _NORMAL_NAMES:
            if all(c in col for c in trio):
                return pts, table[:, [col[c] for c in trio]]
        return pts, None
    pts = table[:, :3]
    if table.shape[1] >= 6:
        cand = table[:, 3:6]
        length = np.linalg.norm(cand, axis=1)
        if np.all(np.abs(length - 1.0) < 0.05):
            return pts, cand
        log.info("%s: columns 4-6 are not unit vectors (colours?); reading x y z only", path.name)
    return pts, None


def _numeric(line: str) -> bool:
    try:
        [float(t) for t in line.split()]
    except ValueError:
        return False
    return True


def _read_pcd(path: Path):
    """Points, normals and whether NaNs mark missing returns (organised cloud)."""
    data = path.read_bytes()
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = data.find(b"\n", pos)
        if end < 0:
            raise InputError(f"{path.name}: PCD header has no DATA line; check the file")
        try:
            line = data[pos:end].decode("ascii").strip()
        except UnicodeDecodeError:
            raise InputError(f"{path.name} is not a PCD file (its header is not text); check the file") from None
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        header[key.upper()] = vals
        if key.upper() == "DATA":
            break
    try:
        fields = [f.lower() for f in header["FIELDS"]]
        n_fields = len(fields)
        sizes = [int(s) for s in header.get("SIZE", ["4"] * n_fields)]
        types = [t.upper() for t in header.get("TYPE", ["F"] * n_fields)]
        counts = [int(c) for c in header.get("COUNT", ["1"] * n_fields)]
        width = int(header.get("WIDTH", ["0"])[0])
        height = int(header.get("HEIGHT", ["1"])[0])
        n_points = int(header.get("POINTS", [str(width * height)])[0])
        kind = header["DATA"][0].lower()
    except (KeyError, ValueError, IndexError):
        raise InputError(f"{path.name}: malformed PCD header (FIELDS/SIZE/TYPE/COUNT/POINTS/DATA); "
                         "check the file") from None
    if not (len(sizes) == len(types) == len(counts) == n_fields) or not {"x", "y", "z"} <= set(fields):
        raise InputError(f"{path.name}: PCD header must list x y z with one SIZE, TYPE and COUNT per field; "
                         "check the file")
    if kind == "ascii":
        body = data[pos:].decode("ascii", errors="replace")
        try:
            table = np.loadtxt(io.StringIO(body), dtype=float, ndmin=2)
        except ValueError as exc:
            raise InputError(f"could not read the ASCII data of {path.name}: {exc}; check the file") from None
        if table.size == 0:
            table = np.zeros((0, sum(counts)))
        if table.shape[1] != sum(counts):
            raise InputError(f"{path.name}: rows have {table.shape[1]} values but the header declares "
                             f"{sum(counts)}; check the file")
        starts = np.cumsum([0] + counts[:-1])

        def column(name):
            return table[:, starts[fields.index(name)]]
    elif kind == "binary":
        try:
            dtype = np.dtype([(f"f{i}", "<" + _PCD_TYPES[(t, s)], (c,) if c > 1 else ())
                              for i, (t, s, c) in enumerate(zip(types, sizes, counts))])
        except KeyError:
            raise InputError(f"{path.name}: unsupported PCD field type/size; check the file") from None
        if len(data) - pos < n_points * dtype.itemsize:
            raise InputError(f"{path.name}: binary data is shorter than the {n_points} points the header "
                             "declares; the file is truncated")
        rec = np.frombuffer(data, dtype=dtype, count=n_points, offset=pos)

        def column(name):
            a = rec[f"f{fields.index(name)}"]
            return np.asarray(a if a.ndim == 1 else a[:, 0], dtype=float)
    else:
        raise InputError(f"{path.name}: PCD DATA {kind} is not supported; save the cloud as ascii or binary "
                         "(e.g. pcl_convert_pcd_ascii_binary)")
    pts = np.stack([column(c) for c in ("x", "y", "z")], axis=1)
    nrm = None
    for trio in _NORMAL_NAMES:
        if all(c in fields for c in trio):
            nrm = np.stack([column(c) for c in trio], axis=1)
            break
    return pts, nrm, height > 1
