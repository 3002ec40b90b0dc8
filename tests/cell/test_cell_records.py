"""The cell records: frames (pytransform3d A2B), transform validation, bodies, the cell file."""

import math

import numpy as np
import pytest

from swath.cell import (
    Body,
    Box,
    Capsule,
    Cell,
    CollisionScene,
    Cylinder,
    Mesh,
    MovingBody,
    check_transform,
    default_sander,
    default_table,
    format_pose,
    parse_pose,
    read_cell_file,
)
from swath.errors import InputError


def test_part2base_maps_part_points_to_base_points():
    """A2B: p_base = part2base @ p_part.  The part 1 m ahead, turned 90 deg about z: its x axis
    points along the base's y, so the part point (0.1, 0, 0) is the base point (1, 0.1, 0)."""
    cell = Cell.from_text("1,0,0,0,0,90deg")
    np.testing.assert_allclose(cell.part2base @ [0.1, 0, 0, 1], [1.0, 0.1, 0, 1], atol=1e-12)
    np.testing.assert_allclose(cell.base2part @ [1.0, 0.1, 0, 1], [0.1, 0, 0, 1], atol=1e-12)


def test_flange_pose_composes_by_frame_names():
    """flange2base = part2base @ tcp2part @ flange2tcp: the TCP origin 150 mm along the flange z
    sits on the target, and tcp2part inverts flange2base."""
    cell = Cell.from_text("0.8,0.1,-0.2,0,0,30", "0,0,150mm,0,0,0")
    tcp2part = parse_pose("0.1,0.2,0,180,0,0")[None]
    flange2base = cell.flange2base(tcp2part)
    tcp_in_base = flange2base[0] @ cell.tcp2flange @ [0, 0, 0, 1]
    np.testing.assert_allclose(tcp_in_base, cell.part2base @ [0.1, 0.2, 0, 1], atol=1e-12)
    # the flange is 150 mm back from the TCP along the tool z; the tool z points down (rx = 180 deg)
    np.testing.assert_allclose(flange2base[0][:3, 3] - tcp_in_base[:3], 0.15 * -(cell.part2base[:3, :3] @ [0, 0, -1]),
                               atol=1e-12)
    np.testing.assert_allclose(cell.tcp2part(flange2base), tcp2part, atol=1e-12)


def test_pose_text_round_trips():
    t = parse_pose("12.5mm,-300mm,1.2,10deg,-20deg,170deg")
    np.testing.assert_allclose(parse_pose(format_pose(t)), t, atol=1e-9)


@pytest.mark.parametrize("bad, says", [
    (np.eye(3), "shape (3, 3)"),
    (np.diag([2.0, 1, 1, 1]), "not a rotation"),
    (np.diag([1.0, 1, -1, 1]), "not a rotation"),                  # a mirror, det -1
    ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]], "last row"),
    ([[1, 0, 0, float("nan")], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "non-finite"),
])
def test_transforms_are_validated_on_input(bad, says):
    with pytest.raises(InputError, match=r"expected a \(4, 4\) rigid transform, got") as err:
        check_transform(bad, name="part2base")
    assert says in str(err.value) and "part2base" in str(err.value)
    with pytest.raises(InputError, match="rigid transform"):
        Cell(part2base=np.asarray(bad, dtype=float) if np.shape(bad) == (4, 4) else bad)


def test_default_sander_dimensions():
    """The stated 3-inch sander: holder Ø90x50 mm on the flange, spindle Ø70x95 mm below it, 30 mm
    of pad stack, so the TCP is 175 mm out along the flange z."""
    tool = default_sander()
    np.testing.assert_allclose(tool.tcp2flange[:3, 3], [0, 0, 0.175])
    holder, spindle = tool.bodies
    assert (holder.shape.radius, holder.shape.length) == (0.045, 0.05)
    assert (spindle.shape.radius, spindle.shape.length) == (0.035, 0.095)
    lo, hi = spindle.aabb()
    assert hi[2] <= 0.145 + 1e-9 + spindle.shape.radius     # cover spheres: a loose but bounded box
    assert 0.175 - (spindle.body2frame[2, 3] + spindle.shape.length / 2) == pytest.approx(0.03)


def test_default_table_top_is_the_lowest_point_under_the_reach():
    v = np.array([[1.0, 0, -0.3], [1.2, 0.1, -0.1]])
    table = default_table(v, 1.3)
    assert table.top_z == -0.3 and table.assumed
    assert table.size_xy == (3.0, 3.0)
    box = table.body()
    lo, hi = box.aabb()
    assert hi[2] == pytest.approx(-0.3, abs=1e-12) or hi[2] >= -0.3    # cover spheres bound the box from outside


