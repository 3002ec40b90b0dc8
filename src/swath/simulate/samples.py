"""Removal samples: points, normals and areas that cover a part at a given spacing in both directions.

The removal simulation needs only sample points on the part, their normals and the area each
stands for (and, for the report, the depth anywhere on the part: :meth:`RemovalSamples.depth_at`).  A conforming subdivision
(:meth:`swath.surface.Surface.subdivided`) gives these, but it must put points along every edge of
a long sliver triangle, so a CAD mesh of slivers narrower than the spacing gets several times the
samples its area needs, and building a whole :class:`~swath.surface.Surface` of millions of
vertices (smoothed normals, KD-tree) costs more than the integration itself.

:func:`removal_samples` samples each triangle on its own:

* a triangle whose corners already lie within ``spacing / √2`` of every point of it (its covering
  radius: the circumradius of an acute triangle, half the longest edge otherwise; times
  :data:`VERTEX_SLACK`) is sampled by its corners, each carrying a third of its area (as
  :attr:`Surface.vertex_areas`); a part meshed at the spacing or finer keeps its own vertices;
* any larger triangle is cut into columns across its longest edge ``AB``, ``ceil(|AB| / spacing)``
  of equal width, and each column into ``ceil(height / spacing)`` equal cells at its centre line;
  a sample sits at the centre of each cell and carries the column's exact area divided among its
  cells.  Cells are at most ``spacing`` wide and high, so a sliver of any width gets one row of
  samples ``spacing`` apart along its length.

Normals are the part's smooth vertex normals (:attr:`Surface.normals`) interpolated linearly over
each triangle and normalised, so nothing is smoothed again on the samples.  The sample count is
known before any sample is made (:func:`count_removal_samples`), so a too-fine request is widened
before memory is spent.

The samples of neighbouring triangles are not joined into one mesh, so the report draws the depth
on the part's own (subdivided) triangulation instead: :meth:`RemovalSamples.depth_at` reads it at
any point as the mean of the samples around it (:func:`interpolate_depth`: weighted by area and a
tent of the distance, across faces and slivers alike, the far side of a thin part left out).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..errors import InputError
from ..surface.geometry import face_normals_and_areas
from ..surface.surface import farther_from_boundary

#: A triangle is sampled by its corners while its covering radius is at most ``VERTEX_SLACK ·
#: spacing / √2``: a mesh generated at the spacing (edges 2.003 mm for 2 mm on ``large_panel``)
#: keeps its vertices instead of getting two lattice samples per triangle.
VERTEX_SLACK = 1.05


def _face_frames(surface, spacing: float):
    """Per face: corners rotated so edge 0 (A→B) is the longest, the covering radius (m), and the
    face's column count and its ``ceil`` limit."""
    faces = np.asarray(surface.faces)
    xyz = np.asarray(surface.vertices, float)
    p0, p1, p2 = xyz[faces[:, 0]], xyz[faces[:, 1]], xyz[faces[:, 2]]
    # edge k runs from corner k to corner k + 1
    length = np.stack([np.linalg.norm(p1 - p0, axis=1), np.linalg.norm(p2 - p1, axis=1),
                       np.linalg.norm(p0 - p2, axis=1)], axis=1)
    longest = np.argmax(length, axis=1)
    L = length[np.arange(len(faces)), longest]
    area = np.asarray(surface.face_areas, float)
    # circumradius abc / 4 area for acute triangles, half the longest edge otherwise
    sq = length**2
    acute = 2 * sq.max(axis=1) < sq.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        circum = np.prod(length, axis=1) / np.maximum(4.0 * area, 1e-300)
    cover = np.where(acute, circum, 0.5 * L)
    return faces, longest, L, area, cover


def _is_vertex_sampled(cover: np.ndarray, spacing: float) -> np.ndarray:
    return cover <= VERTEX_SLACK * spacing / np.sqrt(2.0)


def count_removal_samples(surface, spacing: float) -> int:
    """The number of samples :func:`removal_samples` gives ``surface`` at ``spacing`` (m), without
    making them (a few vectorised passes over the faces)."""
    return lattice_count(lattice_columns(surface, _check_spacing(spacing)))


def lattice_count(cols: dict) -> int:
    """Samples of the lattice ``cols`` (:func:`lattice_columns`)."""
    return int(cols["used"].sum()) + int(cols["rows"].sum())


