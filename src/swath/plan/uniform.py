"""Contact-aware uniform-coverage planner (Jaeger, ch. 4), on meshes.

Each pass is laid along the previous pass's ribbon boundary, so that neighbouring swaths meet
with a set overlap wherever the pad's real contact width changes with curvature:

1. A seed curve is chosen: part of the boundary on one side of the region (default), a slice
   through the middle, or a polyline the user gives.
2. From the latest passes a geodesic distance field ``d`` is computed over the surface (heat
   method, :mod:`potpourri3d`).  At every surface point the pad's swath width ``w_here`` across the
   would-be pass (whose feed runs along the level sets of ``d``) comes from the local contact model
   (principal curvatures and the solved sink at the set force), and ``w_prev`` is the width of the
   previous pass at its nearest point.
3. The next pass is the zero level set of
   ``g = d − (1 − overlap) · (w_prev + w_here) / 2``:
   its near ribbon edge meets the previous ribbon edge with ``overlap`` of the local width.  Jaeger
   finds this point by bisection along a cross curve from each base point of the previous pass;
   here the same condition is solved on every mesh edge (the zero crossing of ``g``), which gives
   the passes everywhere at once and breaks them cleanly at holes and ragged boundaries.
4. Passes are smoothed, projected back on the surface, cut where they turn too tightly for the
   tool to follow at speed (:data:`SHARP_TURN_SPEED_FRACTION`), and repeated until no uncovered
   area remains; the last pass is pulled in so its ribbon reaches the far boundary.  Pockets the
   pad rode over get short touch-up passes across them.  Passes are finally ordered zig-zag (each
   starts at the end nearest the previous one's end); the trajectory stage adds the short
   cross-over links.

The pass direction is free: :func:`uniform` tries several seed directions and keeps the one with
the shortest predicted cycle time (see ``direction``).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from ..errors import InfeasibleError, InputError
from ..surface.curvature import PrincipalCurvature
from ..surface.geometry import normalize
from .common import feed_and_cross
from ..surface.geodesic import FaceGradient
from ..surface.topology import mesh_edges
from .slicing import level_sets, resample, slice_mesh
from ..core import Pass, ToolPath
from ..contact.widths import patch_rows, unique_patches

log = logging.getLogger("swath.plan")

#: About this many working-mesh vertices at most (the default working edge is coarsened to stay near it).
MAX_WORK_VERTICES = 350_000

#: Passes are smoothed by a moving average this many pad radii long: level sets on the working mesh
#: zig-zag at its edge scale, and every zig-zag turns the tool (slowing it under an angular-speed limit).
SMOOTHING_WINDOW = 1.0

#: A pass is cut where following it at the feed would turn the tool about its axis faster than
#: ``max_angular`` / this fraction, i.e. where the angular-speed limit would slow the pad below this
#: fraction of the feed.  A pad that slows in contact dwells, and a tight hook or a small loop of a
#: level set (a pass turning round at a part edge, circling a bump) grinds a ring into the part; the
#: pieces either side are kept and the tool turns in the air between them instead.
SHARP_TURN_SPEED_FRACTION = 0.5

#: Candidate seed directions (rad from the first principal axis) for ``direction="auto"``.
AUTO_DIRECTIONS = tuple(np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 150.0]))


class WidthModel:
    """Swath widths from the local contact model at the vertices of a working mesh.

    The contact patch is solved once per distinct (rounded) curvature pair; widths across any
    feed direction are then read from it.
    """

    def __init__(self, curvature: PrincipalCurvature, normals: np.ndarray, tool):
        self.curvature = curvature
        self.normals = normals
        self.patch, self.inverse = unique_patches(curvature.k1, curvature.k2, tool, 180)

    def across(self, idx: np.ndarray, feed: np.ndarray) -> np.ndarray:
        """Width (m) of the swath at vertices ``idx`` ``(k,)`` for feed directions ``feed`` ``(k, 3)``."""
        n = self.normals[idx]
        t = feed - np.einsum("ij,ij->i", feed, n)[:, None] * n
        cross = np.cross(n, normalize(t))
        psi = np.arctan2(np.einsum("ij,ij->i", cross, self.curvature.d2[idx]),
                         np.einsum("ij,ij->i", cross, self.curvature.d1[idx]))
        return patch_rows(self.patch, self.inverse[idx], lambda p, rows: p.width_across(psi[rows]))


def uniform(surface, tool, *, overlap: float = 0.1, direction=None, seed="boundary",
            point_spacing: float = 1e-3, min_pass_length: float | None = None, max_passes: int = 400,
            feed: float = 0.05, max_angular: float = 1.0, cost=None,
            work_spacing: float | None = None, progress=None) -> ToolPath:
    """Cover a surface with passes laid along each other's ribbon boundaries (uniform coverage).

    Parameters
    ----------
    surface : Surface
        The part surface (normals toward the tool).
    tool : Tool
        The pad; its contact model sets the swath widths.
    overlap : float
        Overlap of neighbouring swaths as a fraction of the local width (default 0.1 = 10 %).
    direction : None, float or (3,) array
        Seed direction: the passes run along the feed direction at this angle (rad) from the
        surface's first principal axis (or along this vector, projected into the best-fit plane).
        None (default): plans with each of :data:`AUTO_DIRECTIONS` and keeps the cheapest by
        ``cost``.  The candidates are recorded in the metadata.
    seed : "boundary", "middle" or (k, 3) array
        The seed curve: the boundary on the low side across the feed direction, a slice through the
        middle (passes grow to both sides), or a polyline on the surface (m).
    point_spacing : float
        Arc-length step between pass points, m (default 1 mm).
    min_pass_length : float, optional
        Pieces shorter than this are dropped, m (default R/4).
    max_passes : int
        Safety limit on the number of pass generations.
    feed, max_angular : float
        Feed (m/s) and angular-speed limit (rad/s): a pass is cut where, at this feed, the tool
        would turn about its axis faster than ``max_angular`` / :data:`SHARP_TURN_SPEED_FRACTION`
        (the tool would slow and dwell there).
    cost : callable, optional
        ``cost(toolpath) -> (value, description)`` ranking candidate directions (lower is better),
        e.g. the predicted cycle time under the very limits and links the job's trajectory will
        use (:func:`swath.cli.job.cycle_time_cost` builds one).  Default: contact length plus the
        straight-line air distance between consecutive passes in zig-zag order, m.
    work_spacing : float, optional
        Edge length (m) the surface is subdivided to for the distance fields (default from the part
        size, between R/12 and R/4, coarsened if the mesh would exceed about
        :data:`MAX_WORK_VERTICES` vertices).
    progress : callable, optional
        ``progress(stage: str, done: int, total: int)``, called as candidate directions finish.

    Returns
    -------
    ToolPath
        ``metadata``: overlap_fraction, direction_rad, direction_rule, seed, n_passes, work_spacing_m,
        n_touch_up_passes and touch_up_passes (their indices in ``passes``; the passes also carry
        ``kind="touch_up"``), candidates (per direction: length_m, cost) for automatic direction,
        order_hint ``"zigzag"``.  Each pass's ``level`` is its generation.
    """
    if not (isinstance(overlap, (int, float)) and 0.0 <= overlap < 0.9):
        raise InputError(f"overlap must be a fraction in [0, 0.9), e.g. 0.1 for 10 %, got {overlap!r}")
    if not (np.isfinite(point_spacing) and point_spacing > 0):
        raise InputError(f"point_spacing must be a positive length in metres, got {point_spacing!r}")
    R = tool.pad_radius
    min_pass_length = 0.25 * R if min_pass_length is None else float(min_pass_length)
    if not (feed > 0 and max_angular > 0):
        raise InputError(f"feed and max_angular must be positive (m/s, rad/s), got {feed!r}, {max_angular!r}")
    ctx = _Context(surface, tool, work_spacing, max_turn_curvature=max_angular / (SHARP_TURN_SPEED_FRACTION * feed))

    if direction is None or (isinstance(direction, str) and direction == "auto"):
        return _auto(ctx, overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes,
                     cost=cost or length_cost, progress=progress)
    if isinstance(direction, str):
        raise InputError(f"direction must be None (auto), an angle in radians or a 3-vector, got {direction!r}")
    if isinstance(direction, (int, float)) and math.isfinite(direction):
        return _plan(ctx, float(direction), overlap=overlap, seed=seed, point_spacing=point_spacing,
                     min_pass_length=min_pass_length, max_passes=max_passes, rule="given angle")
    vec = np.asarray(direction, float).reshape(-1) if not isinstance(direction, (int, float)) else None
    if vec is None or vec.shape != (3,) or not np.isfinite(vec).all():
        raise InputError(f"direction must be None (auto), a finite angle in radians or a 3-vector, got {direction!r}")
    return _plan(ctx, vec, overlap=overlap, seed=seed, point_spacing=point_spacing,
                 min_pass_length=min_pass_length, max_passes=max_passes, rule="given vector")


class _Context:
    """The working mesh, its distance solver and width model, shared by all candidate directions."""

    def __init__(self, surface, tool, work_spacing, max_turn_curvature=math.inf):
        import potpourri3d as pp3d

        t0 = time.perf_counter()
        R = tool.pad_radius
        given = work_spacing is not None
        if not given:
            work_spacing = float(np.clip(np.sqrt(surface.area / 150_000.0), R / 12.0, R / 4.0))
        self.surface = surface
        self.tool = tool
        self.max_turn_curvature = float(max_turn_curvature)   # 1/m, in the tangent plane
        self.work = surface.subdivided(work_spacing)
        # Halving long thin CAD triangles makes far more vertices than an even mesh of the same edge
        # length; the distance solver's set-up grows faster than linearly with them, so coarsen to
        # stay near the budget (never past R/4, where the widths would blur).
        while not given and len(self.work.vertices) > 1.3 * MAX_WORK_VERTICES and work_spacing < R / 4.0:
            work_spacing = min(work_spacing * math.sqrt(len(self.work.vertices) / MAX_WORK_VERTICES), R / 4.0)
            self.work = surface.subdivided(work_spacing)
        self.work_spacing = float(work_spacing)
        W = self.work
        self.solver = pp3d.MeshHeatMethodDistanceSolver(np.asarray(W.vertices), np.asarray(W.faces, np.int64))
        # Curvature from the part's own vertices (nearest one to each working vertex): vertices added
        # on flat facets by the subdivision would read the faceting, not the surface.
        nearest = surface.kdtree.query(W.vertices)[1]
        c = surface.curvature
        self.widths = WidthModel(PrincipalCurvature(c.k1[nearest], c.k2[nearest], c.d1[nearest], c.d2[nearest]),
                                 W.normals, tool)
        self.tree = W.kdtree
        self.edges = mesh_edges(np.asarray(W.faces, np.int64))
        self._pts32 = W.vertices.astype(np.float32)
        self._nrm32 = W.normals.astype(np.float32)
        self.gradient = FaceGradient(W.vertices, W.faces)      # direction of the distance field
        log.info("uniform: working mesh %d vertices (edges <= %.1f mm), set up in %.2f s", len(W.vertices),
                 1e3 * self.work_spacing, time.perf_counter() - t0)

    def distance(self, sources: np.ndarray) -> np.ndarray:
        """Geodesic distance (m) from the vertex set ``sources`` to every working vertex.

        The heat method recovers distance up to a constant; it is fixed so the sources sit at 0
        (their median), and the field is clipped at 0.
        """
        src = np.unique(sources)
        d = np.asarray(self.solver.compute_distance_multisource(src.tolist()), float)
        return np.maximum(d - np.median(d[src]), 0.0)

    def frontier(self, covered: np.ndarray) -> np.ndarray:
        """Covered vertices with an uncovered neighbour: the edge of the covered region."""
        F = self.work.faces
        c = covered[F]
        mixed = c.any(axis=1) & ~c.all(axis=1)
        v = F[mixed][c[mixed]]
        return np.unique(v)

    def gradient_directions(self, d: np.ndarray) -> np.ndarray:
        """Unit tangent direction of increasing ``d`` at each vertex ``(n, 3)``."""
        return self.gradient.vertex_directions(d, self.work.normals)

    def nearest_vertices(self, points: np.ndarray) -> np.ndarray:
        return self.tree.query(points)[1]

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points ``(k, 3)`` dropped onto the tangent plane of their nearest working vertex, and that
        vertex's smooth normal: within a micrometre of the surface for points already near it (the
        working mesh is finer than R/4), and far cheaper than an exact closest-point query."""
        idx = self.nearest_vertices(points)
        n = self.work.normals[idx]
        off = np.einsum("ij,ij->i", points - self.work.vertices[idx], n)
        return points - off[:, None] * n, n

    def touched(self, pts: np.ndarray) -> np.ndarray:
        """(n,) bool: working vertices the pressed pad touches along the pass ``pts`` ``(k, 3)``,
        at poses at most R/8 apart (see :meth:`touched_at`)."""
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        n = max(int(np.ceil(cum[-1] / (self.tool.pad_radius / 8))), 1) + 1
        idx = np.unique(np.searchsorted(cum, np.linspace(0, cum[-1], n)).clip(0, len(pts) - 1))
        return self.touched_at(pts[idx])

    def touched_at(self, poses: np.ndarray) -> np.ndarray:
        """(n,) bool: working vertices the pressed pad touches at the pad centres ``poses`` ``(k, 3)``.

        The mesh contact model (:func:`swath.contact.mesh_contact`), with the pad-face depth capped at
        that of the local contact model (principal curvatures at the pose): where the pad overhangs
        the part's edge the real pad sinks deeper and reaches farther, and passes laid along that
        wider edge would bow outward more with every generation.  The cap only ever shrinks the
        region counted as covered, so the simulator agrees with it.
        """
        from ..contact import mesh_contact

        if len(poses) == 0:
            return np.zeros(len(self.work.vertices), bool)
        closest, normals = self.project(poses)
        axes = -normals
        W = self.work
        mc = mesh_contact(self._pts32, self._nrm32, W.vertex_areas, self.tree, closest, axes, self.tool)
        cap = np.minimum(mc.sink, self.widths.patch.sink[self.widths.inverse[self.nearest_vertices(closest)]])
        height = mc.sink[mc.pose] - mc.pressure / self.tool.k        # sample height along tool z
        sample = mc.sample[height < cap[mc.pose]]
        out = np.zeros(len(W.vertices), bool)
        out[sample] = True
        return out