def test_cover_spheres_contain_the_shapes(rng):
    """Culling is only safe if the covering spheres contain every point of the body."""
    shapes = [Box((0.3, 0.05, 0.1)), Cylinder(0.035, 0.095), Capsule(0.06, 0.6)]
    for shape in shapes:
        centres, radii = shape.cover()
        if isinstance(shape, Box):
            p = (rng.random((4000, 3)) - 0.5) * shape.size
        else:
            ang = rng.random(4000) * 2 * math.pi
            r = shape.radius * np.sqrt(rng.random(4000))
            z = (rng.random(4000) - 0.5) * shape.length
            p = np.column_stack([r * np.cos(ang), r * np.sin(ang), z])
        d = np.linalg.norm(p[:, None] - centres[None], axis=2) - radii
        assert np.all(d.min(axis=1) <= 1e-12), type(shape).__name__


def test_culled_check_finds_what_coal_finds_everywhere(rng):
    """A capsule on a moving frame against a box, a cylinder and a mesh at random poses: the culled
    scene reports exactly the poses where coal, asked about every pose, finds a collision."""
    import coal
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    static = [Body("box", Box((0.2, 0.3, 0.1)), parse_pose("0.5,0,0,0,0,30")),
              Body("cyl", Cylinder(0.05, 0.4), parse_pose("0,0.5,0,90,0,0")),
              Body("ball", Mesh(sphere.vertices, sphere.faces), parse_pose("-0.5,0,0,0,0,0"))]
    moving = [MovingBody(Body("rod", Capsule(0.03, 0.25)), link=0)]
    scene = CollisionScene(static, moving)
    n = 600
    frames = np.tile(np.eye(4), (n, 1, 1, 1))
    angles = rng.uniform(-math.pi, math.pi, (n, 3))
    for k in range(n):
        frames[k, 0] = parse_pose([*rng.uniform(-0.8, 0.8, 3), *np.degrees(angles[k])])
    hits = scene.check(frames)
    want = set()
    for k in range(n):
        ta = coal.Transform3s(frames[k, 0, :3, :3].copy(), frames[k, 0, :3, 3].copy())
        for b in static:
            res = coal.CollisionResult()
            if coal.collide(moving[0].body.shape.coal(), ta, b.shape.coal(),
                            coal.Transform3s(b.body2frame[:3, :3].copy(), b.body2frame[:3, 3].copy()),
                            coal.CollisionRequest(), res):
                want.add((k, b.name))
    got = {(int(k), b) for k, b in zip(hits.pose, hits.body_b)}
    assert got == want
    assert len(want) > 20                                # the test poses do collide
    assert hits.n_queries < 3 * n                        # and culling skipped most of the pairs


CELL_TOML = """
robot = "ur10e"
part2base = "900mm,0,-200mm,0,0,90deg"

[tool]
tcp2flange = "0,0,160mm,0,0,0"
[[tool.body]]
name = "spindle"
shape = "cylinder"
radius = "35mm"
length = "120mm"
pose = "0,0,60mm,0,0,0"

[table]
top_z = "-200mm"
centre = ["900mm", "0"]
size = ["1.2", "0.8"]

[[fixture]]
name = "clamp"
shape = "box"
size = ["100mm", "60mm", "80mm"]
pose = "1.1,0.25,-160mm,0,0,0"

[[fixture]]
name = "post"
shape = "mesh"
file = "post.stl"
units = "mm"
pose = [[1, 0, 0, 0.7], [0, 1, 0, 0], [0, 0, 1, -0.2], [0, 0, 0, 1]]
"""


def test_cell_file_reads_every_part(tmp_path):
    import trimesh

    trimesh.creation.box((40, 40, 300)).export(tmp_path / "post.stl")
    (tmp_path / "cell.toml").write_text(CELL_TOML)
    cell = read_cell_file(tmp_path / "cell.toml")
    assert cell.robot == "ur10e"
    np.testing.assert_allclose(cell.part2base @ [0.1, 0, 0, 1], [0.9, 0.1, -0.2, 1], atol=1e-12)
    np.testing.assert_allclose(cell.tcp2flange[:3, 3], [0, 0, 0.16])
    assert [b.name for b in cell.tool.bodies] == ["tool spindle"]
    assert cell.tool.bodies[0].shape.length == pytest.approx(0.12)
    assert cell.table.top_z == pytest.approx(-0.2) and cell.table.size_xy == (1.2, 0.8) and not cell.table.assumed
    clamp, post = cell.fixtures
    assert clamp.name == "fixture clamp" and clamp.shape.size == pytest.approx((0.1, 0.06, 0.08))
    lo, hi = post.aabb()                                  # the STL is in mm: 40 x 40 x 300 mm at (0.7, 0, -0.2)
    np.testing.assert_allclose(lo, [0.68, -0.02, -0.35], atol=1e-9)
    np.testing.assert_allclose(hi, [0.72, 0.02, -0.05], atol=1e-9)