def _check_spacing(spacing) -> float:
    spacing = float(spacing)
    if not (np.isfinite(spacing) and spacing > 0):
        raise InputError(f"sample spacing must be a positive length in m, got {spacing!r}")
    return spacing


def lattice_columns(surface, spacing: float) -> dict:
    """The sampling plan of ``surface`` at ``spacing`` (m): which faces are sampled by their
    corners, and the columns (position, exact area, rows) of the others; counted by
    :func:`lattice_count`, made into samples by :func:`removal_samples`."""
    faces, longest, L, area, cover = _face_frames(surface, spacing)
    small = _is_vertex_sampled(cover, spacing)
    used = np.zeros(len(surface.vertices), bool)
    used[faces[small].ravel()] = True
    big = np.flatnonzero(~small)
    L_big = L[big]
    h = 2.0 * area[big] / np.maximum(L_big, 1e-300)              # height over the longest edge
    # apex C projected on AB, as a distance from A (in [0, L]: AB is the longest edge)
    k = longest[big]
    rows_ = np.arange(len(big))
    xyz = np.asarray(surface.vertices, float)
    A = xyz[faces[big, k]]
    B = xyz[faces[big, (k + 1) % 3]]
    C = xyz[faces[big, (k + 2) % 3]]
    ex = (B - A) / L_big[:, None]
    xc = np.clip(np.einsum("fc,fc->f", C - A, ex), 0.0, L_big)
    n_cols = np.maximum(np.ceil(L_big / spacing * (1.0 - 1e-12)), 1.0).astype(np.int64)
    col_face = np.repeat(rows_, n_cols)
    first = np.cumsum(n_cols) - n_cols
    col_index = np.arange(len(col_face)) - np.repeat(first, n_cols)
    width = (L_big / n_cols)[col_face]
    x0 = col_index * width
    x1 = x0 + width
    xm = x0 + 0.5 * width
    Lc, hc, xcc = L_big[col_face], h[col_face], xc[col_face]
    col_area = _area_below(x1, Lc, hc, xcc) - _area_below(x0, Lc, hc, xcc)
    height = _top(xm, Lc, hc, xcc)
    n_rows = np.maximum(np.ceil(height / spacing * (1.0 - 1e-12)), 1.0).astype(np.int64)
    return {"faces": faces, "longest": k, "used": used, "small": small, "big": big, "A": A, "B": B,
            "C": C, "ex": ex, "h": h, "xc": xc, "L": L_big, "col_face": col_face, "col_index": col_index,
            "n_cols": n_cols, "xm": xm, "col_area": col_area, "height": height, "rows": n_rows}