def _plan(ctx: _Context, angle, *, overlap, seed, point_spacing, min_pass_length, max_passes, rule,
          extra_meta=None) -> ToolPath:
    """One uniform plan with the feed at ``angle`` (rad from the first principal axis, or a 3-vector)."""
    t0 = time.perf_counter()
    W, tool = ctx.work, ctx.tool
    R = tool.pad_radius
    if isinstance(angle, np.ndarray):
        feed_dir, cross = feed_and_cross(ctx.surface, direction=angle)
        a0 = ctx.surface.principal_axes[1][0]
        angle = math.atan2(float(np.cross(a0, feed_dir) @ np.cross(feed_dir, cross)), float(a0 @ feed_dir))
    else:
        feed_dir, cross = feed_and_cross(ctx.surface, angle=angle)
    step = min(2e-3, 0.5 * ctx.work_spacing)

    generations = []          # each: list of (points (k,3), widths (k,))
    covered = np.zeros(len(W.vertices), bool)
    current = _seed_curves(ctx, seed, cross, step)
    reach = 0.5 - overlap     # pass centre this many local widths beyond the covered edge
    if isinstance(seed, str) and seed == "middle":
        first = (_finished(ctx, current, step, min_pass_length)
                 or _finished(ctx, current, step, min_pass_length, cut=False))
        if not first:
            raise InfeasibleError("the middle slice of the surface is shorter than min_pass_length")
        generations.append(first)
        for pts, _ in first:
            covered |= ctx.touched(pts)
        sources = None
    else:
        sources = np.vstack(current)

    for _ in range(max_passes):
        # Distance from what is covered so far (or from the seed before the first pass).
        src = ctx.nearest_vertices(sources) if sources is not None else ctx.frontier(covered)
        if len(src) == 0:
            break
        d = ctx.distance(src)
        if sources is None:
            d[covered] = 0.0
        left = (d > 0) & ~covered
        if _area(W, left) <= 1e-4 * W.area:
            break
        band = np.flatnonzero((d <= 2.5 * R) & left)
        w_here = np.full(len(W.vertices), 2 * R)
        if len(band):
            gdir = ctx.gradient_directions(d)
            w_here[band] = ctx.widths.across(band, np.cross(W.normals[band], gdir[band]))
        g = d - reach * w_here
        pieces = level_sets(W.vertices, W.faces, g, [0.0], edges=ctx.edges)
        if not pieces:
            # The far boundary is nearer than a full step: pull the last pass in so its ribbon
            # reaches the boundary.
            d_far = float(np.max(d[left]))
            w_left = float(np.median(w_here[left]))
            level = max(d_far - reach * w_left, 0.5 * d_far)
            pieces = level_sets(W.vertices, W.faces, d - level, [0.0], edges=ctx.edges)
        new = _finished(ctx, pieces, step, min_pass_length)
        gained = _touched_by(ctx, new)
        if not (gained & ~covered).any():
            # Cutting at sharp turns left nothing that reaches new area (a short seed stretch gives a
            # first level set curled round it; a pocket's level set is a small loop): a pass that
            # makes the tool slow down beats none.
            whole = _finished(ctx, pieces, step, min_pass_length, cut=False)
            gained_whole = _touched_by(ctx, whole)
            log.debug("uniform generation %d: cut pieces gain nothing; whole pieces gain %.4f m2",
                      len(generations), _area(W, gained_whole & ~covered))
            new, gained = whole, gained_whole
        log.debug("uniform generation %d: %d level-set pieces, %d kept, uncovered %.4f m2", len(generations),
                  len(pieces), len(new), _area(W, left))
        if not (gained & ~covered).any():
            log.warning("uniform: a pass generation covered nothing new; stopping")
            break
        generations.append(new)
        covered |= gained
        sources = None
    else:
        log.warning("uniform: stopped after max_passes=%d generations", max_passes)

    passes_pts = [p for gen in generations for p, _ in gen]
    generation_of = {id(p): g for g, gen in enumerate(generations) for p, _ in gen}
    if not passes_pts:
        raise InfeasibleError("uniform found no pass: the surface is narrower than the shortest allowed pass "
                              f"({min_pass_length * 1e3:.1f} mm) in every direction tried")
    covered, touch_ups = _touch_up(ctx, passes_pts, covered, step, min_pass_length)
    merged = _insert_near(passes_pts, touch_ups)
    touch_up_index = [i for i, q in enumerate(merged) if any(q is t for t in touch_ups)]
    passes = [_on_surface_pass(ctx.surface, p, point_spacing, level=generation_of.get(id(p), -1),
                               kind="touch_up" if i in touch_up_index else "pass") for i, p in enumerate(merged)]
    # Coverage the planner itself predicts (pad-touched area of the working mesh, with the sink
    # capped as in _Context.touched); the simulator's figure is the one to trust.
    covered_pred = float(W.vertex_areas[covered].sum() / W.area)
    meta = dict(overlap_fraction=float(overlap), direction_rad=float(angle), direction_rule=rule,
                predicted_coverage_fraction=covered_pred,
                feed_direction=feed_dir.tolist(), seed=seed if isinstance(seed, str) else "polyline",
                n_passes=len(passes), n_generations=len(generations), n_touch_up_passes=len(touch_ups),
                touch_up_passes=touch_up_index, order_hint="zigzag",
                work_spacing_m=ctx.work_spacing,
                point_spacing_m=float(point_spacing), min_pass_length_m=float(min_pass_length),
                plan_time_s=time.perf_counter() - t0)
    if extra_meta:
        meta.update(extra_meta)
    log.info("uniform %s: direction %.0f deg, %d passes in %d generations, %.2f m, %.1f s", ctx.surface.name,
             math.degrees(angle), len(passes), len(generations), sum(p.length for p in passes), meta["plan_time_s"])
    return ToolPath(ctx.surface, passes, "uniform", meta)


