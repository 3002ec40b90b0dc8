"""The uniform planner's candidate directions: angles with the same seed are laid once, and the
set-up built beside a forked child is the one built here, bit for bit."""

import importlib

import numpy as np
import pytest

from swath.contact import Tool
from swath.examples import blade

U = importlib.import_module("swath.plan.uniform")
ANGLES = [float(a) for a in U.AUTO_DIRECTIONS]
OPTIONS = dict(overlap=0.1, seed="boundary", point_spacing=2e-3, min_pass_length=0.25 * Tool().pad_radius,
               max_passes=500)


@pytest.fixture(scope="module")
def blade_context():
    return U._Context(blade(), Tool(), None, max_turn_curvature=100.0)


def _plain_cost(toolpath):
    """A cost without ``passes_only``: it might read the metadata, so it is called for every angle."""
    return U.length_cost(toolpath)[0] + toolpath.metadata["direction_rad"], "length + angle"


def test_the_blade_seeds_120_and_150_degrees_from_the_same_boundary_stretch(blade_context):
    groups = U._same_seed_groups(blade_context, ANGLES, "boundary")
    assert [[round(np.degrees(a)) for a in g] for g in groups] == [[0], [30], [60], [90], [120, 150]]
    # a given polyline seeds every direction the same way: one group
    seed = blade_context.work.vertices[blade_context.work.boundary_loops[0][:20]]
    assert len(U._same_seed_groups(blade_context, ANGLES, seed)) == 1


@pytest.mark.parametrize("cost", [U.length_cost, _plain_cost])
def test_a_group_ranks_each_angle_as_planning_it_alone_would(blade_context, cost):
    a, b = ANGLES[4], ANGLES[5]
    grouped = U._candidate_group(blade_context, [a, b], OPTIONS, cost)
    alone = [U._candidate(blade_context, x, OPTIONS, cost) for x in (a, b)]
    for g, s, angle in zip(grouped, alone, (a, b)):
        assert g[:4] == s[:4]                                   # length, cost, description, coverage
        assert g[4]["angle"] == s[4]["angle"] == angle
        np.testing.assert_array_equal(g[4]["feed_dir"], s[4]["feed_dir"])
        assert len(g[4]["polylines"]) == len(s[4]["polylines"])
        for p, q in zip(g[4]["polylines"], s[4]["polylines"]):
            np.testing.assert_array_equal(p, q)
    if cost is _plain_cost:
        assert grouped[0][1] != grouped[1][1]                  # the angle entered this cost


def test_the_set_up_built_beside_a_child_equals_the_one_built_here(blade_context):
    here = U._Context(blade(), Tool(), None, max_turn_curvature=100.0, beside=False)
    there = blade_context
    np.testing.assert_array_equal(here.work.normals, there.work.normals)
    for name in ("max_width", "min_width", "inverse"):
        np.testing.assert_array_equal(getattr(here.widths, name), getattr(there.widths, name))
    np.testing.assert_array_equal(here.widths.patch.rho_out, there.widths.patch.rho_out)
    np.testing.assert_array_equal(here.widths.curvature.k1, there.widths.curvature.k1)
    np.testing.assert_array_equal(here._grid.normals, there._grid.normals)   # built from the child's normals
    # the part's own normals and curvature and the working mesh's boundary came from the child too
    np.testing.assert_array_equal(here.surface.normals, there.surface.normals)
    for name in ("k1", "k2", "d1", "d2"):
        np.testing.assert_array_equal(getattr(here.surface.curvature, name), getattr(there.surface.curvature, name))
    assert len(here.work.boundary_loops) == len(there.work.boundary_loops) >= 1
    for a, b in zip(here.work.boundary_loops, there.work.boundary_loops):
        np.testing.assert_array_equal(a, b)
    # and so did the edges and the gradient operator, with its stacked corner bases
    for a, b in zip(here.edges, there.edges, strict=True):          # (edges, face edges)
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(here.gradient.stacked_basis, there.gradient.stacked_basis)
    np.testing.assert_array_equal(here.gradient.face_areas, there.gradient.face_areas)
    d = there.distance(np.arange(5))
    np.testing.assert_array_equal(here.gradient_directions(d), there.gradient_directions(d))


class _InlinePool:
    """A stand-in for ProcessPoolExecutor that runs each task when it is submitted and records the
    order of submission."""

    submitted: list = []

    def __init__(self, *args, **kwargs):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args):
        from concurrent.futures import Future

        type(self).submitted.append(fn.__name__)
        future: Future = Future()
        future.set_result(fn(*args))
        return future


