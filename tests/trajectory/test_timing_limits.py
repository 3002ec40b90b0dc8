"""Speed, acceleration and angular-speed limits of the trajectory stage (issue 5, Amersdorfer & Meurer).

Every limit is checked on the *written* trajectory.csv, read back with ``read_csv`` and resampled
densely in time (positions linearly, orientations by slerp, as a robot controller interpolates):

* speed from the travel between dense samples;
* centripetal acceleration ``v²·κ`` with κ from circles through the written path at ±2 mm (the
  curvature limit reads κ at a 1 mm Gaussian scale; at ±1 mm a three-point circle on a faceted
  mesh reads the facets, several % off the true curvature either way);
* angular speed from the rotation between dense samples;
* tool z against the surface's smooth normal at the closest surface point.
"""

import logging

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from swath.errors import InputError
from swath.examples import blade, doubly_curved_panel, flat_plate, grid_faces
from swath.plan import Pass, ToolPath
from swath.surface import Surface
from swath.trajectory import (
    AngularSpeedLimit,
    CentripetalLimit,
    FeedLimit,
    FeedProfile,
    LinkSettings,
    TangentialAccelLimit,
    read_csv,
    time_path,
)
from swath.trajectory.geometry import (
    curvature_vectors,
    darboux,
    local_quadratic,
    path_curvature,
    resample_uniform,
    shape_tensors,
)
from swath.trajectory.links import clear_link_cache, time_link

TOL = 1.01          # "not above a limit by more than 1 %"


# --- measuring a written trajectory ------------------------------------------------------------