def length_cost(toolpath) -> tuple[float, str]:
    """Contact length plus the straight air distance between passes run zig-zag (each from the end
    nearer the previous end), m: the default ranking of candidate directions."""
    total, end = toolpath.contact_length, None
    for p in toolpath.passes:
        first, last = p.points[0], p.points[-1]
        if end is not None:
            d_first, d_last = np.linalg.norm(first - end), np.linalg.norm(last - end)
            total += min(d_first, d_last)
            end = last if d_first <= d_last else first
        else:
            end = last
    return float(total), "contact + straight air length (m)"


def _auto(ctx, *, overlap, seed, point_spacing, min_pass_length, max_passes, cost, progress=None):
    results = []
    say = progress or (lambda stage, done, total: None)
    what = ""
    for k, a in enumerate(AUTO_DIRECTIONS):
        say("planning (uniform): trying pass directions", k, len(AUTO_DIRECTIONS) + 1)
        try:
            tp = _plan(ctx, float(a), overlap=overlap, seed=seed, point_spacing=max(point_spacing, 2e-3),
                       min_pass_length=min_pass_length, max_passes=max_passes, rule="candidate")
        except InfeasibleError as exc:
            log.info("uniform: direction %.0f deg infeasible: %s", math.degrees(a), exc)
            continue
        value, what = cost(tp)
        results.append((float(a), tp.contact_length, float(value), tp.metadata["predicted_coverage_fraction"]))
        log.info("uniform candidate %.0f deg: %.2f m in contact, cost %.4g (%s)", math.degrees(a),
                 tp.contact_length, value, what)
    if not results:
        raise InfeasibleError("uniform found no feasible direction; check min_pass_length and the part size")
    # A direction must cover (a pad riding on the crests of waves narrower than itself leaves the
    # troughs untouched, so passes along the waves can miss area); among those that cover, the
    # cheapest wins.
    top = max(r[3] for r in results)
    good = [r for r in results if r[3] >= min(0.995, top - 0.002)]
    best = min(good, key=lambda r: r[2])
    say("planning (uniform): trying pass directions", len(AUTO_DIRECTIONS), len(AUTO_DIRECTIONS) + 1)
    candidates = [dict(direction_deg=math.degrees(a), length_m=L, cost=c, predicted_coverage_fraction=cv)
                  for a, L, c, cv in results]
    rule = (f"auto: lowest {what} among the directions whose predicted coverage is at least "
            f"{100 * min(0.995, top - 0.002):.1f} %")
    return _plan(ctx, best[0], overlap=overlap, seed=seed, point_spacing=point_spacing,
                 min_pass_length=min_pass_length, max_passes=max_passes, rule=rule,
                 extra_meta={"candidates": candidates})


