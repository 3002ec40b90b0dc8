"""Where a plan's passes really leave the surface untouched, and the short passes that close it.

A planner's spacing rule says how far apart passes may be; it does not see a hole's edge, a
piece's far side, a dropped sliver or the corner a diagonal direction leaves.  Here the surface is
sampled finely and each sample is counted as covered when a pass point lies within half the
pad's contact chord of it (the chord across the pass, from the local contact model at pad scale).
The uncovered samples, grouped into patches, get a fill pass each: the slice through the patch
along the plan's feed direction, clipped to the patch's extent plus half a pad.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..contact.widths import pad_scale_samples, patch_widths, surface_memo
from ..surface.cells import jit
from ..surface.geometry import face_normals_and_areas, vertex_areas
from ..surface.subdivide import halve_long_edges_except

log = logging.getLogger("swath.plan")

#: Relative slack on the half chord: the default spacing makes neighbouring swaths just touch, so
#: the midline between two passes lies a rounding error from either.
CHORD_TOLERANCE = 5e-3
#: Uncovered patches smaller than this share of the surface are not worth a pass.
MIN_GAP_SHARE = 2e-4
#: Slack (m) on the test that a whole triangle is within reach of a pass point.
SURE_MARGIN = 1e-9


class CoverageCheck:
    """Fine samples of a surface with the contact chord across a given feed direction.

    The samples are the vertices of the surface halved to ``step``
    (:func:`swath.surface.subdivide.halve_long_edges`).  Only where a gap can be: before each
    halving round, a triangle whose every point is surely within reach of a pass point (its
    bounding ball, around its centroid, lies within the smallest reach of any sample of a pass
    point) is set aside unsplit, and its corners are counted as covered.  The samples left and
    their areas are those of the whole halved surface wherever a sample may be uncovered (same
    positions and areas, bit for bit), so the uncovered samples, their patches and the fill
    passes are those of checking every sample; only the numbering of the samples differs.

    Parameters
    ----------
    surface : Surface
    tool : Tool
    feed : (3,) float
        The plan's feed direction (passes run along it); the chord is measured across it.
    step : float, optional
        Sample spacing, m (default R/8).
    chord_share : float
        Share of the contact chord counted as reached (default 1).

    Attributes
    ----------
    points : (s, 3) float
        The samples of the last :meth:`covered` call, m.
    areas : (s,) float
        The area each sample stands for, m² (a third of each incident halved triangle; samples
        set aside as covered may carry only part of theirs).
    half_chord : (s,) float
        Half the contact chord at each sample, m.
    total : float
        Area of the surface, m².
    """

    def __init__(self, surface, tool, feed, *, step: float | None = None, chord_share: float = 1.0):
        R = tool.pad_radius
        step = R / 8.0 if step is None else float(step)
        pad = pad_scale_samples(surface, tool)
        along = np.cross(np.cross(pad.normals, np.asarray(feed, float)), pad.normals)   # feed in each tangent plane
        along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-12)
        chord = patch_widths(pad.curvature, pad.normals, along, tool)
        half = 0.5 * np.minimum(chord, 2 * R)
        self.pad_half_chord = half if chord_share == 1.0 else chord_share * half
        self._pad_tree = surface_memo(surface, ("pad_tree", tool), lambda: cKDTree(pad.points))
        self._neighbours = lambda: surface_memo(surface, ("pad_neighbours", tool),
                                                lambda: pad_neighbours(self._pad_tree, R * 2.0 ** np.arange(-1, 3)))
        self._least: list[tuple[float, np.ndarray]] | None = None
        self.surface = surface
        self.tool = tool
        self.total = float(surface.area)
        self.step = step
        self.points = np.zeros((0, 3))
        self.areas = np.zeros(0)
        self.half_chord = np.zeros(0)
        self._known = np.zeros(0, bool)
        self._grid: PointGrid | None = None
        self._last: tuple[list, np.ndarray] | None = None

    def _least_reach(self, centre: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """(k,) m: a reach no sample in the ball of radius ``rho`` (k,) around ``centre`` (k, 3) falls below.

        A sample's reach is set by its nearest pad-scale sample, which lies within ``2 (rho + d)`` of
        the pad-scale sample nearest to the centre (``d`` away): the least half chord of the
        pad-scale samples that near (:func:`pad_neighbours`) bounds the reach from below.
        """
        d, near = self._pad_tree.query(centre)
        need = 2.0 * (rho + d) * (1.0 + 1e-9) + SURE_MARGIN
        out = np.full(len(centre), float(self.pad_half_chord.min()))
        for radius, least in reversed(self._least_by_radius()):           # the largest radius first
            ok = need <= radius
            if ok.any():
                out[ok] = least[near[ok]]
        return out * (1.0 + CHORD_TOLERANCE)

    def _least_by_radius(self) -> list[tuple[float, np.ndarray]]:
        """``(radius, least (p,))`` per radius of :func:`pad_neighbours`: the least half chord (m) of
        the pad-scale samples within that radius of each pad-scale sample; made once per check."""
        if self._least is None:
            self._least = []
            for radius, i, j in self._neighbours():
                least = self.pad_half_chord.copy()                  # each sample is its own neighbour
                np.minimum.at(least, i, self.pad_half_chord[j])
                self._least.append((radius, least))
        return self._least

    def _drop(self, grid, top: float, n_pass_points: int, xyz, faces) -> np.ndarray:
        """(k,) bool: the triangles ``faces`` (k, 3) of ``xyz`` surely within reach of a pass point of
        ``grid`` (no sample reaches more than ``top``, m), set aside unsplit (see the class)."""
        tri = xyz[faces]
        centre = tri.mean(axis=1)
        rho = np.sqrt(((tri - centre[:, None, :]) ** 2).sum(axis=2)).max(axis=1)
        out = np.zeros(len(faces), bool)
        some = np.flatnonzero(rho + SURE_MARGIN < top)
        if len(some) == 0 or n_pass_points == 0:
            return out
        # a pass point within (least reach - rho) of the centre is within reach of every point
        # of the triangle; the margin outweighs the rounding of these distances many times over
        room = self._least_reach(centre[some], rho[some]) - rho[some] - SURE_MARGIN
        sure = room > 0
        out[some[sure]] = grid.within(centre[some[sure]], room[sure])
        return out

    def _sure_blocks(self, base, grid, top: float, n_pass_points: int) -> np.ndarray:
        """(k,) bool over ``base.split``: the triangles of the blocks surely within reach of a pass
        point of ``grid``, as :meth:`_drop` tests a triangle (a block's ball holds its triangles'
        balls, and the least reach over it is at most theirs).  Set aside, they leave the
        uncovered samples as they were: every point of theirs would have been found covered."""
        rho, centre = base.block_rho, base.block_centre
        sure_block = np.zeros(len(rho), bool)
        some = np.flatnonzero(rho + SURE_MARGIN < top)
        if len(some) and n_pass_points:
            room = self._least_reach(centre[some], rho[some]) - rho[some] - SURE_MARGIN
            sure = room > 0
            sure_block[some[sure]] = grid.within(centre[some[sure]], room[sure])
        return sure_block[base.block_of]

    def _sample(self, pass_points: np.ndarray) -> None:
        """Halve the surface to the step where a sample may be out of reach of ``pass_points``."""
        top = float(self.pad_half_chord.max()) * (1.0 + CHORD_TOLERANCE)      # no sample reaches more
        grid = self._grid = PointGrid(pass_points, top)

        def drop(xyz, faces):
            return self._drop(grid, top, len(pass_points), xyz, faces)

        base = surface_memo(self.surface, ("coverage_base", self.tool, self.step),
                            lambda: _coverage_base(self.surface, self._pad_tree, self.step))
        n0 = len(self.surface.vertices)
        if len(base.split):
            # whole blocks of triangles first (a few hundred tests instead of one per triangle),
            # then the triangles of the blocks left, round by round
            block = self._sure_blocks(base, grid, top, len(pass_points))
            v, f, gone = halve_long_edges_except(self.surface.vertices, base.split[~block], self.step, drop)
            if block.any():
                gone = np.vstack([base.split[block], gone])
        else:
            v, f, gone = self.surface.vertices, base.split, base.split
        # the areas of the triangles never split, then the others', summed one by one in the
        # order of the whole halved surface (unsplit triangles first)
        areas = np.zeros(len(v))
        areas[:n0] = base.areas
        if len(f):
            np.add.at(areas, f.ravel(), np.repeat(face_normals_and_areas(v, f)[1] / 3.0, 3))
        self.points, self.areas = v, areas
        self._known = np.zeros(len(v), bool)
        self._known[gone.ravel()] = True
        self.half_chord = np.zeros(len(v))
        todo = np.flatnonzero(~self._known)
        # the nearest pad-scale sample of each sample that may be uncovered (the surface's own
        # vertices have theirs already)
        nearest = np.empty(len(todo), np.int64)
        old = todo < n0
        nearest[old] = base.nearest[todo[old]]
        if not old.all():
            nearest[~old] = self._pad_tree.query(v[todo[~old]])[1]
        self.half_chord[todo] = self.pad_half_chord[nearest]

    def covered(self, passes) -> np.ndarray:
        """(s,) bool: samples within half a chord of a pass point (``s`` = ``len(self.points)``).

        The samples follow the passes (see the class): a call whose ``passes`` do not extend
        those of the previous call samples the surface anew.  A sample is covered by a set of
        passes when it is covered by some of them, so when ``passes`` extends the set of the
        previous call (fill rounds add passes; the final check re-sorts them) the samples are
        kept, and only those still uncovered are tested, and only against the added passes: the
        same answer as testing all, for a fraction of the cost.
        """
        ids = {id(p) for p in passes}
        if self._last is not None and {id(p) for p in self._last[0]} <= ids:
            before, out = self._last[0], self._last[1].copy()
            old = {id(p) for p in before}
            added = [p for p in passes if id(p) not in old]
            fresh = False
        else:
            fresh = True
            added = list(passes)
            self._sample(np.vstack([p.points for p in added]) if added else np.zeros((0, 3)))
            out = self._known.copy()
        if added:
            reach = self.half_chord * (1.0 + CHORD_TOLERANCE)
            todo = np.flatnonzero(~out)
            if len(todo):
                if fresh and self._grid is not None:         # the passes' grid of the sampling
                    grid = self._grid
                else:
                    grid = PointGrid(np.vstack([p.points for p in added]), float(reach[todo].max()))
                out[todo] = grid.within(self.points[todo], reach[todo])
        # keep the passes themselves, so their ids stay theirs while the result is remembered
        self._last = (list(passes), out)
        return out.copy()

    def gap_fraction(self, passes) -> float:
        """Area share of the surface no pass reaches, 0..1."""
        free = ~self.covered(passes)              # first: the call may sample the surface anew
        return float(self.areas[free].sum() / self.total)

    def gap_patches(self, passes, *, min_share: float = MIN_GAP_SHARE) -> list[np.ndarray]:
        """Sample indices of each connected uncovered patch larger than ``min_share`` of the surface."""
        free = np.flatnonzero(~self.covered(passes))
        if len(free) == 0:
            return []
        pairs = cKDTree(self.points[free]).query_pairs(1.5 * self.step, output_type="ndarray")
        label = component_labels(len(free), pairs)
        # the samples of each label in increasing order (a stable sort), labels in increasing order
        order = np.argsort(label, kind="stable")
        cuts = np.flatnonzero(np.diff(label[order])) + 1
        out = []
        for members in np.split(order, cuts):
            idx = free[members]
            if self.areas[idx].sum() >= min_share * self.total:
                out.append(idx)
        return out


def component_labels(n: int, pairs: np.ndarray) -> np.ndarray:
    """(n,) int: the connected component of each of ``n`` nodes joined by ``pairs`` ``(e, 2)``,
    numbered in the order of their lowest node, as
    ``scipy.sparse.csgraph.connected_components(..., directed=False)`` numbers them (a compiled
    union-find instead of a sparse matrix)."""
    pairs = np.ascontiguousarray(np.asarray(pairs, np.int64).reshape(-1, 2))
    return _component_labels(int(n), pairs)


@jit()
def _component_labels(n, pairs):   # pragma: no cover - compiled
    parent = np.arange(n)
    for e in range(len(pairs)):
        a, b = pairs[e, 0], pairs[e, 1]
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
    label = np.empty(n, np.int64)
    count = 0
    for v in range(n):                  # a root is its component's lowest node: numbered first
        r = v
        while parent[r] != r:
            r = parent[r]
        if r == v:
            label[v] = count
            count += 1
        else:
            label[v] = label[r]
    return label


@dataclass(frozen=True)
class _CoverageBase:
    """What the samples of :class:`CoverageCheck` share whatever the passes: the triangles with an
    edge to halve ``split`` (k, 3), the area the others give the surface's vertices ``areas`` (n,)
    (m², a third of each, summed in face order) and each vertex's nearest pad-scale sample ``nearest`` (n,)."""

    split: np.ndarray
    areas: np.ndarray
    nearest: np.ndarray
    #: block of each triangle of ``split`` (k,), and each block's ball: centre (b, 3), radius (b,), m
    block_of: np.ndarray
    block_centre: np.ndarray
    block_rho: np.ndarray