def test_the_pool_queues_every_layout_before_any_ranking_and_gives_the_serial_rows(blade_context, monkeypatch):
    monkeypatch.setattr(U, "ProcessPoolExecutor", _InlinePool)
    monkeypatch.setattr(U, "_WORKER_CONTEXT", blade_context)
    _InlinePool.submitted = []
    groups = [[ANGLES[0]], [ANGLES[4], ANGLES[5]], [ANGLES[2]]]
    heard: list = []
    pooled = U._run_pool(None, None, groups, OPTIONS, U.length_cost, 2, lambda *a: heard.append(a[1:]),
                         clock=lambda: 0.0)
    # the short ranking tasks go last, where they fill the gaps the long layouts leave
    assert _InlinePool.submitted == ["_worker_layout"] * 3 + ["_worker_group_rows"] * 3
    # a layout counts LAYOUT_STEPS steps (120 and 150 degrees share one), a ranking one per direction
    steps = U.LAYOUT_STEPS
    total = 3 * steps + 4 + 1
    done = [h[0] for h in heard]
    assert {h[1] for h in heard} == {total} and done == sorted(done)
    assert done[2] == 3 * steps and done[-1] == 3 * steps + 4          # the layouts, then the rankings
    serial = [U._candidate_group(blade_context, g, OPTIONS, U.length_cost) for g in groups]
    assert [len(r) for r in pooled] == [1, 2, 1]
    for rows_p, rows_s in zip(pooled, serial):
        for p, q in zip(rows_p, rows_s):
            assert p[:4] == q[:4] and p[4]["angle"] == q[4]["angle"]


def test_the_layouts_still_running_count_by_their_time_against_those_back():
    now = [0.0]
    steps = U._PoolProgress(4, 2, clock=lambda: now[0])     # layouts 0 and 1 start at 0 s, 2 and 3 wait
    n = U.LAYOUT_STEPS
    now[0] = 10.0
    # layout 0 back after 10 s, layout 2 starts: layout 1 has run as long, so counts 0.9 of its steps
    assert steps.back(layout=0) == int(n + 0.9 * n)
    now[0] = 11.0
    assert steps.back(layout=1) == int(2 * n + n / 10.5)    # layout 3 starts; 2 has run 1 s of the mean 10.5
    now[0] = 20.0
    assert steps.back(layout=2) == int(3 * n + n * 9.0 / (31.0 / 3))   # 3 has run 9 s of the mean 10.3
    now[0] = 21.0
    assert steps.back(layout=3) == 4 * n
    assert steps.back(ranked=2) == 4 * n + 2
    # never fewer than said: five layouts on three workers, where a slow one raises the mean time
    now[0] = 0.0
    slow = U._PoolProgress(5, 3, clock=lambda: now[0])
    told = []
    for at, layout in ((5.0, 1), (105.0, 2), (205.0, 0), (205.1, 3)):
        now[0] = at
        told.append(slow.back(layout=layout))
    assert told[:3] == [25, 34, 43]          # 43: 3 layouts back, layout 3 at 0.9, layout 4 100 s of the mean 105
    # layout 3 back: 4 layouts and layout 4 at 100.1 s of the mean 128.8 make 42.99 steps, under the 43 said
    assert told[3] == 43
    # a layout back before the task whose worker it took (both in one batch): counted, its time unknown
    now[0] = 0.0
    batch = U._PoolProgress(3, 1, clock=lambda: now[0])
    now[0] = 5.0
    assert batch.back(layout=1) == n and batch.took == [] and sorted(batch.started) == [0, 2]   # 1 not queued again
    assert batch.back(layout=0) == 2 * n and batch.took == [5.0]


def test_the_set_up_says_its_vertices_and_about_how_long_it_takes():
    import re

    from swath.examples import flat_plate
    from swath.plan import uniform_model as M

    heard: list = []
    ctx = M._Context(flat_plate(spacing=0.01), Tool(), None, progress=lambda *a: heard.append(a))
    n = len(ctx.work.vertices)
    assert heard == [(f"{M.SETUP_STAGE} ({n:,} vertices, about {M.setup_estimate_s(n):.0f} s)", 0, 1)]
    assert re.fullmatch(r".* \([0-9,]+ vertices, about [0-9]+ s\)", heard[0][0])
    # the reference: 5.7 s at crs_part_5's 308,365 vertices, 1.2 s at snp_part_scan's 75,668
    assert M.setup_estimate_s(308_365) == pytest.approx(5.7)
    assert M.setup_estimate_s(75_668) == pytest.approx(1.22, abs=0.01)


def test_the_coverage_floor_is_within_0_2_percent_of_the_best_and_at_most_99_5_percent():
    assert U.coverage_floor(0.999) == pytest.approx(0.995)
    assert U.coverage_floor(0.99) == pytest.approx(0.988)
    assert U._worth_ranking({"covered_pred": 0.996}, 0.999)
    assert not U._worth_ranking({"covered_pred": 0.994}, 0.999)
    assert U._worth_ranking("infeasible: no seed", 0.999)          # its reason is reported, not ranked