# ----------------------------------------------------------------------------------------------
# pieces
# ----------------------------------------------------------------------------------------------
def _seed_curves(ctx, seed, cross, step) -> list[np.ndarray]:
    """Seed polylines (each (k, 3), on the working mesh)."""
    W = ctx.work
    if isinstance(seed, str):
        h = W.vertices @ cross
        if seed == "boundary":
            if not W.boundary_loops:
                raise InfeasibleError("the surface has no boundary to seed from; use seed='middle'")
            return [_boundary_seed(W, np.cross(cross, _mean_normal(W)), h, ctx.tool.pad_radius)]
        if seed == "middle":
            mid = 0.5 * (h.min() + h.max())
            lines = slice_mesh(W.vertices, W.faces, cross, [mid])
            return [resample(pl, step).points for pl in lines]
        raise InputError(f"seed must be 'boundary', 'middle' or a (k, 3) polyline, got {seed!r}")
    pts = np.asarray(seed, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2 or not np.isfinite(pts).all():
        raise InputError(f"a seed polyline must be a finite (k>=2, 3) array of points in metres, got {pts.shape}")
    closest, dist, _ = W.closest_points(pts)
    if dist.max() > ctx.tool.pad_radius:
        raise InputError(f"the seed polyline lies up to {dist.max() * 1e3:.1f} mm off the surface; "
                         "give points on the surface")
    return [closest]


def _mean_normal(W) -> np.ndarray:
    return normalize((W.face_normals * W.face_areas[:, None]).sum(axis=0)[None])[0]


def _boundary_seed(W, feed, h, R) -> np.ndarray:
    """The stretch of boundary on the low side across the feed that runs along the feed.

    Starting from the boundary vertex lowest in ``h`` (the coordinate across the feed), the loop is
    followed both ways while its tangent (smoothed over about R/2) stays within 50 degrees of the
    feed direction: the whole straight edge of a panel, the trailing edge of a blade, and only the
    near-parallel part of a ragged scan edge.
    """
    loops = W.boundary_loops
    k = int(np.argmin([h[l].min() for l in loops]))
    loop = loops[k]
    pts = W.vertices[loop]
    seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    span = max(3, int(np.ceil(0.5 * R / max(np.median(seg), 1e-9))))
    tangent = normalize(np.roll(pts, -span, axis=0) - np.roll(pts, span, axis=0))
    local = normalize(np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0))
    # Both the smoothed and the local tangent must run along the feed: smoothing alone would
    # carry the run a little way round a corner.
    cos50 = np.cos(np.radians(50.0))
    along = (np.abs(tangent @ feed) >= cos50) & (np.abs(local @ feed) >= cos50)
    n = len(loop)
    start = int(np.argmin(h[loop]))
    lo = hi = start
    while along[(lo - 1) % n] and (hi - lo) < n - 1:
        lo -= 1
    while along[(hi + 1) % n] and (hi - lo) < n - 1:
        hi += 1
    run = [(i % n) for i in range(lo, hi + 1)]
    return pts[run] if len(run) >= 2 else pts[[start, (start + 1) % n]]