def _coverage_base(surface, pad_tree, step) -> _CoverageBase:
    V, F = surface.vertices, surface.faces
    # the surface's own edge lengths (worked out already), the same numbers as halve_long_edges's
    # ``((d * d).sum(axis=2)) ** 0.5`` bit for bit: corner k to corner k + 1, squares summed in order
    long_face = (surface.edge_lengths.reshape(-1, 3) > step).any(axis=1)
    # a face's area is a function of its own corners (face_normals_and_areas works row by row), so
    # the surface's face areas of the faces kept, and its vertex areas where every face is kept
    if long_face.any():
        areas = vertex_areas(len(V), F[~long_face], surface.face_areas[~long_face])
    else:
        areas = surface.vertex_areas
    split = F[long_face].astype(np.int64)
    return _CoverageBase(split, areas, pad_tree.query(V)[1], *_blocks(V[split], BLOCK_STEPS * step))


#: Edge of the cells (in sample steps) whose triangles :meth:`CoverageCheck._sure_blocks` tests together.
BLOCK_STEPS = 2.0


def _blocks(corners: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The triangles ``corners`` (k, 3, 3) (m) grouped by the cube of edge ``cell`` (m) their centroid
    falls in: each triangle's block (k,), each block's centre (the middle of its corners' bounding
    box) (b, 3) and the radius of the ball round it that holds them (b,), m."""
    if len(corners) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0)
    centroid = corners.mean(axis=1)
    key = np.floor((centroid - centroid.min(axis=0)) / cell).astype(np.int64)
    dims = key.max(axis=0) + 1
    _, block_of = np.unique((key[:, 0] * dims[1] + key[:, 1]) * dims[2] + key[:, 2], return_inverse=True)
    block_of = block_of.ravel()
    n = int(block_of.max()) + 1
    lo, hi = np.full((n, 3), np.inf), np.full((n, 3), -np.inf)
    np.minimum.at(lo, block_of, corners.min(axis=1))
    np.maximum.at(hi, block_of, corners.max(axis=1))
    centre = 0.5 * (lo + hi)
    rho = np.zeros(n)
    np.maximum.at(rho, block_of, np.linalg.norm(corners - centre[block_of][:, None, :], axis=2).max(axis=1))
    return block_of, centre, rho * (1.0 + 1e-9)


def pad_neighbours(tree, radii) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """For each radius (m), the pairs of points of ``tree`` within it of each other, as
    ``(radius, i (e,), j (e,))`` (radii increasing; both orders and each point with itself).

    The pairs are those of ``tree.query_ball_point(tree.data, radius)`` (the same distance test:
    ``j`` is in the ball of ``i``), found by one ``sparse_distance_matrix`` per radius: its pairs
    come as arrays, where the ball queries build a Python list per point (5-15x the time on the
    shared meshes).
    """
    out = []
    for radius in sorted(float(r) for r in radii):
        pairs = tree.sparse_distance_matrix(tree, radius, output_type="ndarray")
        out.append((radius, pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)))
    return out


#: Grids of the pass points with more cells than this fall back to a KD-tree query.
MAX_GRID_CELLS = 20_000_000


def within_reach(samples: np.ndarray, reach: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(s,) bool: whether some of ``points`` ``(p, 3)`` lies within ``reach[i]`` (m) of ``samples[i]``
    ``(s, 3)`` (m), the distance being ``sqrt(dx² + dy² + dz²)`` as in :class:`scipy.spatial.cKDTree`.

    The points are binned on a grid of cells as wide as the largest reach (:class:`PointGrid`) and
    each sample looks in its own and the 26 neighbouring cells, stopping at the first point close
    enough (compiled); most samples near a pass stop within a few points, where a nearest-neighbour
    query would keep looking for the nearest one.
    """
    reach = np.ascontiguousarray(reach, float)
    if len(samples) == 0 or len(points) == 0:
        return np.zeros(len(samples), bool)
    return PointGrid(points, float(reach.max())).within(samples, reach)


class PointGrid:
    """Points ``(p, 3)`` (m) binned on a grid of cubic cells of side ``cell`` (m), to ask
    :meth:`within` about any reach up to ``cell`` without binning them again."""

    def __init__(self, points: np.ndarray, cell: float):
        self.points = np.ascontiguousarray(points, float).reshape(-1, 3)
        self.cell = float(cell)
        self.tree = None
        if len(self.points) == 0:
            return
        self.lo = self.points.min(axis=0)
        dims = (np.floor((self.points.max(axis=0) - self.lo) / self.cell) + 1) if self.cell > 0 else np.full(3, np.inf)
        if not (np.isfinite(dims).all() and float(np.prod(dims)) <= MAX_GRID_CELLS):
            self.tree = cKDTree(self.points)
            return
        self.dims = dims.astype(np.int64)
        ijk = np.floor((self.points - self.lo) / self.cell).astype(np.int64)
        key = (ijk[:, 0] * self.dims[1] + ijk[:, 1]) * self.dims[2] + ijk[:, 2]
        order = np.argsort(key, kind="stable")
        self.start = np.searchsorted(key[order], np.arange(int(np.prod(self.dims)) + 1))
        self.sorted = self.points[order]

    def within(self, samples: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """(s,) bool: whether a point lies within ``reach[i]`` (m, at most the cell) of ``samples[i]``
        ``(s, 3)`` (m); see :func:`within_reach`."""
        samples = np.ascontiguousarray(samples, float).reshape(-1, 3)
        reach = np.ascontiguousarray(reach, float)
        if len(samples) == 0 or len(self.points) == 0:
            return np.zeros(len(samples), bool)
        if not float(reach.max()) <= self.cell:
            raise ValueError(f"reach {float(reach.max())!r} m is over the grid's cell {self.cell!r} m")
        if self.tree is not None:
            d = self.tree.query(samples, distance_upper_bound=self.cell + 1e-9)[0]
            return d <= reach
        return _within_reach_kernel(samples, reach, self.sorted, self.lo, self.cell, self.dims, self.start)


@jit()
def _within_reach_kernel(samples, reach, points, lo, cell, dims, start):   # pragma: no cover - compiled
    # The sample's own cell first, then the neighbours whose box comes within reach (the others
    # hold no point within reach: the slack outweighs the rounding of the binning many times over).
    out = np.zeros(len(samples), np.bool_)
    steps = np.array([0, -1, 1])
    for s in range(len(samples)):
        x, y, z = samples[s, 0], samples[s, 1], samples[s, 2]
        r = reach[s]
        slack = r * (1.0 + 1e-9) + 1e-12
        ci = int(np.floor((x - lo[0]) / cell))
        cj = int(np.floor((y - lo[1]) / cell))
        ck = int(np.floor((z - lo[2]) / cell))
        found = False
        for a in range(3):
            i = ci + steps[a]
            if i < 0 or i >= dims[0]:
                continue
            gx = max(lo[0] + i * cell - x, x - (lo[0] + (i + 1) * cell), 0.0)
            if gx > slack:
                continue
            for b in range(3):
                j = cj + steps[b]
                if j < 0 or j >= dims[1]:
                    continue
                gy = max(lo[1] + j * cell - y, y - (lo[1] + (j + 1) * cell), 0.0)
                if gx * gx + gy * gy > slack * slack:
                    continue
                for e in range(3):
                    k = ck + steps[e]
                    if k < 0 or k >= dims[2]:
                        continue
                    gz = max(lo[2] + k * cell - z, z - (lo[2] + (k + 1) * cell), 0.0)
                    if gx * gx + gy * gy + gz * gz > slack * slack:
                        continue
                    c = (i * dims[1] + j) * dims[2] + k
                    for q in range(start[c], start[c + 1]):
                        dx = points[q, 0] - x
                        dy = points[q, 1] - y
                        dz = points[q, 2] - z
                        if np.sqrt(dx * dx + dy * dy + dz * dz) <= r:
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
            if found:
                break
        out[s] = found
    return out


def fill_passes(check: CoverageCheck, patches, slicer, feed, cross, pad_radius: float) -> list:
    """One fill pass per uncovered patch: the slice through the patch's middle (along the cross
    direction), clipped to the patch's extent along the feed plus half a pad either side.

    Parameters
    ----------
    check : CoverageCheck
    patches : list of (k,) int
        Sample indices of each patch (:meth:`CoverageCheck.gap_patches`).
    slicer : callable
        ``slicer(offset) -> list of (points (k, 3), normals (k, 3))``: the fragments of the plane
        ``x·cross = offset`` through the surface, resampled, normals toward the tool.
    feed, cross : (3,) float
    pad_radius : float, m

    Returns
    -------
    list of (points, normals, offset)
    """
    out = []
    for idx in patches:
        p = check.points[idx]
        off = float(np.median(p @ cross))
        lo, hi = float((p @ feed).min()) - 0.5 * pad_radius, float((p @ feed).max()) + 0.5 * pad_radius
        for pts, nrm in slicer(off):
            s = pts @ feed
            keep = (s >= lo) & (s <= hi)
            if keep.sum() < 2:
                continue
            # the longest run of kept points (a fragment may leave and re-enter the window)
            edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(int), [0]])))
            runs = edges.reshape(-1, 2)
            a, b = max(runs, key=lambda r: r[1] - r[0])
            if b - a >= 2 and _comes_within(p, pts[a:b:max((b - a) // 50, 1)], 2 * pad_radius):
                out.append((pts[a:b], nrm[a:b], off))
    return out


def _comes_within(points: np.ndarray, others: np.ndarray, reach: float) -> bool:
    """Whether some of ``points`` ``(s, 3)`` lies within ``reach`` (m) of some of ``others`` ``(q, 3)``,
    the distance being ``np.linalg.norm`` of the difference: the answer of comparing every pair,
    found by a nearest-neighbour query and the exact distances of the nearest pair only (all pairs
    near the reach only when the query's rounding could decide otherwise)."""
    d = cKDTree(others).query(points)[0]
    slack = reach * (1.0 + 1e-9)
    near = d <= slack                        # a pair within reach is surely among these
    if not near.any():
        return False
    best = points[int(np.argmin(d))]
    if np.min(np.linalg.norm(best[None, :] - others, axis=1)) <= reach:
        return True
    return bool(np.min(np.linalg.norm(points[near][:, None, :] - others[None, :, :], axis=2)) <= reach)


#: At most this many rounds of fill passes (each round fills the gaps the previous ones left).
FILL_ROUNDS = 3


def fill_rounds(check: CoverageCheck, passes, fills_for, *, rounds: int = FILL_ROUNDS) -> tuple[list, int]:
    """Add fill passes until the plan leaves no gap patch, a round adds nothing or ``rounds`` are done.

    Parameters
    ----------
    check : CoverageCheck
    passes : sequence of Pass
        The plan so far (not modified).
    fills_for : callable
        ``fills_for(patches, passes) -> list of Pass``: the fill passes for this round's gap
        ``patches`` (:meth:`CoverageCheck.gap_patches`) given the plan so far.
    rounds : int

    Returns
    -------
    passes : list of Pass
        ``passes`` followed by every round's fill passes.
    added : int
    """
    passes = list(passes)
    added = 0
    for _ in range(rounds):
        patches = check.gap_patches(passes)
        if not patches:
            break
        new = fills_for(patches, passes)
        if not new:
            break
        passes += new
        added += len(new)
    return passes, added

