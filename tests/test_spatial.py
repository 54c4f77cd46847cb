"""SO(3)/SE(3) helpers: accuracy near 0 and π, round trips, batching."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ratectl import spatial as sp

vec3 = st.lists(st.floats(-1, 1, allow_nan=False), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 1e-3)


@pytest.mark.parametrize("angle", [0.0, 1e-7, 1e-3, 0.7, 2.0, math.pi])
def test_so3_left_jacobian_maps_the_rotation_vector_rate_to_angular_velocity(angle):
    """d/dt exp(w) = [J_l(w) ẇ]× exp(w) (by central differences), J_l shrinks no vector, and it
    is the V of se3_exp."""
    rng = np.random.default_rng(7)
    axis = rng.standard_normal(3)
    w = angle * axis / np.linalg.norm(axis)
    wd = rng.standard_normal(3)
    h = 1e-6
    Rp, Rm = sp.so3_exp(w + h * wd), sp.so3_exp(w - h * wd)
    omega = sp.vee((Rp - Rm) / (2 * h) @ sp.so3_exp(w).T)
    Jl = sp.so3_left_jacobian(w)
    assert np.allclose(Jl @ wd, omega, atol=1e-8)
    assert np.all(np.linalg.svd(Jl, compute_uv=False) <= 1.0 + 1e-12)
    v = rng.standard_normal(3)
    assert np.allclose(sp.se3_exp(np.concatenate([v, w]))[:3, 3], Jl @ v, atol=1e-14)
    assert sp.so3_left_jacobian(np.stack([w, 2 * w])).shape == (2, 3, 3)


@settings(max_examples=200, deadline=None)
@given(vec3, st.floats(0.0, math.pi, allow_nan=False))
def test_so3_exp_log_round_trip(axis, angle):
    axis = np.array(axis) / np.linalg.norm(axis)
    w = angle * axis
    R = sp.so3_exp(w)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14)
    w2 = sp.so3_log(R)
    if angle < math.pi - 1e-9:
        assert np.allclose(w2, w, atol=1e-10)
    assert np.allclose(sp.so3_exp(w2), R, atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 1e-4, math.pi - 1e-4, math.pi - 1e-8,
                                   math.pi - 1e-12, math.pi])
def test_log_accurate_near_zero_and_pi(angle):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    R = sp.so3_exp(angle * axis)
    w = sp.so3_log(R)
    assert abs(np.linalg.norm(w) - angle) < 1e-9
    if angle > 0:
        assert abs(abs(w @ axis) / np.linalg.norm(w) - 1) < 1e-9
    assert np.allclose(sp.so3_exp(w), R, atol=1e-13)


def test_log_never_nan_for_slightly_non_orthogonal_rotations():
    R = sp.rotz(math.pi) * (1 + 1e-12)
    assert np.all(np.isfinite(sp.so3_log(R)))
    R = np.eye(3) * (1 + 1e-12)
    assert np.all(np.isfinite(sp.so3_log(R)))


@settings(max_examples=100, deadline=None)
@given(vec3, vec3, st.floats(0.0, 3.0))
def test_se3_exp_log_round_trip(v, w, scale):
    xi = np.concatenate([v, scale * np.array(w) / np.linalg.norm(w)])
    T = sp.se3_exp(xi)
    assert np.allclose(sp.se3_log(T), xi, atol=1e-9)


def test_pose_error_convention():
    T = sp.transform(sp.rotz(0.1), [1, 2, 3])
    Td = sp.transform(sp.rotz(0.3), [1.5, 2, 3])
    e = sp.pose_error(Td, T)
    assert np.allclose(e, [0.5, 0, 0, 0, 0, 0.2])
    # e rotates the actual orientation into the desired one, in base axes
    assert np.allclose(sp.so3_exp(e[3:]) @ T[:3, :3], Td[:3, :3])


def test_quaternion_round_trip_and_convention():
    R = sp.rotx(math.pi / 2)
    q = sp.quat_from_rotation(R)
    assert np.allclose(q, [math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0])
    rng = np.random.default_rng(0)
    Rs = sp.so3_exp(rng.normal(size=(50, 3)))
    assert np.allclose(sp.rotation_from_quat(sp.quat_from_rotation(Rs)), Rs, atol=1e-12)
    assert np.allclose(sp.quat_from_rotation(sp.rotz(math.pi))[[0, 3]], [0, 1], atol=1e-12)


def test_rpy_round_trip():
    rpy = np.array([0.1, -0.4, 2.0])
    R = sp.rotation_from_rpy(rpy)
    assert np.allclose(R, sp.rotz(2.0) @ sp.roty(-0.4) @ sp.rotx(0.1))
    assert np.allclose(sp.rpy_from_rotation(R), rpy)
    # gimbal lock still reproduces the rotation
    R = sp.rotation_from_rpy([0.3, math.pi / 2, 0.2])
    assert np.allclose(sp.rotation_from_rpy(sp.rpy_from_rotation(R)), R, atol=1e-12)


def test_interpolation_endpoints_and_midpoint():
    T0 = sp.transform(sp.rotx(0.2), [0, 0, 0])
    T1 = sp.transform(sp.rotx(1.0), [1, 0, 0])
    for method in ("decoupled", "screw"):
        Ts = sp.interpolate(T0, T1, np.array([0.0, 0.5, 1.0]), method=method)
        assert np.allclose(Ts[0], T0) and np.allclose(Ts[2], T1)
        assert np.allclose(Ts[1][:3, :3], sp.rotx(0.6))
    assert np.allclose(sp.interpolate(T0, T1, 0.5)[:3, 3], [0.5, 0, 0])
    with pytest.raises(ValueError, match="decoupled"):
        sp.interpolate(T0, T1, 0.5, method="linear")


def test_inverse_and_adjoint():
    T = sp.transform(sp.so3_exp([0.1, 0.2, 0.3]), [1, -2, 0.5])
    assert np.allclose(T @ sp.inverse_transform(T), np.eye(4))
    xi = np.array([0.1, 0.2, 0.3, -0.2, 0.5, 0.1])
    # Ad_T xi is the same motion expressed in the outer frame
    lhs = T @ sp.se3_exp(1e-6 * xi) @ sp.inverse_transform(T)
    assert np.allclose(sp.se3_log(lhs) / 1e-6, sp.adjoint(T) @ xi, atol=1e-5)


def test_skew_vee_batched():
    v = np.arange(12.0).reshape(4, 3)
    S = sp.skew(v)
    assert S.shape == (4, 3, 3)
    assert np.allclose(sp.vee(S), v)
    assert np.allclose(S[1] @ [1, 2, 3], np.cross(v[1], [1, 2, 3]))


@settings(max_examples=300, deadline=None)
@given(vec3, st.sampled_from([0.0, 1e-9, 1e-7, 1e-6, 2e-6, 1e-3, 0.5, 2.0, 2.7, 3.0, math.pi - 1e-9,
                              math.pi]) | st.floats(0.0, math.pi))
def test_scalar_so3_forms_agree_with_the_array_forms(axis, angle):
    """so3_exp_rows / so3_log_rows (plain floats, used every control cycle) give what
    so3_exp / so3_log give, near 0, near π (the symmetric-part branch) and between."""
    w = angle * np.array(axis) / np.linalg.norm(axis)
    R = np.array(sp.so3_exp_rows(*w.tolist()))
    assert np.allclose(R, sp.so3_exp(w), atol=1e-15, rtol=0)
    x, y, z, th = sp.so3_log_rows(R.tolist())
    assert np.allclose([x, y, z], sp.so3_log(R), atol=1e-12, rtol=0)
    assert th == pytest.approx(np.linalg.norm(sp.so3_log(R)), abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(vec3, st.floats(0.0, math.pi), vec3, st.floats(0.0, math.pi))
def test_rotation_error_rows_is_the_pose_errors_rotation(axis, angle, axis2, angle2):
    """rotation_error_rows(R_d, R) (rows of floats, a pose's fourth column ignored) is
    so3_log(R_d Rᵀ) with its angle, and exactly zero for R_d = R (the servo takes the
    rotation of a target that only translates as 0 without computing it)."""
    Rd = sp.so3_exp(angle * np.array(axis) / np.linalg.norm(axis))
    R = sp.so3_exp(angle2 * np.array(axis2) / np.linalg.norm(axis2))
    Td = np.eye(4)
    Td[:3, :3] = Rd
    Td[:3, 3] = [0.3, -0.2, 0.5]
    x, y, z, th = sp.rotation_error_rows(Td.tolist(), R.tolist())
    assert np.allclose([x, y, z], sp.so3_log(Rd @ R.T), atol=1e-9, rtol=0)
    assert th == pytest.approx(np.linalg.norm(sp.so3_log(Rd @ R.T)), abs=1e-9)
    assert sp.rotation_error_rows(Td.tolist(), Rd.tolist()) == (0.0, 0.0, 0.0, 0.0)


@settings(max_examples=200, deadline=None)
@given(vec3, st.floats(0.0, math.pi), vec3, st.floats(0.0, math.pi), vec3)
def test_pose_error_rows_is_the_pose_error(axis, angle, axis2, angle2, shift):
    """pose_error_rows on a pose's first three rows of floats ([R | p]) writes the pose error
    e = [p_d − p; log(R_d Rᵀ)] and returns its two norms, as pose_error / pose_error_into."""
    Td, T = np.eye(4), np.eye(4)
    Td[:3, :3] = sp.so3_exp(angle * np.array(axis) / np.linalg.norm(axis))
    T[:3, :3] = sp.so3_exp(angle2 * np.array(axis2) / np.linalg.norm(axis2))
    Td[:3, 3] = [0.3, -0.2, 0.5]
    T[:3, 3] = np.array(shift) * 0.1
    e, e_into = np.zeros(6), np.zeros(6)
    ep, eo = sp.pose_error_rows(e, Td.tolist()[:3], T.tolist()[:3])
    assert np.allclose(e, sp.pose_error(Td, T), atol=1e-9, rtol=0)
    assert (ep, eo) == sp.pose_error_into(e_into, Td, T) and np.array_equal(e, e_into)
    assert ep == pytest.approx(np.linalg.norm(Td[:3, 3] - T[:3, 3]), abs=1e-12)


@settings(max_examples=300, deadline=None)
@given(vec3, st.floats(0.0, math.pi), st.integers(0, 15), st.sampled_from([0.0, 1e-7, 2e-6, 1e-3, -1.0]))
def test_rigid_transform_defect_fast_path_agrees_with_the_full_check(axis, angle, entry, delta):
    """The per-cycle (plain float) path of rigid_transform_defect accepts exactly what the
    array path accepts: a rotation perturbed in one entry, a mirror, a wrong last row."""
    T = np.eye(4)
    T[:3, :3] = sp.so3_exp(angle * np.array(axis) / np.linalg.norm(axis))
    T[:3, 3] = [0.3, -0.2, 0.5]
    T.flat[entry] += delta
    got = sp.rigid_transform_defect(T)
    slow = sp.rigid_transform_defect(T.tolist())  # a list takes the array path
    assert (got is None) == (slow is None), (got, slow)
    if entry in (12, 13, 14, 15) and delta != 0.0 or (entry % 4 != 3 and entry < 12 and abs(delta) > 1e-6):
        assert got is not None
    mirror = T.copy()
    mirror[:3, 0] *= -1
    assert sp.rigid_transform_defect(mirror) is not None