def _finished(ctx, pieces, step, min_length: float, cut: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`_finish_piece` over level-set ``pieces``, keeping the parts at least ``min_length`` m long."""
    return [c for p in pieces for c in _finish_piece(ctx, p, step, cut) if _length(c[0]) >= min_length]


def _finish_piece(ctx, pl, step, cut: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
    """Resample, smooth and project a pass piece and (if ``cut``) cut it at sharp turns; return its
    parts as (points (k, 3), widths (k,)) pairs."""
    pts = pl if isinstance(pl, np.ndarray) else resample(pl, step).points
    if len(pts) < 3:
        return []
    # A short piece or a small loop would shrink under the full window: keep it to a sixth of the
    # piece (a loop's radius), which moves a loop's points in by under 4 %.
    window = min(SMOOTHING_WINDOW * ctx.tool.pad_radius, _length(pts) / 6.0) / step
    pts = _smooth(pts, window=max(3, int(round(window))))
    pts, nrm = ctx.project(pts)
    out = []
    limit = ctx.max_turn_curvature if cut else math.inf
    for part in _cut_sharp_turns(pts, nrm, limit, ctx.tool.pad_radius / 8):
        if len(part) < 3:
            continue
        tangents = normalize(np.gradient(part, axis=0))
        w = ctx.widths.across(ctx.nearest_vertices(part), tangents)
        out.append((part, w))
    return out


def turn_curvature(pts: np.ndarray, normals: np.ndarray, arm: float) -> np.ndarray:
    """(k,) curvature (1/m) of the polyline ``pts`` ``(k, 3)`` within the tangent planes ``normals``:
    the turn between the chords to the points ``arm`` metres behind and ahead, over their mean
    length.  This is the geodesic curvature a pass has on the surface; at feed v the tool turns
    about its axis at v times it.  A closed polyline (ends within two steps) wraps round."""
    k = len(pts)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if k < 3 or steps.sum() <= 0:
        return np.zeros(k)
    m = max(1, int(round(arm / max(float(np.median(steps)), 1e-12))))
    closed = _is_closed(pts)
    i = np.arange(k)
    if closed:
        ring = k - 1                              # the last point repeats the first
        back, ahead = pts[(i - m) % ring], pts[(i + m) % ring]
    else:
        back, ahead = pts[np.maximum(i - m, 0)], pts[np.minimum(i + m, k - 1)]
    c1, c2 = pts - back, ahead - pts
    c1 = c1 - np.einsum("ij,ij->i", c1, normals)[:, None] * normals
    c2 = c2 - np.einsum("ij,ij->i", c2, normals)[:, None] * normals
    l1, l2 = np.linalg.norm(c1, axis=1), np.linalg.norm(c2, axis=1)
    ok = (l1 > 1e-12) & (l2 > 1e-12)
    cos = np.einsum("ij,ij->i", c1, c2) / np.maximum(l1 * l2, 1e-300)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))
    return np.where(ok, angle / np.maximum(0.5 * (l1 + l2), 1e-12), 0.0)


def _cut_sharp_turns(pts, normals, max_curvature: float, arm: float) -> list[np.ndarray]:
    """Split the polyline ``pts`` where it turns in its tangent plane by more than ``max_curvature``
    (1/m, measured over chords ``arm`` long); the sharp stretches themselves are dropped."""
    if not math.isfinite(max_curvature):
        return [pts]
    sharp = turn_curvature(pts, normals, arm) > max_curvature
    if not sharp.any():
        return [pts]
    closed = len(pts) > 3 and _is_closed(pts)
    if closed:
        # Start the loop at a sharp point so the smooth runs do not straddle the seam.
        first = int(np.flatnonzero(sharp)[0])
        pts = np.vstack([pts[first:-1], pts[:first + 1]])
        sharp = np.concatenate([sharp[first:-1], sharp[:first + 1]])
    keep = ~sharp
    edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
    return [pts[a:b] for a, b in zip(edges[::2], edges[1::2])]


def _is_closed(pts) -> bool:
    """Whether the polyline ``pts`` ``(k, 3)`` is a loop: its ends within two median steps."""
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    return bool(np.linalg.norm(pts[-1] - pts[0]) <= 2.0 * np.median(steps))


def _smooth(pts, window):
    """Moving-average smoothing of a polyline ``(k, 3)`` over ``window`` points: an open one with
    its ends held, a closed one (ends within two point steps) all the way round."""
    k = len(pts)
    if k < 5 or window < 3:
        return pts
    window = min(window | 1, k - (1 - k % 2))
    if window < 3:
        return pts
    kernel = np.ones(window) / window
    half = window // 2
    closed = _is_closed(pts)
    if closed:
        padded = np.vstack([pts[-half - 1:-1], pts, pts[1:half + 1]])
    else:
        padded = np.vstack([np.repeat(pts[:1], half, 0), pts, np.repeat(pts[-1:], half, 0)])
    out = np.stack([np.convolve(padded[:, j], kernel, mode="valid") for j in range(3)], axis=1)
    if not closed:
        out[0], out[-1] = pts[0], pts[-1]
    return out


def _touched_by(ctx, pieces) -> np.ndarray:
    """(n,) bool: working vertices the pad touches along any of ``pieces`` ((points, widths) pairs)."""
    gained = np.zeros(len(ctx.work.vertices), bool)
    for pts, _ in pieces:
        gained |= ctx.touched(pts)
    return gained


def _length(pts) -> float:
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _area(W, mask) -> float:
    return float(W.vertex_areas[mask].sum())


def _touch_up(ctx, passes: list[np.ndarray], covered: np.ndarray, step: float, min_pass_length: float,
              rounds: int = 2) -> tuple[np.ndarray, list[np.ndarray]]:
    """Check the pockets the passes seem to miss, and cross the ones they really miss.

    Where the surface is concave more tightly than the pad can follow (waves or dimples narrower
    than the pad), the pad rides on the crests and touches a trough's bottom only with its rim, at
    the moment its centre is about a pad radius away.  Those rim contacts are thin, so the pockets
    left uncovered by the generation loop (whose poses are R/8 apart) are first re-checked with a pose
    at every pass point (``step`` apart).  A pocket (at least 1 % and at most 100 % of the pad's area)
    still untouched gets a short pass across it
    along its most concave principal direction, reaching a pad radius beyond it on both sides, so
    the rim sweeps its bottom on the way in and out; it is kept only if it touches new area.

    Parameters
    ----------
    passes : list of (k, 3) float
        The passes so far, points ``step`` apart, m.
    covered : (n,) bool
        Working vertices touched so far.

    Returns
    -------
    covered : (n,) bool
        Updated.
    touch_ups : list of (k, 3) float
        The added passes.
    """
    W, R = ctx.work, ctx.tool.pad_radius
    min_area = max(1e-4 * W.area, 0.01 * math.pi * R * R)
    pad_area = math.pi * R * R
    big = _uncovered_pockets(ctx, covered, pad_area * (1 + 1e-9))
    if big:           # larger than the pad: not a pocket between passes (max_passes, or passes dropped)
        log.warning("uniform: %d uncovered regions larger than the pad (%.4f m2 in all) left as they are",
                    len(big), sum(_area(W, b) for b in big))
    blobs = _uncovered_pockets(ctx, covered, min_area, pad_area)
    if not blobs:
        return covered, []
    from scipy.spatial import cKDTree

    near_tree = cKDTree(W.vertices[np.concatenate(blobs)])
    for pts in passes:
        close = np.isfinite(near_tree.query(pts, distance_upper_bound=1.2 * R)[0])
        if close.any():
            covered = covered | ctx.touched_at(pts[close])
    added = []
    c = ctx.widths.curvature
    for _ in range(rounds):
        blobs = _uncovered_pockets(ctx, covered, min_area, pad_area)
        if not blobs:
            break
        grew = False
        for blob in blobs:
            centre = W.vertices[blob].T @ W.vertex_areas[blob] / W.vertex_areas[blob].sum()
            v = blob[np.argmin(np.linalg.norm(W.vertices[blob] - centre, axis=1))]
            n = W.normals[v]
            across = normalize((c.d2[v] - (c.d2[v] @ n) * n)[None])[0]
            reach = float(np.max(np.linalg.norm(W.vertices[blob] - W.vertices[v], axis=1))) + 1.1 * R
            pieces = slice_mesh(W.vertices, W.faces, np.cross(n, across), [float(W.vertices[v] @ np.cross(n, across))])
            best = None
            for pl in pieces:
                pts = resample(pl, step).points
                if len(pts) < 3:
                    continue
                dist = np.linalg.norm(pts - W.vertices[v], axis=1)
                k = int(np.argmin(dist))
                if best is None or dist[k] < best[1]:
                    best = (pts, dist[k], k, dist)
            if best is None or best[1] > ctx.work_spacing:
                continue
            pts, _, k, dist = best
            lo, hi = k, k
            while lo > 0 and dist[lo - 1] <= reach:
                lo -= 1
            while hi < len(pts) - 1 and dist[hi + 1] <= reach:
                hi += 1
            pts = pts[lo:hi + 1]
            if _length(pts) < min_pass_length:
                continue
            pts, _ = ctx.project(pts)
            gained = ctx.touched_at(pts) & ~covered
            if _area(W, gained) <= 0.0:
                continue
            covered = covered | gained
            added.append(pts)
            grew = True
        if not grew:
            break
    if added:
        log.info("uniform: %d touch-up passes across pockets the passes missed (%.2f m)", len(added),
                 sum(_length(p) for p in added))
    return covered, added


def _uncovered_pockets(ctx, covered: np.ndarray, min_area: float, max_area: float = math.inf) -> list[np.ndarray]:
    """Connected groups of uncovered working vertices (edges of ``ctx.edges``) whose area is
    within [``min_area``, ``max_area``] m²."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    W = ctx.work
    free = ~covered
    e = ctx.edges[0]
    e = e[free[e[:, 0]] & free[e[:, 1]]]
    n = len(W.vertices)
    _, label = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)
    ids = np.flatnonzero(free)
    area = np.bincount(label[ids], weights=W.vertex_areas[ids], minlength=n)
    order = np.argsort(label[ids], kind="stable")
    groups = np.split(ids[order], np.flatnonzero(np.diff(label[ids][order])) + 1)
    return [g for g in groups if len(g) and min_area <= area[label[g[0]]] <= max_area]


def _insert_near(passes: list[np.ndarray], extra: list[np.ndarray]) -> list[np.ndarray]:
    """``passes`` with each of ``extra`` inserted right after the pass nearest to its middle."""
    out = list(passes)
    for e in extra:
        mid = e[len(e) // 2]
        k = int(np.argmin([np.min(np.linalg.norm(p - mid, axis=1)) for p in out]))
        out.insert(k + 1, e)
    return out


def _on_surface_pass(surface, pts, point_spacing, **tags) -> Pass:
    """Resample a pass at ``point_spacing`` and put every point on ``surface`` with its smooth normal."""
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(int(np.ceil(cum[-1] / point_spacing)), 1) + 1
    s = np.linspace(0.0, cum[-1], n)
    res = np.stack([np.interp(s, cum, pts[:, j]) for j in range(3)], axis=1)
    closest, _, face = surface.closest_points(res)
    return Pass(closest, surface.interpolate_normals(closest, face), **tags)
