"""The order stage's link costs against what the trajectory stage really flies and times."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay
from scipy.spatial.transform import Rotation

from swath.core import Pass, ToolPath
from swath.order import order_toolpath
from swath.order.variants import LinkModel, link_time_estimate
from swath.surface import Surface
from swath.trajectory.links import LinkSettings, time_link


@pytest.mark.parametrize("mid", [0.005, 0.02, 0.05, 0.1, 0.3, 1.0])
def test_link_time_estimate_matches_the_timed_link(mid):
    """Retract 20 mm, ``mid`` across, approach; the tool turns 0..3.1 rad about its axis: the
    closed form is within 30 ms of toppra on the rounded route (the old max(trapezoid, turn/omega)
    was up to 0.4 s short)."""
    route = np.array([[0, 0, 0], [0, 0, 0.02], [mid, 0, 0.02], [mid, 0, 0]])
    q0 = np.array([1.0, 0, 0, 0])
    for turn in (0.0, 0.5, 1.5, 3.1):
        q1 = Rotation.from_rotvec([0, 0, turn]).as_quat(scalar_first=True)
        timed = time_link(route, q0, q1, LinkSettings(), omega_max=1.0).duration
        est = float(link_time_estimate(0.04 + mid, turn, clearance=0.02, speed=0.25, acceleration=1.0,
                                       omega_max=1.0))
        assert est == pytest.approx(timed, abs=0.03)


def test_link_model_cost_is_the_estimate_of_the_frames_turn():
    model = LinkModel(clearance=0.02, speed=0.25, acceleration=1.0, omega_max=1.0)
    eye = np.eye(3)
    flipped = np.diag([-1.0, -1.0, 1.0])            # half a turn about the tool axis
    assert float(model.cost(0.14, eye, flipped)) == pytest.approx(
        float(link_time_estimate(0.14, np.pi, clearance=0.02, speed=0.25, acceleration=1.0, omega_max=1.0)))
    assert float(model.cost(0.14, eye, flipped)) > np.pi          # the turn alone takes pi s
    assert LinkModel(clearance=0.02).cost(0.14, eye, flipped) == 0.14   # untimed: the length


def ridge_plate(edge=5e-3, height=0.06):
    """A flat plate x in [-0.05, 0.15], y in [-0.05, 0.25] (z = 0) with a wall ``height`` high
    along x = 0.05 (12 mm thick) from y = 0.08 to the far edge."""
    xs, ys = np.arange(-0.05, 0.15 + 1e-9, edge), np.arange(-0.05, 0.25 + 1e-9, edge)
    gx, gy = np.meshgrid(xs, ys)
    p = np.stack([gx.ravel(), gy.ravel()], 1)
    z = np.where((np.abs(p[:, 0] - 0.05) <= 0.006 + 1e-9) & (p[:, 1] >= 0.08 - 1e-9), height, 0.0)
    tri = Delaunay(p).simplices
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
    tri = np.where(ccw[:, None], tri, tri[:, ::-1])
    return Surface(np.column_stack([p, z]), tri, name="ridge_plate")


def test_links_that_must_climb_over_the_part_cost_their_route():
    """Two passes either side of a wall that stops short of y = 0: straight at the clearance the
    link at y = 0.2 is 10 mm shorter than the one at y = 0, but it runs through the wall; its
    route climbs over it.  Routed costing takes the link round the wall's end."""
    surf = ridge_plate()
    passes = [Pass(np.array([[0.0, 0.0, 0], [0.0, 0.1, 0], [0.0, 0.2, 0]]), np.tile([0, 0, 1.0], (3, 1))),
              Pass(np.array([[0.11, 0.0, 0], [0.105, 0.1, 0], [0.1, 0.2, 0]]), np.tile([0, 0, 1.0], (3, 1)))]
    tp = ToolPath(surf, passes, "test")
    straight = order_toolpath(tp, method="exact", routed=False)
    assert straight.metadata["air_after_m"] == pytest.approx(0.04 + 0.1)
    assert straight.passes[0].points[-1][1] == pytest.approx(0.2)      # through the wall
    routed = order_toolpath(tp, method="exact")
    assert routed.passes[0].points[-1][1] == pytest.approx(0.0)        # round its end
    assert routed.metadata["air_after_m"] == pytest.approx(0.04 + 0.11)
    assert routed.metadata["order_route_rounds"] == 1
    # what the order stage reports is what route_links flies
    from swath.order import route_links

    flown = route_links(routed, clearance=0.02)
    assert flown.metadata["air_route_length_m"] == pytest.approx(routed.metadata["air_after_m"])
    climbs = route_links(straight, clearance=0.02).metadata["air_route_length_m"]
    assert climbs > 0.04 + 0.1 + 2 * 0.04                               # up over the 60 mm wall and down