def _top(x, L, h, xc):
    """Height (m) of the triangle ``A=(0,0), B=(L,0), C=(xc,h)`` above ``x`` (0 ≤ x ≤ L)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        left = np.where(xc > 0, h * x / np.where(xc > 0, xc, 1.0), h)
        right = np.where(L - xc > 0, h * (L - x) / np.where(L - xc > 0, L - xc, 1.0), h)
    return np.clip(np.minimum(left, right), 0.0, h)


def _area_below(x, L, h, xc):
    """Area (m²) of the triangle ``A=(0,0), B=(L,0), C=(xc,h)`` left of the abscissa ``x``."""
    x = np.clip(x, 0.0, L)
    safe_xc = np.where(xc > 0, xc, 1.0)
    safe_r = np.where(L - xc > 0, L - xc, 1.0)
    left = np.where(xc > 0, 0.5 * h * np.minimum(x, xc) ** 2 / safe_xc, 0.0)
    beyond = np.maximum(x - xc, 0.0)
    right = np.where(L - xc > 0, 0.5 * h * ((L - xc) ** 2 - (L - xc - beyond) ** 2) / safe_r, 0.0)
    return left + right


class RemovalSamples:
    """Sample points of a part for the removal simulation (see the module notes).

    Read like the sampled :class:`~swath.surface.Surface` the simulation used before (the report
    and the metrics read ``vertices``, ``normals``, ``vertex_areas``, ``faces``, ``kdtree``,
    ``name``); not a full surface: no curvature, adjacency or closest-point queries.

    Attributes
    ----------
    vertices : (n, 3) float
        Sample positions, m, part frame.
    normals : (n, 3) float
        Unit normals toward the tool.
    vertex_areas : (n,) float
        Area each sample stands for, m²; they sum to the part's area.
    face_of : (n,) int
        The part face each sample lies on (for a corner sample, one of its faces).
    faces : (k, 3) int
        Triangles over the samples: the corner-sampled faces, and within each larger face the
        cells of neighbouring columns joined; not conforming between lattice faces (gaps up to a
        spacing), and a face with a single row of samples (a sliver) has none.  The report does not
        draw these: it draws the part's own mesh with :meth:`depth_at`.
    part : Surface
        The sampled part.
    spacing : float
        The spacing asked, m.
    """

    def __init__(self, vertices, normals, vertex_areas, face_of, faces, part, spacing: float):
        self.vertices = _ro(np.ascontiguousarray(vertices, float))
        self.normals = _ro(np.ascontiguousarray(normals, float))
        self.vertex_areas = _ro(np.ascontiguousarray(vertex_areas, float))
        self.face_of = _ro(np.asarray(face_of, np.int64))
        # the display triangles, or (corner triangles, columns per face, rows per column) to make
        # them from on first use (only the report needs them)
        self._faces = faces
        self.part = part
        self.spacing = float(spacing)
        self.name = getattr(part, "name", "")

    def __len__(self) -> int:
        return len(self.vertices)

    @cached_property
    def faces(self) -> np.ndarray:
        """(k, 3) int: the display triangles (see the class notes)."""
        if isinstance(self._faces, tuple):
            corner_faces, n_cols, rows = self._faces
            zipped = _zip_columns(n_cols, rows, np.cumsum(rows) - rows) + (len(self) - int(rows.sum()))
            faces = np.concatenate([corner_faces, zipped])
        else:
            faces = self._faces
        self._faces = None
        return _ro(np.asarray(faces, np.int64).reshape(-1, 3))

    def __repr__(self) -> str:
        return f"RemovalSamples({self.name!r}, {len(self)} samples at {self.spacing * 1e3:.3g} mm)"

    @property
    def area(self) -> float:
        """Total area the samples stand for, m² (the part's)."""
        return float(self.vertex_areas.sum())

    @cached_property
    def kdtree(self):
        """``scipy.spatial.cKDTree`` of the samples."""
        from scipy.spatial import cKDTree

        return cKDTree(self.vertices)

    @cached_property
    def _face_normals_areas(self):
        return face_normals_and_areas(self.vertices, self.faces)

    @property
    def face_normals(self) -> np.ndarray:
        """(k, 3) unit normals of the display faces."""
        return self._face_normals_areas[0]

    @property
    def face_areas(self) -> np.ndarray:
        """(k,) areas of the display faces, m² (they do not add up to the part's area)."""
        return self._face_normals_areas[1]

    def farther_from_boundary(self, margin: float) -> np.ndarray:
        """(n,) bool: samples farther than ``margin`` (m) from the part's open boundary, its edges
        sampled at half the spacing (:func:`swath.surface.surface.farther_from_boundary`); computed
        once per margin (read-only: the metrics, the evenness split and the feed stage ask again)."""
        masks = self.__dict__.setdefault("_farther", {})
        key = float(margin)
        if key not in masks:
            masks[key] = _ro(farther_from_boundary(self.vertices, self.part, key, step=0.5 * self.spacing))
        return masks[key]

    @property
    def principal_axes(self):
        """The part's principal axes (:attr:`Surface.principal_axes`)."""
        return self.part.principal_axes

    def depth_at(self, points, depth, *, normals=None, radius: float | None = None) -> np.ndarray:
        """Removal depth at ``points`` interpolated from the samples' ``depth`` (see :func:`interpolate_depth`).

        Parameters
        ----------
        points : (p, 3) float
            Where to read the depth, m, part frame (on or near the part).
        depth : (n,) float
            Depth at each sample, m.
        normals : (p, 3) float, optional
            Unit surface normals at ``points``: samples facing away (the other side of a thin part)
            are not used.
        radius : float, optional
            Support of the weights, m (default and least ``DEPTH_RADIUS · spacing``).

        Returns
        -------
        (p,) float
            Depth, m.
        """
        return interpolate_depth(self.vertices, self.normals, self.vertex_areas, depth, points,
                                 normals=normals, radius=max(DEPTH_RADIUS * self.spacing, radius or 0.0),
                                 tree=self.kdtree)


#: Radius of the depth interpolation (:meth:`RemovalSamples.depth_at`) in sample spacings: every point
#: of the part is within about ``0.75 · spacing`` of a sample, so a radius of 1.5 spacings holds the
#: nearest 5-10 samples around any point.
DEPTH_RADIUS = 1.5
#: Neighbours read at most per point by :func:`interpolate_depth`.
DEPTH_NEIGHBOURS = 48


def interpolate_depth(sample_points, sample_normals, sample_areas, depth, points, *, normals=None,
                      radius: float, tree=None) -> np.ndarray:
    """Depth at ``points``: the mean of the samples within ``radius``, weighted by their area and a
    tent ``1 − d / radius`` of their distance ``d``.

    Samples across faces, columns and slivers all count, so neighbouring points get neighbouring
    values wherever they are on the part; with ``normals``, only samples facing the same side
    (normals at less than about 70°) count, so the two skins of a thin part do not mix.  A point
    with no such sample within ``radius`` takes the depth of its nearest sample.

    Parameters
    ----------
    sample_points, sample_normals : (n, 3) float
        The samples (m) and their unit normals.
    sample_areas : (n,) float
        Area each sample stands for, m².
    depth : (n,) float
        Depth at each sample, m.
    points : (p, 3) float
        Where to read the depth, m.
    normals : (p, 3) float, optional
        Unit normals at ``points``.
    radius : float
        Support of the tent, m (> 0).
    tree : scipy.spatial.cKDTree, optional
        KD-tree of ``sample_points``.

    Returns
    -------
    (p,) float
        Depth, m.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, float).reshape(-1, 3)
    depth = np.asarray(depth, float)
    if depth.shape != (len(sample_points),):
        raise InputError(f"depth must have one value per sample, shape ({len(sample_points)},), got {depth.shape}")
    if not (np.isfinite(radius) and radius > 0):
        raise InputError(f"interpolation radius must be a positive length in m, got {radius!r}")
    out = np.zeros(len(points))
    if len(points) == 0 or len(sample_points) == 0:
        return out
    tree = cKDTree(sample_points) if tree is None else tree
    k = int(min(DEPTH_NEIGHBOURS, len(sample_points)))
    step = max(1, 2_000_000 // k)                                # bounded memory: (step, k) blocks
    for lo in range(0, len(points), step):
        sl = slice(lo, lo + step)
        dist, idx = tree.query(points[sl], k=k, distance_upper_bound=radius)
        dist, idx = dist.reshape(len(dist), -1), idx.reshape(len(idx), -1)
        found = idx < len(sample_points)
        safe = np.where(found, idx, 0)
        w = np.where(found, np.asarray(sample_areas)[safe] * np.clip(1.0 - dist / radius, 0.0, 1.0), 0.0)
        if normals is not None:
            facing = np.einsum("pkc,pc->pk", np.asarray(sample_normals)[safe], np.asarray(normals, float)[sl])
            w = np.where(facing > 0.35, w, 0.0)
        wsum = w.sum(axis=1)
        block = np.einsum("pk,pk->p", w, depth[safe]) / np.maximum(wsum, 1e-300)
        lonely = wsum <= 0
        if lonely.any():
            block[lonely] = depth[tree.query(points[sl][lonely])[1]]
        out[sl] = block
    return out


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def removal_samples(surface, spacing: float, *, columns: dict | None = None) -> RemovalSamples:
    """Samples of ``surface`` at most ``spacing`` apart in both directions (see the module notes).

    Parameters
    ----------
    surface : Surface
        The part (part frame, normals toward the tool).
    spacing : float
        Largest distance between neighbouring samples along and across each triangle, m.
    columns : dict, optional
        ``lattice_columns(surface, spacing)`` when the caller has it (it counted the samples).

    Returns
    -------
    RemovalSamples
        Corner samples first (the part's vertices of its small faces, in their order), then the
        lattice samples face by face.
    """
    spacing = _check_spacing(spacing)
    cols = lattice_columns(surface, spacing) if columns is None else columns
    part_normals = np.asarray(surface.normals, float)
    xyz = np.asarray(surface.vertices, float)
    faces = cols["faces"]
    # --- corner samples of the small faces
    used = cols["used"]
    corner_ids = np.flatnonzero(used)
    remap = np.full(len(xyz), -1, np.int64)
    remap[corner_ids] = np.arange(len(corner_ids))
    small = np.flatnonzero(cols["small"])
    face_area = np.asarray(surface.face_areas, float)
    corner_area = np.bincount(faces[small].ravel(), weights=np.repeat(face_area[small] / 3.0, 3),
                              minlength=len(xyz))[corner_ids]
    corner_face = np.zeros(len(xyz), np.int64)
    corner_face[faces[small].ravel()] = np.repeat(small, 3)
    # --- lattice samples of the large faces: column c has rows[c] cells
    rows = cols["rows"]
    col_face = cols["col_face"]
    s_col = np.repeat(np.arange(len(rows)), rows)
    col_first = np.cumsum(rows) - rows
    s_row = np.arange(len(s_col)) - col_first[s_col]
    s_face = col_face[s_col]
    y = (s_row + 0.5) * (cols["height"] / rows)[s_col]
    x = cols["xm"][s_col]
    h, xc, L = cols["h"][s_face], cols["xc"][s_face], cols["L"][s_face]
    # barycentric coordinates of (x, y) in A=(0,0), B=(L,0), C=(xc,h)
    gamma = np.where(h > 0, y / np.where(h > 0, h, 1.0), 0.0)
    beta = (x - gamma * xc) / L
    alpha = 1.0 - beta - gamma
    bary = np.stack([alpha, beta, gamma], axis=1)
    big = cols["big"]
    A, B, C = cols["A"], cols["B"], cols["C"]
    points = alpha[:, None] * A[s_face] + beta[:, None] * B[s_face] + gamma[:, None] * C[s_face]
    face_ids = big[s_face]
    # corners of each big face in the rotated order A, B, C (A→B the longest edge)
    k = cols["longest"]
    abc = faces[big][np.arange(len(big))[:, None], (k[:, None] + np.arange(3)[None, :]) % 3]
    normals = np.einsum("sk,skc->sc", bary, part_normals[abc[s_face]])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    areas = (cols["col_area"] / rows)[s_col]
    # --- display triangles: corner faces, and columns zipped together within each large face
    display = (remap[faces[small]], cols["n_cols"], rows)
    return RemovalSamples(np.concatenate([xyz[corner_ids], points]),
                          np.concatenate([part_normals[corner_ids], normals]),
                          np.concatenate([corner_area, areas]),
                          np.concatenate([corner_face[corner_ids], face_ids]), display, surface, spacing)


def _zip_columns(n_cols: np.ndarray, rows: np.ndarray, col_first: np.ndarray) -> np.ndarray:
    """Triangles ``(t, 3)`` joining each column's samples to the next column's of the same face
    (samples numbered from 0 in column order), wound as the face (columns run A→B, rows toward C).

    Two columns of ``p`` and ``q`` samples are joined by ``p + q − 2`` triangles: their samples
    merged by relative height, each new sample closing a triangle with the current one of the
    other column."""
    last_col = np.cumsum(n_cols) - 1
    left = np.ones(len(rows), bool)
    left[last_col] = False                                      # a face's last column has no right neighbour
    pair = np.flatnonzero(left)                                 # column pair (pair, pair + 1)
    if len(pair) == 0:
        return np.zeros((0, 3), np.int64)
    p, q = rows[pair], rows[pair + 1]
    oa, ob = col_first[pair], col_first[pair + 1]
    # items: every sample of both columns of every pair
    n_items = p + q
    item_pair = np.repeat(np.arange(len(pair)), n_items)
    item_first = np.cumsum(n_items) - n_items
    local = np.arange(len(item_pair)) - item_first[item_pair]
    is_b = local >= p[item_pair]
    index = np.where(is_b, local - p[item_pair], local)
    count = np.where(is_b, q[item_pair], p[item_pair])
    key = (index + 0.5) / count
    order = np.lexsort((is_b, key, item_pair))
    item_pair, is_b, index = item_pair[order], is_b[order], index[order]
    # samples of each column met so far (this one included), per pair
    a_seen = np.cumsum(~is_b)
    b_seen = np.cumsum(is_b)
    start = item_first                                          # sorted items keep pairs contiguous
    a_before = a_seen - np.concatenate([[0], a_seen])[start][item_pair]
    b_before = b_seen - np.concatenate([[0], b_seen])[start][item_pair]
    cur_a = oa[item_pair] + np.maximum(a_before - (~is_b), 1) - 1      # current a before this item
    cur_b = ob[item_pair] + np.maximum(b_before - is_b, 1) - 1
    new = np.where(is_b, ob[item_pair], oa[item_pair]) + index
    step = index >= 1                                           # the first of each column only starts
    adv_a = step & ~is_b
    adv_b = step & is_b
    tri_a = np.stack([new[adv_a] - 1, cur_b[adv_a], new[adv_a]], axis=1)
    tri_b = np.stack([new[adv_b] - 1, new[adv_b], cur_a[adv_b]], axis=1)
    return np.concatenate([tri_a, tri_b])
