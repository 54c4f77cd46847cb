"""Kinematic Hessian ∂J/∂q: finite differences, J̇ consistency, batching, random chains."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.kinematics.hessian import hessian_from_jacobian, jacobian_hessian, numerical_hessian


def test_hessian_matches_finite_differences(arm, rng):
    for _ in range(8):
        q = arm.random_q(rng=rng)
        H = jacobian_hessian(arm, q)
        assert H.shape == (arm.dof, 6, arm.dof)
        assert np.max(np.abs(H - numerical_hessian(arm, q))) < 1e-7


def test_hessian_at_a_tool_point_matches_finite_differences(rng):
    arm = rc.robots.puma560()
    point = np.array([0.03, -0.02, 0.2])
    for _ in range(5):
        q = arm.random_q(rng=rng)
        H = jacobian_hessian(arm, q, point=point)
        assert np.max(np.abs(H - numerical_hessian(arm, q, point=point))) < 1e-7


def test_hessian_contracted_with_qd_is_jacobian_dot(arm, rng):
    # J̇ = Σ_k (∂J/∂q_k) q̇_k; jacobian_dot is an independent implementation
    for _ in range(5):
        q = arm.random_q(rng=rng)
        qd = rng.normal(size=arm.dof)
        H = jacobian_hessian(arm, q)
        assert np.max(np.abs(np.einsum("kai,k->ai", H, qd) - arm.jacobian_dot(q, qd))) < 1e-10


def test_position_hessian_is_symmetric_and_angular_part_is_strictly_upper(rng):
    # ∂J_v,i/∂q_k = ∂²p/∂q_i∂q_k is symmetric; ∂J_ω,i/∂q_k = 0 for k ≥ i
    arm = rc.robots.stanford()
    q = arm.random_q(rng=rng)
    Hfd = numerical_hessian(arm, q)
    H = jacobian_hessian(arm, q)
    lin = H[:, :3, :]  # [k, row, i]
    assert np.max(np.abs(lin - np.transpose(lin, (2, 1, 0)))) < 1e-12
    assert np.max(np.abs(Hfd[:, :3, :] - np.transpose(Hfd[:, :3, :], (2, 1, 0)))) < 1e-7
    for k in range(arm.dof):
        for i in range(k + 1):
            assert np.all(H[k, 3:, i] == 0.0)


@pytest.mark.parametrize("shape", [(4,), (2, 3)])
def test_batched_hessian_equals_looped(shape, rng):
    arm = rc.robots.iiwa7()
    qs = arm.random_q(shape, rng=rng)
    H = jacobian_hessian(arm, qs)
    assert H.shape == shape + (7, 6, 7)
    flat_q = qs.reshape(-1, 7)
    flat_H = H.reshape(-1, 7, 6, 7)
    for qi, Hi in zip(flat_q, flat_H, strict=True):
        # the batched and the single-configuration Jacobian kernels agree to rounding
        assert np.max(np.abs(Hi - jacobian_hessian(arm, qi))) < 1e-13


def test_bad_input_raises():
    with pytest.raises(rc.InputError):
        hessian_from_jacobian(np.zeros((5, 6)))
    with pytest.raises(rc.InputError):
        numerical_hessian(rc.robots.ur5e(), np.zeros((2, 6)))


@st.composite
def random_chain(draw):
    n = draw(st.integers(1, 7))
    cls = draw(st.sampled_from([rc.DH, rc.MDH]))
    lengths = st.floats(-1.0, 1.0, allow_nan=False)
    angles = st.one_of(st.floats(-math.pi, math.pi, allow_nan=False),
                       st.sampled_from([0.0, math.pi / 2, -math.pi / 2]))
    rows = [cls(a=draw(lengths), d=draw(lengths), alpha=draw(angles), theta=draw(angles),
                joint=draw(st.sampled_from(["revolute", "revolute", "prismatic"])))
            for _ in range(n)]
    build = rc.Chain.from_dh if cls is rc.DH else rc.Chain.from_mdh
    tool = rc.spatial.translation(*draw(st.lists(lengths, min_size=3, max_size=3)))
    chain = build(rows, tool=tool)
    q = np.array(draw(st.lists(st.floats(-math.pi, math.pi, allow_nan=False), min_size=n, max_size=n)))
    return chain, q


@settings(max_examples=60, deadline=None)
@given(random_chain())
def test_random_chains_hessian_matches_finite_differences(case):
    chain, q = case
    assert np.max(np.abs(jacobian_hessian(chain, q) - numerical_hessian(chain, q))) < 1e-6