def test_job_key_order_objective_chooses_time_or_length(tmp_path):
    from swath.cli.job import order_options
    from swath.cli.settings import settings_from_mapping
    from swath.errors import InputError

    pts = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]
    tp = ToolPath(None, tuple(Pass(pts, [[0, 0, 1]] * 2) for _ in range(3)), "raster", {"order_hint": "gtsp"})
    base = {"part": "example:plate", "out": str(tmp_path / "o"), "pad_radius": "50mm"}
    timed = order_options(tp, settings_from_mapping(base))                        # time by default
    assert timed["link_speed"] == pytest.approx(0.25) and timed["omega_max"] == pytest.approx(1.0)
    assert timed["pad_radius"] == pytest.approx(0.05) and timed["clearance"] == pytest.approx(0.02)
    s = settings_from_mapping({**base, "order_objective": "length"})
    assert s.as_record()["order_objective"] == "length"
    by_length = order_options(tp, s)
    assert {"link_speed", "omega_max", "link_acceleration"}.isdisjoint(by_length)
    assert by_length["pad_radius"] == pytest.approx(0.05)
    assert timed["feed"] == pytest.approx(0.05)
    with pytest.raises(InputError, match="order_objective"):
        settings_from_mapping({**base, "order_objective": "energy"})


@pytest.mark.parametrize("kind", ["U", "L"])
def test_contact_step_over_costs_the_contact_time_it_adds(kind):
    """Two 200 mm passes on a plate joined by a 39 mm step-over in contact: the timed trajectory
    takes ``contact_cost`` longer than the two passes timed apart (each with its approach and
    retract, 0.57 s)."""
    from swath.examples import flat_plate
    from swath.order.joining import StepOverJoiner, join_passes
    from swath.order.variants import contact_cost, pass_ends
    from swath.trajectory.constraints import AngularSpeedLimit, CentripetalLimit, FeedLimit
    from swath.trajectory.timing import time_path

    plate = flat_plate()
    limits = [FeedLimit(0.05), AngularSpeedLimit(1.0), CentripetalLimit(2.0)]

    def line(p0, p1):
        w = np.linspace(0, 1, 41)[:, None]
        return Pass(np.asarray(p0) * (1 - w) + np.asarray(p1) * w, np.tile([0, 0, 1.0], (41, 1)))

    a = line([0.1, 0.1, 0], [0.3, 0.1, 0])
    b = line([0.3, 0.139, 0], [0.1, 0.139, 0]) if kind == "U" else line([0.3, 0.139, 0], [0.3, 0.28, 0])
    joined = join_passes(ToolPath(plate, (a, b), "t"), StepOverJoiner(plate, max_gap=0.08))
    assert len(joined.passes) == 1
    apart = sum(time_path(ToolPath(plate, (p,), "t"), limits).duration for p in (a, b))
    added = time_path(joined, limits).duration - apart + 0.571            # one approach and retract fewer
    end, start = pass_ends(a), pass_ends(b)
    model = LinkModel(clearance=0.02, speed=0.25, acceleration=1.0, omega_max=1.0, feed=0.05)
    cost = float(contact_cost(model, start[0] - end[3], end[5], start[2]))
    assert cost == pytest.approx(0.039 / 0.05 + 0.81 * (np.pi if kind == "U" else np.pi / 2))
    assert cost == pytest.approx(added, abs=0.1)


def test_links_inside_a_group_cost_their_route_too():
    surf = ridge_plate()
    passes = [Pass(np.array([[0.0, 0.0, 0], [0.0, 0.2, 0]]), np.tile([0, 0, 1.0], (2, 1))),
              Pass(np.array([[0.1, 0.2, 0], [0.11, 0.0, 0]]), np.tile([0, 0, 1.0], (2, 1)))]   # a snake
    tp = ToolPath(surf, passes, "test")
    straight = order_toolpath(tp, groups=[[0, 1]], method="exact", routed=False)
    assert straight.metadata["air_after_m"] == pytest.approx(0.04 + 0.1)   # through the wall
    routed = order_toolpath(tp, groups=[[0, 1]], method="exact")
    assert routed.metadata["air_after_m"] == pytest.approx(0.04 + 0.11)    # the group run from y = 0.2 down
    assert routed.passes[0].points[-1][1] == pytest.approx(0.0)


def test_a_length_only_link_model_refuses_to_time_a_step_over():
    frame = np.eye(3)[None]
    assert LinkModel().cost(np.array([0.3]), frame, frame) == pytest.approx([0.3])
    with pytest.raises(Exception, match="link speed"):
        LinkModel().straight_time(np.array([0.3]), frame, frame)