def runs(mask):
    """(start, stop) index pairs of the True runs of a boolean array."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def dense(tr, start, stop, dt=2e-3):
    """Samples ``start:stop`` of ``tr`` resampled every ``dt`` s (plus the written instants)."""
    t = tr.t[start:stop]
    keep = np.concatenate([[True], np.diff(t) > 0])
    t = t[keep]
    extra = np.arange(t[0], t[-1], dt)
    gap = np.abs(extra - t[np.clip(np.searchsorted(t, extra), 0, len(t) - 1)])
    gap = np.minimum(gap, np.abs(extra - t[np.clip(np.searchsorted(t, extra) - 1, 0, len(t) - 1)]))
    td = np.unique(np.concatenate([extra[gap > 1e-6], t]))                  # no slivers of time
    pos = np.stack([np.interp(td, t, tr.position[start:stop][keep][:, k]) for k in range(3)], axis=1)
    q = tr.quaternion[start:stop][keep]
    rot = Slerp(t, Rotation.from_quat(q / np.linalg.norm(q, axis=1, keepdims=True), scalar_first=True))(td)
    return td, pos, rot


def measure(tr, start, stop, d=2e-3):
    """Speed, angular speed (per dense interval) and centripetal acceleration (per dense sample)."""
    td, pos, rot = dense(tr, start, stop)
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    h = np.diff(td)
    speed = step / h
    omega = np.linalg.norm((rot[1:] * rot[:-1].inv()).as_rotvec(), axis=1) / h
    s = np.concatenate([[0.0], np.cumsum(step)])
    ok = (s >= d) & (s <= s[-1] - d)

    def at(q):
        return np.stack([np.interp(q, s, pos[:, k]) for k in range(3)], axis=1)

    a, b, c = at(s[ok] - d), pos[ok], at(s[ok] + d)
    ab, bc, ca = (np.linalg.norm(x, axis=1) for x in (b - a, c - b, a - c))
    kappa = 2 * np.linalg.norm(np.cross(b - a, c - a), axis=1) / np.maximum(ab * bc * ca, 1e-300)
    v_node = np.concatenate([[speed[0]], np.maximum(speed[:-1], speed[1:]), [speed[-1]]])
    return {"t": td, "pos": pos, "rot": rot, "speed": speed, "omega": omega, "kappa": kappa,
            "a_c": v_node[ok] ** 2 * kappa}


def written(tr, tmp_path):
    path = tmp_path / "trajectory.csv"
    tr.write_csv(path)
    return read_csv(path)


def check_contact_contract(tr, surface, *, max_angle_deg=0.5):
    """FORMATS.md on contact: steps ≤ 2 mm and ≤ 20 ms, on the surface, tool z = −normal (dense)."""
    for a, b in runs(tr.contact):
        step = np.linalg.norm(np.diff(tr.position[a:b], axis=0), axis=1)
        assert step.max() <= 2e-3 and np.diff(tr.t[a:b]).max() <= 0.02
        _, pos, rot = dense(tr, a, b)
        closest, dist, face = surface.closest_points(pos)
        assert dist.max() < 1e-4
        n = surface.interpolate_normals(closest, face)
        cosang = -np.einsum("ij,ij->i", rot.apply([0.0, 0.0, 1.0]), n)
        assert np.degrees(np.arccos(np.clip(cosang, -1, 1))).max() < max_angle_deg


def omega_columns(tr):
    return np.stack([tr.extra["wx"], tr.extra["wy"], tr.extra["wz"]], axis=1)


# --- parts and passes ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fine_blade():
    """A short span of the NACA 0012 blade meshed at ≤ 1 mm (0.4 mm at the leading edge)."""
    return blade(span=0.06, max_spacing=1e-3)


def profile_passes(surface, span_indices):
    """Passes round the blade profile at fixed span: rows of the structured (profile × span) grid,
    alternating in direction."""
    n_span = len(np.unique(surface.vertices[:, 1]))
    V = surface.vertices.reshape(-1, n_span, 3)
    N = surface.normals.reshape(-1, n_span, 3)
    out = [Pass(V[:, j].copy(), N[:, j].copy()) for j in span_indices]
    return [p if i % 2 == 0 else p.reversed() for i, p in enumerate(out)]


def naca_max_curvature(chord=0.4, thickness=0.12):
    """Analytic largest curvature of the NACA 00xx profile (at the leading edge), 1/m.

    With ``x = c u²`` the profile is polynomial in ``u``; its derivatives are exact."""
    c, f = chord, 5 * thickness * chord
    u = np.linspace(0.0, 0.3, 300001)
    a = np.array([0.2969, -0.1260, 0.0, -0.3516, 0.0, 0.2843, 0.0, -0.1036])   # coefficients of u^1..u^8
    powers = np.arange(1, 9)
    z1 = f * (a * powers * u[:, None] ** (powers - 1)).sum(1)
    z2 = f * (a * powers * (powers - 1) * u[:, None] ** np.maximum(powers - 2, 0)).sum(1)
    x1, x2 = 2 * c * u, 2 * c
    return float((np.abs(x1 * z2 - z1 * x2) / (x1**2 + z1**2) ** 1.5).max())


# --- the blade: passes round the leading edge ------------------------------------------------------

def test_curvature_estimate_matches_the_leading_edge(fine_blade):
    (p,) = profile_passes(fine_blade, [20])
    s, pts = resample_uniform(p.points, 2e-4)
    kappa = path_curvature(pts, s[1] - s[0], 1e-3)
    true = naca_max_curvature()
    assert true == pytest.approx(2 / (0.6 * 0.2969) ** 2 / 0.4, rel=0.01)    # 1 / r_LE, r_LE = 6.35 mm
    assert kappa.max() == pytest.approx(true, rel=0.01)


def test_blade_centripetal_limit_on_written_csv(fine_blade, tmp_path):
    feed, a_c, a_t = 0.2, 2.0, 1.0
    tp = ToolPath(fine_blade, profile_passes(fine_blade, [15, 45]), "test")
    tr = written(time_path(tp, [FeedLimit(feed), CentripetalLimit(a_c), TangentialAccelLimit(a_t)]), tmp_path)
    check_contact_contract(tr, fine_blade)
    for a, b in runs(tr.contact):
        m = measure(tr, a, b)
        assert m["speed"].max() <= feed * TOL
        assert m["a_c"].max() <= a_c * TOL
        assert m["a_c"].max() >= 0.95 * a_c                     # the limit binds at the leading edge
        # slowed there to about sqrt(a_c / κ_LE) = 0.11 m/s, at the feed elsewhere
        le = np.argmin(np.abs(m["pos"][:, 0]))
        assert m["speed"][min(le, len(m["speed"]) - 1)] == pytest.approx(np.sqrt(a_c / naca_max_curvature()), rel=0.03)
        assert np.quantile(m["speed"], 0.5) == pytest.approx(feed, rel=1e-3)
        # tangential acceleration: speed over windows of 8 written samples (≥ 1.6 mm, so that the
        # CSV's rounding of positions to 0.1 µm does not dominate), and its change per window
        t, p = tr.t[a:b:8], tr.position[a:b:8]
        v = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
        acc = np.diff(v) / (0.5 * (np.diff(t)[1:] + np.diff(t)[:-1]))
        assert np.abs(acc).max() <= a_t * TOL
        assert np.abs(acc).max() >= 0.9 * a_t
        assert tr.feed[a] == 0 and tr.feed[b - 1] == 0          # from rest, to rest


def test_blade_angular_speed_limit_on_written_csv(fine_blade, tmp_path):
    feed, w_max = 0.05, 1.0
    tp = ToolPath(fine_blade, profile_passes(fine_blade, [15, 45]), "test")
    cons = [FeedLimit(feed), CentripetalLimit(2.0), AngularSpeedLimit(w_max), TangentialAccelLimit(1.0)]
    tr = written(time_path(tp, cons), tmp_path)
    check_contact_contract(tr, fine_blade)
    whole = measure(tr, 0, len(tr))                        # contact, links, approach and retract
    assert whole["omega"].max() <= w_max * TOL
    assert np.linalg.norm(omega_columns(tr), axis=1).max() <= w_max * TOL
    for a, b in runs(tr.contact):
        m = measure(tr, a, b)
        assert m["speed"].max() <= feed * TOL and m["a_c"].max() <= 2.0 * TOL
        assert m["omega"].max() >= 0.98 * w_max               # binds at the leading edge ...
        le = np.argmin(np.abs(m["pos"][:, 0]))
        # ... where the frame turns at about κ_LE rad/m, so v ≈ ω_max / κ_LE = 6.3 mm/s (a few % less:
        # the mesh's smoothed normals turn a little unevenly from facet to facet)
        v_le = m["speed"][min(le, len(m["speed"]) - 1)]
        assert 0.9 * w_max / naca_max_curvature() <= v_le <= w_max / naca_max_curvature() * TOL
    # the written angular velocity is the written speed times the rotation per metre of the written
    # quaternions (R[i+1] = exp([r_i]×) R[i]; the mean of both neighbouring steps at a sample)
    for a, b in runs(tr.contact):
        rot = Rotation.from_quat(tr.quaternion[a:b], scalar_first=True)
        per_m = (rot[1:] * rot[:-1].inv()).as_rotvec() / np.linalg.norm(np.diff(tr.position[a:b], axis=0), axis=1)[:, None]
        node = 0.5 * (per_m[1:] + per_m[:-1])
        w = omega_columns(tr)[a + 1:b - 1]
        err = np.linalg.norm(w - tr.feed[a + 1:b - 1, None] * node, axis=1)
        assert err.max() <= 0.005 * w_max


def test_limits_cost_cycle_time_only_where_they_bind(fine_blade):
    tp = ToolPath(fine_blade, profile_passes(fine_blade, [30]), "test")
    free = time_path(tp, [FeedLimit(0.05)])
    slow = time_path(tp, [FeedLimit(0.05), AngularSpeedLimit(1.0)])
    L = tp.contact_length

    def contact(tr):
        return np.diff(tr.t)[tr.contact[1:] & tr.contact[:-1]].sum()

    def turned(tr):
        rot = Rotation.from_quat(tr.quaternion[tr.contact], scalar_first=True)
        return np.linalg.norm((rot[1:] * rot[:-1].inv()).as_rotvec(), axis=1).sum()

    assert contact(free) == pytest.approx(L / 0.05, rel=0.01)
    # the tool turns by more than π from the lower surface round the leading edge: at ω_max = 1 rad/s
    # that takes at least turned / ω_max, most of it at the leading edge
    assert turned(slow) > np.pi
    assert contact(slow) >= turned(slow) / 1.0 * 0.999
    assert contact(free) + 1.0 < contact(slow) < 2 * contact(free)


# --- analytic cases ----------------------------------------------------------------------------

def circle_pass(surface, r, centre=(0.2, 0.15), arc=(0.2, 2.8)):
    th = np.linspace(*arc, 400)
    p = np.stack([centre[0] + r * np.cos(th), centre[1] + r * np.sin(th), np.zeros_like(th)], axis=1)
    return Pass(p, np.tile([0.0, 0.0, 1.0], (len(p), 1)))


def test_circle_on_plate_centripetal_and_angular_caps():
    plate = flat_plate()
    r = 0.1
    tp = ToolPath(plate, [circle_pass(plate, r)], "test")
    tr = time_path(tp, [FeedLimit(0.1), CentripetalLimit(0.02)])
    mid = tr.contact & (np.abs(np.arctan2(tr.position[:, 1] - 0.15, tr.position[:, 0] - 0.2) - 1.5) < 1.0)
    assert np.allclose(tr.feed[mid], np.sqrt(0.02 * r), rtol=0.005)         # v = sqrt(a r)
    tr = time_path(tp, [FeedLimit(0.1), AngularSpeedLimit(0.2)])
    mid = tr.contact & (np.abs(np.arctan2(tr.position[:, 1] - 0.15, tr.position[:, 0] - 0.2) - 1.5) < 1.0)
    # on a plane the tool turns about its axis at 1/r rad/m: v = ω_max r
    assert np.allclose(tr.feed[mid], 0.2 * r, rtol=0.005)
    w = omega_columns(tr)[mid]
    assert np.allclose(w[:, :2], 0, atol=1e-9) and np.allclose(w[:, 2], 0.2, rtol=0.005)


def test_tangential_limit_gives_the_rest_to_rest_time():
    plate = flat_plate()
    p = Pass(np.array([[0.05, 0.1, 0.0], [0.35, 0.1, 0.0]]), np.tile([0.0, 0, 1], (2, 1)))
    tp = ToolPath(plate, [p], "test")
    feed, a_t, L = 0.05, 0.02, 0.3
    tr = time_path(tp, [FeedLimit(feed), TangentialAccelLimit(a_t)])
    contact = np.diff(tr.t)[tr.contact[1:] & tr.contact[:-1]].sum()
    assert contact == pytest.approx(L / feed + feed / a_t, rel=2e-3)           # trapezoid, rest to rest
    v = tr.feed[tr.contact]
    s = tr.position[tr.contact, 0] - 0.05
    ramp = s < 0.95 * feed**2 / (2 * a_t)
    assert np.allclose(v[ramp], np.sqrt(2 * a_t * s[ramp]), rtol=1e-6, atol=1e-9)
    tr = time_path(tp, [FeedLimit(feed), TangentialAccelLimit(a_t, rest_at_ends=False)])
    assert np.diff(tr.t)[tr.contact[1:] & tr.contact[:-1]].sum() == pytest.approx(L / feed, rel=1e-6)


def test_feed_profile_caps_the_speed_pointwise():
    plate = flat_plate()
    p = Pass(np.array([[0.05, 0.1, 0.0], [0.2, 0.1, 0.0], [0.35, 0.1, 0.0]]), np.tile([0.0, 0, 1], (3, 1)))
    tp = ToolPath(plate, [p], "test")
    tr = time_path(tp, [FeedLimit(0.05), FeedProfile([[0.02, 0.08, 0.04]])])
    x, v = tr.position[tr.contact, 0], tr.feed[tr.contact]
    expect = np.minimum(0.05, np.interp(x, [0.05, 0.2, 0.35], [0.02, 0.08, 0.04]))
    # at the grid points exactly; in between v² is linear in s, so allow the profile's change over
    # one grid step (slope 0.4 /s × 1 mm)
    assert np.allclose(v, expect, rtol=0, atol=0.4 * 1e-3)
    assert np.abs(v - expect).mean() < 2e-5
    p, t = tr.position[tr.contact], tr.t[tr.contact]
    measured = np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(t)
    assert np.all(measured <= np.maximum(expect[1:], expect[:-1]) * (1 + 1e-9))
    with pytest.raises(InputError, match="one speed per pass point"):
        time_path(tp, [FeedLimit(0.05), FeedProfile([[0.02, 0.03]])])
    with pytest.raises(InputError, match="one array of speeds per pass"):
        time_path(tp, [FeedLimit(0.05), FeedProfile([[0.02, 0.03, 0.04], [0.1, 0.1]])])
    with pytest.raises(InputError, match="positive"):
        FeedProfile([[0.02, 0.0, 0.04]])


def test_noisy_scan_does_not_slow_the_tool_absurdly():
    rng = np.random.default_rng(7)
    xs, ys = np.linspace(0, 0.2, 201), np.linspace(0, 0.04, 41)         # 1 mm grid
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = rng.normal(0.0, 50e-6, X.shape)                                    # 50 µm scan noise
    scan = Surface(np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1), grid_faces(len(xs), len(ys)))
    ends, _, face = scan.closest_points(np.array([[0.01, 0.02, 0.0], [0.19, 0.02, 0.0]]))
    tp = ToolPath(scan, [Pass(ends, scan.interpolate_normals(ends, face))], "test")
    feed = 0.2                                    # a_c = 2 m/s² binds from κ = 50 /m (20 mm radius)
    free = time_path(tp, [FeedLimit(feed)]).duration
    for scale, slower in ((1e-3, 0.03), (2e-3, 0.005)):
        tr = time_path(tp, [FeedLimit(feed), CentripetalLimit(2.0, scale=scale)])
        assert tr.duration <= free * (1 + slower)
        assert tr.feed[tr.contact].min() >= 0.5 * feed
    # the raw polyline (no smoothing scale) would read the noise as curvature of hundreds per metre
    tr = time_path(tp, [FeedLimit(feed)])
    p = tr.position[tr.contact]
    raw = np.linalg.norm(np.diff(p, 2, axis=0), axis=1) / np.linalg.norm(np.diff(p, axis=0), axis=1)[1:] ** 2
    assert np.quantile(raw, 0.99) > 100


# --- Darboux frame against the discrete frame derivative ---------------------------------------------

def cylinder(radius=0.1, half_angle=0.7, length=0.25, spacing=1.5e-3):
    """Cylinder patch about the y-axis, normals outward (+z at φ = 0)."""
    phi = np.linspace(-half_angle, half_angle, int(np.ceil(2 * half_angle * radius / spacing)) + 1)
    y = np.linspace(0, length, int(np.ceil(length / spacing)) + 1)
    P, Y = np.meshgrid(phi, y, indexing="ij")
    v = np.stack([radius * np.sin(P).ravel(), Y.ravel(), radius * np.cos(P).ravel()], axis=1)
    return Surface(v, grid_faces(len(phi), len(y)), name="cylinder")


def test_discrete_angular_velocity_matches_darboux_on_a_helix():
    R, alpha, feed = 0.1, np.deg2rad(35.0), 0.05
    cyl = cylinder(R)
    assert cyl.face_normals[0, 2] > 0                       # outward, toward the tool
    s = np.linspace(0, 0.14, 300)
    phi, y = -0.55 + s * np.cos(alpha) / R, 0.05 + s * np.sin(alpha)
    pts = np.stack([R * np.sin(phi), y, R * np.cos(phi)], axis=1)
    nrm = np.stack([np.sin(phi), np.zeros_like(phi), np.cos(phi)], axis=1)
    tr = time_path(ToolPath(cyl, [Pass(pts, nrm)], "test"), [FeedLimit(feed)])
    c = tr.contact
    P, w = tr.position[c], omega_columns(tr)[c] / feed               # rad/m, discrete derivative
    ph = np.arctan2(P[:, 0], P[:, 2])
    # exact Darboux vector of the helix: κ_g = 0, κ_n = −cos²α/R, τ_g = sinα cosα/R
    T = np.stack([np.cos(ph) * np.cos(alpha), np.full_like(ph, np.sin(alpha)), -np.sin(ph) * np.cos(alpha)], 1)
    n = np.stack([np.sin(ph), np.zeros_like(ph), np.cos(ph)], axis=1)
    B = np.cross(n, T)
    D = (np.sin(alpha) * np.cos(alpha) / R) * T + (np.cos(alpha) ** 2 / R) * B
    assert np.linalg.norm(D, axis=1) == pytest.approx(np.cos(alpha) / R)
    inner = (np.arange(len(P)) > 0.15 * len(P)) & (np.arange(len(P)) < 0.85 * len(P))
    err = np.linalg.norm(w - D, axis=1)[inner] / (np.cos(alpha) / R)
    assert err.max() < 0.01
    # the Darboux formulas evaluated from the mesh (shape tensors of the quadric fit, curvature of the
    # sampled path) agree with the discrete frame derivative
    sg, pg, ng = resample_uniform(P, 1e-3, n)
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    t_, k_ = curvature_vectors(pg, sg[1] - sg[0], 1e-3)
    closest, _, face = cyl.closest_points(pg)
    Dm, kg, kn, tg = darboux(t_, ng, k_, shape_tensors(cyl, closest, face, ng))
    core = slice(len(pg) // 6, -len(pg) // 6)
    assert np.abs(kg[core]).max() < 0.05 / R
    assert np.allclose(kn[core], -np.cos(alpha) ** 2 / R, rtol=0.03)
    assert np.allclose(tg[core], np.sin(alpha) * np.cos(alpha) / R, rtol=0.03)
    w_at = np.stack([np.interp(sg, np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]),
                               w[:, k]) for k in range(3)], axis=1)
    assert np.linalg.norm(Dm - w_at, axis=1)[core].max() < 0.03 * np.cos(alpha) / R


# --- the doubly curved panel: a zig-zag ---------------------------------------------------------------

@pytest.fixture(scope="module")
def panel():
    return doubly_curved_panel()


def panel_rows(panel, rows, *, x_range=(25, -25)):
    xs = np.unique(panel.vertices[:, 0])
    ny = len(np.unique(panel.vertices[:, 1]))
    V, N = panel.vertices.reshape(len(xs), ny, 3), panel.normals.reshape(len(xs), ny, 3)
    a, b = x_range
    return V, N, [(V[a:b, j], N[a:b, j]) for j in rows]


def test_panel_zigzag_with_air_links(panel, tmp_path):
    _, _, rows = panel_rows(panel, [20, 35, 50, 65])
    passes = [Pass(p, n) if i % 2 == 0 else Pass(p, n).reversed() for i, (p, n) in enumerate(rows)]
    links = LinkSettings(clearance=0.02, speed=0.25, acceleration=1.0)
    cons = [FeedLimit(0.05), CentripetalLimit(2.0), AngularSpeedLimit(1.0), TangentialAccelLimit(1.0)]
    tr = written(time_path(ToolPath(panel, passes, "zigzag"), cons, links=links), tmp_path)
    assert len(runs(tr.contact)) == 4
    check_contact_contract(tr, panel)
    m = measure(tr, 0, len(tr))
    assert m["omega"].max() <= 1.0 * TOL
    # each link turns the tool by π about its axis: at ω_max it takes at least π s
    for a, b in runs(~tr.contact)[1:-1]:
        assert tr.t[b] - tr.t[a - 1] >= np.pi
        seg = measure(tr, a - 1, b + 1)
        assert seg["speed"].max() <= 0.25 * TOL
    for a, b in runs(tr.contact):
        assert measure(tr, a, b)["speed"].max() <= 0.05 * TOL


def test_zigzag_corner_in_contact_turns_the_tool_gradually(panel):
    V, N, _ = panel_rows(panel, [])
    # one continuous pass: along row 30, 30 mm along the column, back along row 37.5 mm later
    a, b = 25, -26
    leg1 = V[a:b, 30]
    step = V[b, 30:39][1:]
    leg2 = V[a:b, 38][::-1][1:]
    pts = np.vstack([leg1, step, leg2])
    nrm = np.vstack([N[a:b, 30], N[b, 30:39][1:], N[a:b, 38][::-1][1:]])
    tp = ToolPath(panel, [Pass(pts, nrm)], "zigzag")
    free = time_path(tp, [FeedLimit(0.05)])
    c = free.contact
    x = free.tool_x()[c]
    heading = np.degrees(np.arctan2(x[:, 1], x[:, 0]))
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(free.position[c], axis=0), axis=1))])
    corner1 = np.linalg.norm(leg1[:, :2] - leg1[0, :2], axis=1).max()
    # the heading goes 0° → 90° → 180° ...
    assert abs(heading[0]) < 1 and abs(heading[len(s) // 2] - 90) < 1 and abs(abs(heading[-1]) - 180) < 1
    # ... and turns over several millimetres at each corner, not on the spot
    turning = (heading > 10) & (heading < 80) & (s < corner1 + 15e-3)
    assert s[turning].max() - s[turning].min() > 8e-3
    w = np.linalg.norm(omega_columns(free)[c], axis=1)
    # averaging unit directions over a Gaussian of σ = 5 mm turns the heading at most at 2/(σ√(2π)) rad/m
    assert 0.9 < w.max() / (0.05 * 2 / (5e-3 * np.sqrt(2 * np.pi))) < 1.15
    # with the angular speed limit the tool slows into each corner instead
    lim = time_path(tp, [FeedLimit(0.05), AngularSpeedLimit(1.0)])
    assert np.linalg.norm(omega_columns(lim), axis=1).max() <= 1.0 * TOL
    assert lim.feed[lim.contact].min() < 0.5 * 0.05


# --- links ----------------------------------------------------------------------------------------------

def test_link_timing_respects_speed_and_acceleration():
    from swath.trajectory.links import _times_from_squared_speeds  # noqa: F401 (documented helper)

    route = np.array([[0.0, 0, 0], [0.0, 0, 0.02], [0.15, 0.0, 0.02], [0.15, 0.0, 0.0]])
    q = np.array([1.0, 0, 0, 0])
    ls = LinkSettings(speed=0.25, acceleration=1.0, step=1e-3)
    lp = time_link(route, q, q, ls)
    assert lp.method == "toppra"
    p = lp.position
    assert np.allclose(p[0], route[0]) and np.allclose(p[-1], route[-1])
    # sampled every 0.1 mm along the rounded route: finite differences give speed and acceleration
    fine = time_link(route, q, q, LinkSettings(speed=0.25, acceleration=1.0, step=1e-4))
    dt = np.diff(fine.t)
    vel = np.diff(fine.position, axis=0) / dt[:, None]
    acc = np.diff(vel, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None]
    assert np.linalg.norm(vel, axis=1).max() <= 0.25 * TOL
    assert np.linalg.norm(acc, axis=1).max() <= 1.0 * TOL
    assert np.linalg.norm(acc, axis=1).max() >= 0.95                   # time-optimal: it uses the limit
    assert fine.duration == pytest.approx(lp.duration, rel=0.01)
    # no slower than necessary: within 40 % of the straight-line rest-to-rest bound over the same length
    L = np.linalg.norm(np.diff(p, axis=0), axis=1).sum()
    assert lp.duration < 1.4 * (L / 0.25 + 0.25 / 1.0)


def test_link_falls_back_to_trapezoid_with_a_warning(monkeypatch, caplog):
    import toppra.algorithm

    def broken(*args, **kwargs):
        raise ValueError("degenerate")

    monkeypatch.setattr(toppra.algorithm, "TOPPRA", broken)
    clear_link_cache()                  # a link timed earlier with toppra would be handed back
    route = np.array([[0.0, 0, 0], [0.0, 0, 0.02], [0.1, 0.0, 0.02], [0.1, 0.0, 0.0]])
    q = np.array([1.0, 0, 0, 0])
    with caplog.at_level(logging.WARNING, logger="swath.trajectory.links"):
        lp = time_link(route, q, q, LinkSettings())
    assert lp.method == "trapezoid"
    assert any("toppra failed" in r.message for r in caplog.records)
    L = 0.14
    assert lp.duration == pytest.approx(L / 0.25 + 0.25 / 1.0)
    assert np.all(np.diff(lp.t) >= 0)
    clear_link_cache()                  # nor may this one be handed to a later test


# --- validation ---------------------------------------------------------------------------------------

def test_constraints_are_validated():
    plate = flat_plate()
    tp = ToolPath(plate, [Pass(np.array([[0.1, 0.1, 0], [0.2, 0.1, 0]]), np.tile([0.0, 0, 1], (2, 1)))], "t")
    for bad in (lambda: CentripetalLimit(-1.0), lambda: CentripetalLimit(1.0, scale=0),
                lambda: AngularSpeedLimit(float("nan")), lambda: TangentialAccelLimit(0.0)):
        with pytest.raises(InputError, match="must be a positive"):
            bad()
    with pytest.raises(InputError, match="two AngularSpeedLimit"):
        time_path(tp, [FeedLimit(0.05), AngularSpeedLimit(1.0), AngularSpeedLimit(2.0)])
    with pytest.raises(InputError, match="needs exactly one FeedLimit"):
        time_path(tp, [AngularSpeedLimit(1.0)])
    with pytest.raises(InputError, match="does not know the constraint"):
        time_path(tp, [FeedLimit(0.05), "fast"])


# --- building blocks ------------------------------------------------------------------------------

def test_speed_profile_matches_a_sequential_sweep(rng):
    from swath.trajectory.timing import speed_profile

    s = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 400))
    caps = rng.uniform(0.01, 0.08, 400)
    a = 0.3
    w = caps**2
    w[0] = w[-1] = 0.0
    for i in range(1, len(w)):                          # forward: accelerate at most a
        w[i] = min(w[i], w[i - 1] + 2 * a * (s[i] - s[i - 1]))
    for i in range(len(w) - 2, -1, -1):                 # backward: decelerate at most a
        w[i] = min(w[i], w[i + 1] + 2 * a * (s[i + 1] - s[i]))
    assert np.allclose(speed_profile(caps, s, a), np.sqrt(w), rtol=1e-12, atol=1e-12)
    assert np.array_equal(speed_profile(caps, s, None), caps)


def test_curvature_of_a_circle_clean_and_noisy(rng):
    r = 0.05
    th = np.linspace(0, 2.0, 2000)
    circle = np.stack([r * np.cos(th), r * np.sin(th), np.zeros_like(th)], axis=1)
    s, pts = resample_uniform(circle, 5e-4)
    h = s[1] - s[0]
    assert np.allclose(path_curvature(pts, h, 1e-3)[10:-10] * r, 1.0, rtol=1e-3)
    _, d1, d2 = local_quadratic(pts, h, 1e-3)
    assert np.allclose(np.linalg.norm(d1, axis=1), 1.0, atol=1e-3)         # unit speed in arc length
    noisy = pts + rng.normal(0.0, 20e-6, pts.shape)                          # 20 µm noise
    k2 = path_curvature(noisy, h, 2e-3) * r
    assert abs(np.median(k2) - 1.0) < 0.05 and k2.max() < 1.5
    k_raw = np.linalg.norm(np.diff(noisy, 2, axis=0), axis=1) / h**2 * r       # unsmoothed: noise dominates
    assert np.median(k_raw) > 3
