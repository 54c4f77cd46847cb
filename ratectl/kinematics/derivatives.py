"""Time derivative of the Jacobian (J̇) and statics (τ = Jᵀ F)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..checks import real_array
from ..errors import InputError
from .forward import check_frame, check_point, jacobian, rotate_jacobian, shift_jacobian
from .reference import all_frames

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["jacobian_dot", "joint_torques"]


def jacobian_dot(chain: Chain, q: ArrayLike, qd: ArrayLike, *, frame: str = "base",
                 point: ArrayLike | None = None) -> np.ndarray:
    """Time derivative of the geometric Jacobian along the motion ``q̇``, (..., 6, n).

    With ω_i = Σ_{j<i, revolute} z_j q̇_j the angular velocity of the body carrying
    axis i, ż_i = ω_i × z_i, ȯ_i the velocity of the point o_i (fixed on that body)
    and ṗ = J_v q̇ the tool velocity:

    * revolute:  ``[ ż_i × (p − o_i) + z_i × (ṗ − ȯ_i) ; ż_i ]``
    * prismatic: ``[ ż_i ; 0 ]``

    The tool acceleration is ``ξ̇ = J q̈ + J̇ q̇``.
    """
    check_frame(frame)
    a = chain.check_q(q)
    qd = chain.check_q(qd, name="qd")
    a, qd = np.broadcast_arrays(a, qd)
    _, Js, Ttool = all_frames(chain, a)
    z = Js[..., :3, 2]
    o = Js[..., :3, 3]
    rev = ~chain.prismatic
    p = Ttool[..., :3, 3]
    # joint-space rates as per-joint vectors
    wz = np.where(rev[:, None], z * qd[..., :, None], 0.0)  # z_j q̇_j (revolute)
    vz = np.where(rev[:, None], 0.0, z * qd[..., :, None])  # z_j q̇_j (prismatic)
    # exclusive cumulative sums over j < i
    omega = np.cumsum(wz, axis=-2) - wz
    zxo = np.cross(wz, o)
    sum_zxo = np.cumsum(zxo, axis=-2) - zxo
    sum_v = np.cumsum(vz, axis=-2) - vz
    o_dot = np.cross(omega, o) - sum_zxo + sum_v
    z_dot = np.cross(omega, z)
    # tool velocity
    omega_all = wz.sum(axis=-2)
    p_dot = np.cross(omega_all, p) - zxo.sum(axis=-2) + vz.sum(axis=-2)
    r = p[..., None, :] - o
    lin_rev = np.cross(z_dot, r) + np.cross(z, p_dot[..., None, :] - o_dot)
    lin = np.where(rev[:, None], lin_rev, z_dot)
    ang = np.where(rev[:, None], z_dot, 0.0)
    Jd = np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(ang, -1, -2)], axis=-2)
    if point is None and frame == "base":
        return Jd
    J = jacobian(chain, a)
    w = omega_all
    if point is not None:
        pt = check_point(point)
        rr = Ttool[..., :3, :3] @ pt
        # J_v' = J_v − [r]× J_ω  ⇒  J̇_v' = J̇_v − [ω × r]× J_ω − [r]× J̇_ω
        Jd = shift_jacobian(Jd, rr)
        Jd[..., :3, :] += shift_jacobian(J, np.cross(w, rr))[..., :3, :] - J[..., :3, :]
        J = shift_jacobian(J, rr)
    if frame == "tool":
        # d/dt(Rᵀ J) = Rᵀ (J̇ − [ω]× J)
        Jd = Jd.copy()
        for rows in (slice(0, 3), slice(3, 6)):
            cols = np.swapaxes(J[..., rows, :], -1, -2)
            Jd[..., rows, :] -= np.swapaxes(np.cross(w[..., None, :], cols), -1, -2)
        Jd = rotate_jacobian(Jd, Ttool[..., :3, :3])
    return Jd


def joint_torques(chain: Chain, q: ArrayLike, wrench: ArrayLike, *, frame: str = "base",
                  point: ArrayLike | None = None) -> np.ndarray:
    """Static joint torques ``τ = Jᵀ F`` balancing a tool wrench ``F = [f; τ]`` [N; N·m].

    The wrench is expressed in the same axes (``frame``) and at the same point as the
    Jacobian. Returns (..., n) in N·m (revolute) or N (prismatic).
    """
    J = jacobian(chain, q, frame=frame, point=point)
    F = real_array("wrench", wrench, "a (..., 6) wrench [f; τ]")
    if F.shape[-1:] != (6,) or not np.all(np.isfinite(F)):
        raise InputError(f"wrench must be finite with shape (..., 6) = [f; τ], got {F.shape}",
                         argument="wrench", value=wrench)
    return np.einsum("...ji,...j->...i", J, F)
