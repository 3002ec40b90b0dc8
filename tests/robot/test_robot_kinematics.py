"""Kinematic models: FK of every IK solution back to the pose, against own DH FK, catalogue facts."""

import math

import numpy as np
import pytest

from swath.errors import InputError
from swath.robot import dh_robot, get_robot
from swath.robot.chain import wrap_angle
from swath.robot.opw import OPWParameters, opw_ik
from swath.robot.pose import (
    matrix_to_quat,
    matrix_to_zyx,
    pose_error,
    quat_to_matrix,
    zyx_to_matrix,
)

MODELS = ["ur3e", "ur5e", "ur10e", "ur16e", "irb4600-60/2.05", "kr120r2700-2"]


@pytest.mark.parametrize("name", MODELS)
def test_every_ik_solution_maps_back_to_the_pose(name):
    model = get_robot(name)
    rng = np.random.default_rng(7)
    q = rng.uniform(np.maximum(model.lower, -math.pi), np.minimum(model.upper, math.pi), (60, 6))
    target = model.fk(q)
    sols = model.ik(target)
    assert sols.shape == (60, 8, 6)
    finite = np.isfinite(sols[..., 0])
    assert finite.sum() >= 60 * 4          # at least half the branches exist for random reachable poses
    dp, da = pose_error(model.fk(sols[finite]), np.repeat(target[:, None], 8, axis=1)[finite])
    assert dp.max() < 1e-9 and da.max() < 1e-9
    # the configuration the pose came from is among the solutions
    diff = np.abs(wrap_angle(sols - wrap_angle(q)[:, None])).max(axis=2)
    assert np.all(np.nanmin(diff, axis=1) < 1e-7)


def test_ur_ik_package_agrees_with_own_dh_forward_kinematics():
    import ur_analytic_ik

    model = get_robot("ur10e")
    q = np.array([0.3, -1.2, 1.1, -0.5, 0.7, 0.2])
    np.testing.assert_allclose(model.fk(q[None])[0], ur_analytic_ik.ur10e.forward_kinematics(*q), atol=1e-12)
    # UR10e at zero: arm stretched along -x (a2 + a3), wrist offsets d4 sideways and d6 down along -y / -z
    t0 = model.fk(np.zeros((1, 6)))[0]
    np.testing.assert_allclose(t0[:3, 3], [-0.6127 - 0.57155, -0.17415 - 0.11655, 0.1807 - 0.11985], atol=1e-12)


def test_opw_positions_match_the_datasheet_poses():
    abb = get_robot("irb4600")
    # calibration position: wrist centre 175 + 960 mm forward, 495 + 900 + 175 mm up; flange 135 mm further
    np.testing.assert_allclose(abb.fk(np.zeros((1, 6)))[0][:3, 3], [1.270, 0, 1.570], atol=1e-12)
    kuka = get_robot("kr120")
    home = np.radians([[0, -90, 90, 0, 0, 0]])
    np.testing.assert_allclose(kuka.fk(home)[0][:3, 3], [0.350 + 1.200 + 0.215, 0, 0.675 + 1.150 + 0.041], atol=1e-12)
    # KUKA A1 positive turns clockwise seen from above (the arm swings to -y)
    assert kuka.fk(np.radians([[30, -90, 90, 0, 0, 0]]))[0][1, 3] < 0


def test_opw_with_lateral_offset_and_signs():
    p = OPWParameters(a1=0.1, a2=-0.135, b=0.05, c1=0.6, c2=0.7, c3=0.75, c4=0.09, sign=(-1, 1, -1, 1, -1, 1),
                      offset=(0.1, -0.2, 0.3, 0, 0.4, 0))
    chain = p.chain()
    q = np.random.default_rng(3).uniform(-2, 2, (40, 6))
    target = chain.fk(q)
    sols = opw_ik(p, target)
    finite = np.isfinite(sols[..., 0])
    dp, da = pose_error(chain.fk(sols[finite]), np.repeat(target[:, None], 8, axis=1)[finite])
    assert dp.max() < 1e-9 and da.max() < 1e-9


def test_numeric_dh_robot_solves_to_1e_9():
    d, a = (0.1625, 0, 0, 0.1333, 0.0997, 0.0996), (0, -0.425, -0.3922, 0, 0, 0)
    alpha = (math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0)
    model = dh_robot("ur5e-dh", d, a, alpha, lower=[-2 * math.pi] * 6, upper=[2 * math.pi] * 6,
                     max_speed=[math.pi] * 6, max_accel=[2 * math.pi] * 6)
    q0 = np.array([0.2, -1.0, 1.2, -0.8, 1.3, 0.1])
    q = q0 + np.linspace(0, 0.05, 5)[:, None]
    target = model.fk(q)
    sol = model.ik(target, seed=q0 + 0.02)
    dp, da = pose_error(model.fk(sol[:, 0]), target)
    assert dp.max() < 1e-9 and da.max() < 1e-9


def test_unknown_robot_is_refused_by_name():
    with pytest.raises(InputError, match="ur10e"):
        get_robot("ur11")


def test_pose_conversions_round_trip():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    r = quat_to_matrix(q)
    np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(r)), r, atol=1e-12)
    abc = matrix_to_zyx(r)
    np.testing.assert_allclose(zyx_to_matrix(*abc.T), r, atol=1e-12)
    # KUKA A, B, C: A = 90° about z maps x to y
    np.testing.assert_allclose(zyx_to_matrix(math.pi / 2, 0, 0) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