@pytest.mark.parametrize("workers", [1, 2])
def test_a_direction_that_covers_too_little_is_not_ranked_and_the_plan_is_unchanged(monkeypatch, workers):
    import math

    from swath.examples import doubly_curved_panel
    from swath.plan.uniform import uniform

    surface = doubly_curved_panel(size_x=0.25, size_y=0.2, spacing=8e-3)
    options = dict(work_spacing=Tool().pad_radius / 5, workers=workers)
    everything = uniform(surface, Tool(), **options)
    assert round(math.degrees(everything.metadata["direction_rad"])) != 60
    real = U._first_layout
    ranked: list[float] = []

    def thin_at_60(ctx, angle, opts):
        layout = real(ctx, angle, opts)
        return dict(layout, covered_pred=0.9) if math.isclose(angle, math.radians(60)) else layout

    def counted(toolpath):                   # a lambda-like cost: does not pickle, so ranked here
        ranked.append(toolpath.metadata["direction_rad"])
        return U.length_cost(toolpath)

    monkeypatch.setattr(U, "_first_layout", thin_at_60)
    # forked workers inherit the patched layout; the picklable default cost ranks there
    thin = uniform(surface, Tool(), **options)
    by_angle = {round(c["direction_deg"]): c for c in thin.metadata["candidates"]}
    assert by_angle[60]["cost"] is None and by_angle[60]["predicted_coverage_fraction"] == 0.9
    before = {round(c["direction_deg"]): c for c in everything.metadata["candidates"]}
    for deg in (0, 30, 90, 120, 150):
        assert by_angle[deg] == before[deg]
    assert by_angle[60]["length_m"] == before[60]["length_m"]
    # 60 degrees did not win before, so the plan is the same, pass for pass
    assert thin.metadata["direction_rad"] == everything.metadata["direction_rad"]
    assert len(thin.passes) == len(everything.passes)
    for a, b in zip(thin.passes, everything.passes):
        np.testing.assert_array_equal(a.points, b.points)
    # ranked here one after another: the thin direction's cost is never computed
    uniform(surface, Tool(), work_spacing=Tool().pad_radius / 5, cost=counted)
    assert ranked and all(not math.isclose(a, math.radians(60)) for a in ranked)


def test_the_candidate_paths_are_the_plans_their_directions_give():
    surface, tool, paths = blade(), Tool(), {}
    chosen = U.uniform(surface, tool, overlap=0.3, candidate_paths=paths)
    ranked = [c for c in chosen.metadata["candidates"] if c["cost"] is not None]
    assert sorted(round(np.degrees(a)) for a in paths) == sorted(round(c["direction_deg"]) for c in ranked)
    assert len(paths) >= 2
    for angle in sorted(paths)[:2]:
        alone = U.uniform(surface, tool, overlap=0.3, direction=angle)     # the working mesh is reused
        assert len(alone.passes) == len(paths[angle].passes)
        for p, q in zip(alone.passes, paths[angle].passes):
            np.testing.assert_array_equal(p.points, q.points)
        assert paths[angle].metadata["direction_rad"] == pytest.approx(angle)


def test_a_large_cad_part_is_planned_on_a_working_mesh_within_the_budget():
    # crs_part_5: 2.96 m² of long CAD triangles; halved at the spacing its area asks for (4.4 mm) it
    # would have 837,279 vertices, every distance solve paying for them
    from conftest import SHARED_MESH_UNITS, shared_mesh
    from swath.io import load_mesh
    from swath.plan import uniform_model as M

    surface = load_mesh(shared_mesh("crs_part_5.stl"), units=SHARED_MESH_UNITS["crs_part_5.stl"])
    R = Tool().pad_radius
    work, spacing = M.working_mesh(surface, R)
    assert len(work.vertices) <= 1.3 * M.MAX_WORK_VERTICES or spacing == pytest.approx(R / 4)
    assert len(work.vertices) < 200_000                # (169,820 at R/4: a heat-method solve about 0.07 s)
    assert spacing <= R / 4 + 1e-12
    assert work.edge_lengths.max() <= spacing * (1 + 1e-9)
    assert work.area == pytest.approx(surface.area, rel=1e-9)        # the same surface, finer
    # a given spacing is kept, and a small part is not coarsened (the plate: R/12 from its area)
    assert M.working_mesh(surface, R, 0.02)[1] == 0.02
    from swath.examples import flat_plate

    plate = flat_plate(spacing=0.01)
    assert M.working_mesh(plate, R)[1] == pytest.approx(R / 12)