@pytest.mark.parametrize("text, says", [
    ("robots = 'ur10e'", "unknown key"),
    ("part2base = '1,2,3'", "six values"),
    ("part2base = [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]", "expected a (4, 4) rigid transform"),
    ("[[fixture]]\nshape = 'sphere'", "box, cylinder, capsule or mesh"),
    ("[[fixture]]\nshape = 'box'\nsize = ['1', '2']", "three lengths"),
    ("[[fixture]]\nshape = 'cylinder'\nradius = '-5mm'\nlength = 1", "positive length"),
    ("[[fixture]]\nshape = 'mesh'\nfile = 'missing.stl'", "not found"),
    ("[table]\ncentre = [0, 0]", "top_z"),
])
def test_cell_file_refuses_bad_input(tmp_path, text, says):
    (tmp_path / "cell.toml").write_text(text)
    with pytest.raises(InputError) as err:
        read_cell_file(tmp_path / "cell.toml")
    assert says in str(err.value)


def test_cell_file_table_false_means_no_table(tmp_path):
    (tmp_path / "cell.toml").write_text("table = false\n")
    cell = read_cell_file(tmp_path / "cell.toml")
    assert cell.table is None and not cell.auto_table
    (tmp_path / "cell2.toml").write_text("robot = 'irb4600'\n")
    cell = read_cell_file(tmp_path / "cell2.toml")
    assert cell.table is None and cell.auto_table and cell.tool is None


def test_surface_points_bound_every_point_of_the_mesh(rng):
    """Culling a mesh by sampled points is safe only if every point of every triangle lies within
    the stated bound of a sampled point: checked on random points of long, thin and obtuse triangles."""
    from scipy.spatial import cKDTree

    from swath.cell.collide import surface_points

    v = np.array([[0, 0, 0], [1.0, 0, 0], [0.5, 0.02, 0], [0, 0.3, 0.1], [0.05, 0.05, 0.4]])
    f = np.array([[0, 1, 2], [0, 1, 3], [0, 3, 4], [1, 3, 4]])
    pts, bound = surface_points(v, f, spacing=0.01)
    assert bound <= 0.01 / np.sqrt(3) * (1 + 1e-6)
    w = rng.dirichlet(np.ones(3), size=20000)
    tri = v[f[rng.integers(0, len(f), 20000)]]
    sample = np.einsum("nk,nkd->nd", w, tri)
    d, _ = cKDTree(pts).query(sample)
    assert d.max() <= bound


def test_a_job_file_reads_its_cell_file_beside_it(tmp_path):
    """`cell = "cell.toml"` in a job file is read from the job file's folder, and a bad cell file is
    refused when the settings are checked, before any work."""
    from swath.cli.settings import check_settings, load_job_toml
    from swath.cli.stages import job_cell

    (tmp_path / "cell.toml").write_text('robot = "irb4600"\npart2base = "1.2,0,-0.3,0,0,0"\ntable = false\n')
    (tmp_path / "job.toml").write_text('[job]\npart = "example:plate"\nout = "out"\ncell = "cell.toml"\n'
                                       'allow_collisions = true\n')
    settings = load_job_toml(tmp_path / "job.toml")
    assert settings.cell == str(tmp_path / "cell.toml") and settings.allow_collisions
    check_settings(settings)
    cell = job_cell(settings)
    np.testing.assert_allclose(cell.part2base[:3, 3], [1.2, 0, -0.3])
    assert cell.tool is not None and cell.tool.tcp2flange[2, 3] == pytest.approx(0.175)   # the default sander
    assert any("3-inch random-orbital sander" in n for n in cell.notes)
    (tmp_path / "cell.toml").write_text('part2base = "1.2,0,-0.3,0,0"\n')
    with pytest.raises(InputError, match="six values"):
        check_settings(load_job_toml(tmp_path / "job.toml"))
