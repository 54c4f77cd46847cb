"""Rotations and rigid transforms: SO(3) and SE(3) helpers.

Conventions (fixed across the package):

* SI units; angles in radians.
* Twists are ``[v; ω]`` (linear first), rotation vectors are ``θ·axis``.
* Quaternions are scalar-first ``[w, x, y, z]`` (MuJoCo's order), unit norm.
* Roll-pitch-yaw is the URDF convention: ``R = Rz(yaw) · Ry(pitch) · Rx(roll)``.
* Every function accepts leading batch dimensions: a rotation is ``(..., 3, 3)``,
  a transform ``(..., 4, 4)``, a vector ``(..., 3)``.

Accuracy: `so3_log` and `so3_exp` use series near angle 0 and the
symmetric part of ``R`` near angle π, so they stay accurate to machine precision
over the whole range; no ``arccos`` of an unclipped value is ever taken.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .errors import InputError

#: a rotation or pose as rows of floats (lists or tuples): ``T.tolist()``, a kernel's rows
Rows = Sequence[Sequence[float]]

__all__ = [
    "skew",
    "vee",
    "rotx",
    "roty",
    "rotz",
    "transform",
    "translation",
    "inverse_transform",
    "so3_exp",
    "so3_log",
    "so3_left_jacobian",
    "se3_exp",
    "se3_log",
    "pose_error",
    "pose_error_into",
    "rigid_transform_defect",
    "rotation_angle",
    "quat_from_rotation",
    "rotation_from_quat",
    "rpy_from_rotation",
    "rotation_from_rpy",
    "interpolate",
    "adjoint",
]

_SMALL = 1e-6


def _as_array(x, name: str, tail: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.shape[a.ndim - len(tail):] != tail or a.ndim < len(tail):
        raise InputError(
            f"{name} must have shape (..., {', '.join(map(str, tail))}), got {a.shape}",
            argument=name, value=a)
    return a


def skew(v: ArrayLike) -> np.ndarray:
    """Skew-symmetric matrix ``[v]×`` with ``[v]× u = v × u``.

    Args:
        v: vector(s), shape ``(..., 3)``.

    Returns:
        ``(..., 3, 3)`` array.
    """
    v = _as_array(v, "v", (3,))
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def vee(S: ArrayLike) -> np.ndarray:
    """Inverse of `skew` for the skew part of ``S``: returns ``(..., 3)``."""
    S = _as_array(S, "S", (3, 3))
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        axis=-1,
    )


def _axis_rotation(angle, i: int, j: int) -> np.ndarray:
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    k = 3 - i - j
    out[..., k, k] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def rotx(angle: ArrayLike) -> np.ndarray:
    """Rotation about x by ``angle`` [rad]: ``(..., 3, 3)``."""
    return _axis_rotation(angle, 1, 2)


def roty(angle: ArrayLike) -> np.ndarray:
    """Rotation about y by ``angle`` [rad]: ``(..., 3, 3)``."""
    return _axis_rotation(angle, 2, 0)


def rotz(angle: ArrayLike) -> np.ndarray:
    """Rotation about z by ``angle`` [rad]: ``(..., 3, 3)``."""
    return _axis_rotation(angle, 0, 1)


def transform(R: ArrayLike | None = None, p: Any = None) -> np.ndarray:
    """Homogeneous transform from a rotation ``R`` (..., 3, 3) and translation ``p`` (..., 3) [m].

    Either may be omitted (identity rotation, zero translation).
    """
    R = np.eye(3) if R is None else _as_array(R, "R", (3, 3))
    p = np.zeros(3) if p is None else _as_array(p, "p", (3,))
    batch = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros(batch + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """Pure translation transform by ``(x, y, z)`` [m]."""
    return transform(None, np.array([x, y, z], dtype=float))


def inverse_transform(T: ArrayLike) -> np.ndarray:
    """Inverse of a rigid transform: ``[Rᵀ, −Rᵀp; 0, 1]``."""
    T = _as_array(T, "T", (4, 4))
    R = T[..., :3, :3]
    p = T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    return transform(Rt, -np.einsum("...ij,...j->...i", Rt, p))


def so3_exp(w: ArrayLike) -> np.ndarray:
    """Rotation matrix of a rotation vector ``w = θ·axis`` (Rodrigues' formula).

    ``R = I + (sin θ/θ)[w]× + ((1 − cos θ)/θ²)[w]×²``, with Taylor series for θ < 1e-6.
    """
    w = _as_array(w, "w", (3,))
    th2 = np.einsum("...i,...i->...", w, w)
    th = np.sqrt(th2)
    small = th < _SMALL
    th_safe = np.where(small, 1.0, th)
    A = np.where(small, 1.0 - th2 / 6.0, np.sin(th_safe) / th_safe)
    B = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(th_safe)) / th_safe**2)
    K = skew(w)
    K2 = K @ K
    return np.eye(3) + A[..., None, None] * K + B[..., None, None] * K2


def rotation_angle(R: ArrayLike) -> np.ndarray:
    """Rotation angle θ ∈ [0, π] of ``R``, computed as atan2(‖vee(R)‖, (tr R − 1)/2)."""
    R = _as_array(R, "R", (3, 3))
    s = np.linalg.norm(vee(R), axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    return np.arctan2(s, c)


def so3_log(R: ArrayLike) -> np.ndarray:
    """Rotation vector ``w = θ·axis`` of a rotation matrix (inverse of `so3_exp`).

    θ = atan2(‖vee(R)‖, (tr R − 1)/2) is accurate everywhere. Away from π the axis
    comes from the skew part, ``w = θ/sin θ · vee(R)``; near π (where that part
    vanishes) it comes from the symmetric part, ``(R + Rᵀ)/2 − cos θ I = (1 − cos θ) a aᵀ``,
    with the sign fixed by the skew part.
    """
    R = _as_array(R, "R", (3, 3))
    v = vee(R)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    th = np.arctan2(s, c)
    small = th < _SMALL
    # th / sin(th): series 1 + th²/6 near 0.
    s_safe = np.where(s == 0.0, 1.0, s)
    factor = np.where(small, 1.0 + th**2 / 6.0, th / s_safe)
    w = factor[..., None] * v
    near_pi = c < -0.9  # θ > ~154°: use the symmetric part
    if np.any(near_pi):
        S = 0.5 * (R + np.swapaxes(R, -1, -2)) - c[..., None, None] * np.eye(3)
        diag = np.diagonal(S, axis1=-2, axis2=-1)
        k = np.argmax(diag, axis=-1)
        col = np.take_along_axis(S, k[..., None, None].repeat(3, axis=-1), axis=-2)[..., 0, :]
        norm = np.linalg.norm(col, axis=-1, keepdims=True)
        axis = col / np.where(norm == 0.0, 1.0, norm)
        sign = np.where(np.einsum("...i,...i->...", axis, v) < 0.0, -1.0, 1.0)
        w_pi = (sign * th)[..., None] * axis
        w = np.where(near_pi[..., None], w_pi, w)
    return w


def _left_jacobian_terms(th2):
    th = np.sqrt(th2)
    small = th < 1e-4
    ts = np.where(small, 1.0, th)
    B = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ts)) / ts**2)
    C = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ts - np.sin(ts)) / ts**3)
    return B, C


def so3_left_jacobian(w: ArrayLike) -> np.ndarray:
    """Left Jacobian of SO(3) at the rotation vector ``w`` (θ = ‖w‖), shape ``(..., 3, 3)``.

    ``J_l(w) = I + B[w]× + C[w]×²``, ``B = (1 − cos θ)/θ²``, ``C = (θ − sin θ)/θ³`` (series
    near θ = 0). It maps the rate of a rotation vector to the angular velocity in the fixed
    frame: ``d/dt exp(w) = [J_l(w) ẇ]× exp(w)``; it is also the V of `se3_exp`.
    """
    w = _as_array(w, "w", (3,))
    B, C = _left_jacobian_terms(np.einsum("...i,...i->...", w, w))
    K = skew(w)
    return np.eye(3) + B[..., None, None] * K + C[..., None, None] * (K @ K)


def se3_exp(xi: ArrayLike) -> np.ndarray:
    """Transform ``exp([ξ])`` of a twist ``ξ = [v; ω]`` (unit time), shape ``(..., 6)``.

    ``T = [exp(ω), V(ω) v; 0, 1]`` with ``V = J_l(ω)`` the left Jacobian
    (`so3_left_jacobian`).
    """
    xi = _as_array(xi, "xi", (6,))
    v, w = xi[..., :3], xi[..., 3:]
    V = so3_left_jacobian(w)
    return transform(so3_exp(w), np.einsum("...ij,...j->...i", V, v))


def se3_log(T: ArrayLike) -> np.ndarray:
    """Twist ``ξ = [v; ω]`` with ``se3_exp(ξ) = T`` (inverse of `se3_exp`)."""
    T = _as_array(T, "T", (4, 4))
    w = so3_log(T[..., :3, :3])
    th2 = np.einsum("...i,...i->...", w, w)
    th = np.sqrt(th2)
    small = th < 1e-4
    ts = np.where(small, 1.0, th)
    # V⁻¹ = I − ½[ω]× + D[ω]×², D = (1 − θ sin θ / (2(1 − cos θ))) / θ²
    half = ts / 2.0
    D = np.where(small, 1.0 / 12.0 + th2 / 720.0,
                 (1.0 - half / np.tan(np.where(small, 1.0, half))) / ts**2)
    K = skew(w)
    Vinv = np.eye(3) - 0.5 * K + D[..., None, None] * (K @ K)
    v = np.einsum("...ij,...j->...i", Vinv, T[..., :3, 3])
    return np.concatenate([v, w], axis=-1)


def pose_error(T_desired: ArrayLike, T_actual: ArrayLike) -> np.ndarray:
    """Servoing pose error ``e = [p_d − p ; log(R_d Rᵀ)]`` in base-frame axes, ``(..., 6)``.

    The rotational part is the rotation vector that takes the actual orientation to
    the desired one, expressed in the base frame [rad] (exact, accurate near π); the
    linear part [m]. This is the one pose error of the package: the controller, IK,
    the governor and ``follow`` all call it (or `pose_error_into`, its scalar
    form).
    """
    Td = _as_array(T_desired, "T_desired", (4, 4))
    Ta = _as_array(T_actual, "T_actual", (4, 4))
    if Td.shape == (4, 4) and Ta.shape == (4, 4):
        out = np.empty(6)
        pose_error_into(out, Td, Ta)
        return out
    dp = Td[..., :3, 3] - Ta[..., :3, 3]
    Rerr = Td[..., :3, :3] @ np.swapaxes(Ta[..., :3, :3], -1, -2)
    return np.concatenate(np.broadcast_arrays(dp, so3_log(Rerr)), axis=-1)


def so3_exp_rows(x: float, y: float, z: float) -> list[list[float]]:
    """`so3_exp` of one rotation vector ``w = (x, y, z)`` as three rows of Python floats.

    ``R = I + A[w]× + B[w]×²`` with ``A = sin θ/θ``, ``B = (1 − cos θ)/θ²`` and
    ``[w]×² = w wᵀ − θ² I`` (the same series below θ = 1e-6). Plain arithmetic: a control
    cycle calls it on one vector, where numpy's per-call cost would dominate.
    """
    th2 = x * x + y * y + z * z
    if th2 < _SMALL * _SMALL:
        A, B = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        A, B = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    Bxy, Bxz, Byz = B * x * y, B * x * z, B * y * z
    return [[1.0 + B * (x * x - th2), Bxy - A * z, Bxz + A * y],
            [Bxy + A * z, 1.0 + B * (y * y - th2), Byz - A * x],
            [Bxz - A * y, Byz + A * x, 1.0 + B * (z * z - th2)]]


def so3_log_rows(R: Rows) -> tuple[float, float, float, float]:
    """`so3_log` of one rotation given as three rows of floats: ``(x, y, z, θ)``, the
    rotation vector and its angle [rad]. The angle is ``atan2(‖vee(R)‖, (tr R − 1)/2)``;
    past ``cos θ < −0.9`` the axis comes from `so3_log`'s symmetric-part branch."""
    c = 0.5 * (R[0][0] + R[1][1] + R[2][2] - 1.0)
    if c < -0.9:
        x, y, z = so3_log(np.array(R)).tolist()
        return x, y, z, math.sqrt(x * x + y * y + z * z)
    return _log_skew(0.5 * (R[2][1] - R[1][2]), 0.5 * (R[0][2] - R[2][0]), 0.5 * (R[1][0] - R[0][1]), c)


def _log_skew(vx: float, vy: float, vz: float, c: float) -> tuple[float, float, float, float]:
    """`so3_log_rows` away from π (c = cos θ ≥ −0.9) from vee(R) = (vx, vy), vz and c:
    θ = atan2(‖vee(R)‖, c), w = θ/sin θ · vee(R) (the series 1 + θ²/6 near 0)."""
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    th = math.atan2(s, c)
    f = th / s if th > _SMALL else 1.0 + th * th / 6.0
    return f * vx, f * vy, f * vz, th


def rotation_error_rows(Rd: Rows, R: Rows) -> tuple[float, float, float, float]:
    """`so3_log_rows` of ``R_d Rᵀ`` for two rotations given as rows of floats (the rows of
    a pose: a fourth column is ignored): ``(x, y, z, θ)``, the rotation vector that takes R
    to R_d in base axes and its angle [rad] — the rotational part of the pose error. Each
    entry of the product is the dot product of a row of R_d with a row of R, summed in
    index order."""
    a, b, c = Rd[0], Rd[1], Rd[2]
    u, v, w = R[0], R[1], R[2]
    a0, a1, a2, b0, b1, b2, c0, c1, c2 = a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
    u0, u1, u2, v0, v1, v2, w0, w1, w2 = u[0], u[1], u[2], v[0], v[1], v[2], w[0], w[1], w[2]
    m00 = a0 * u0 + a1 * u1 + a2 * u2
    m11 = b0 * v0 + b1 * v1 + b2 * v2
    m22 = c0 * w0 + c1 * w1 + c2 * w2
    m01 = a0 * v0 + a1 * v1 + a2 * v2
    m02 = a0 * w0 + a1 * w1 + a2 * w2
    m10 = b0 * u0 + b1 * u1 + b2 * u2
    m12 = b0 * w0 + b1 * w1 + b2 * w2
    m20 = c0 * u0 + c1 * u1 + c2 * u2
    m21 = c0 * v0 + c1 * v1 + c2 * v2
    cos = 0.5 * (m00 + m11 + m22 - 1.0)
    if cos < -0.9:
        return so3_log_rows([[m00, m01, m02], [m10, m11, m12], [m20, m21, m22]])
    return _log_skew(0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01), cos)


def pose_error_into(out: np.ndarray, T_desired: np.ndarray, T_actual: np.ndarray) -> tuple[float, float]:
    """`pose_error` of one pair of (4, 4) poses written into ``out`` (6,).

    Returns ``(‖p_d − p‖ [m], θ [rad])``, the norms of the two parts. The scalar
    arithmetic on the poses' rows as Python floats avoids numpy's per-call cost on
    3-vectors (this runs every control cycle); the rotational part is
    `rotation_error_rows`, log(R_d Rᵀ).
    """
    return pose_error_rows(out, T_desired.tolist(), T_actual.tolist())


def pose_error_rows(out: np.ndarray, d: Rows, a: Rows) -> tuple[float, float]:
    """`pose_error_into` of two poses given as their first three rows of floats ([R | p],
    a pose's ``tolist()``), written into ``out`` (6,): for a caller that has the rows
    already (a control cycle reads a pose's rows once)."""
    ex = d[0][3] - a[0][3]
    ey = d[1][3] - a[1][3]
    ez = d[2][3] - a[2][3]
    x, y, z, th = rotation_error_rows(d, a)
    out[:] = (ex, ey, ez, x, y, z)
    return math.sqrt(ex * ex + ey * ey + ez * ez), th


def finite_rows(rows: Rows) -> bool:
    """Whether every entry of the four rows of floats ``rows`` (a 4×4 pose's ``tolist()``)
    is finite: their plain sum is (NaN or inf make it non-finite; an overflow to inf of
    finite values counts as non-finite too)."""
    r0, r1, r2, r3 = rows
    t = sum(r3, sum(r2, sum(r1, sum(r0))))
    return t - t == 0.0


def is_rigid_rows(rows: Rows, *, tolerance: float = 1e-6) -> bool:
    """True when the four rows of floats ``rows`` (a 4×4 pose's ``tolist()``) are a rigid
    transform by the test of `rigid_transform_defect` (finite, max|RRᵀ − I| and |det R − 1|
    within ``tolerance``, last row [0, 0, 0, 1]), which says what is wrong when it is not.
    Plain arithmetic on one list: the per-cycle check of a servo target."""
    r0, r1, r2, r3 = rows
    if not (finite_rows(rows) and r3 == [0.0, 0.0, 0.0, 1.0]):
        return False
    a0, a1, a2 = r0[0], r0[1], r0[2]
    b0, b1, b2 = r1[0], r1[1], r1[2]
    c0, c1, c2 = r2[0], r2[1], r2[2]
    ortho = max(abs(a0 * a0 + a1 * a1 + a2 * a2 - 1.0), abs(b0 * b0 + b1 * b1 + b2 * b2 - 1.0),
                abs(c0 * c0 + c1 * c1 + c2 * c2 - 1.0), abs(a0 * b0 + a1 * b1 + a2 * b2),
                abs(a0 * c0 + a1 * c1 + a2 * c2), abs(b0 * c0 + b1 * c1 + b2 * c2))
    det = a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)
    return ortho <= tolerance and abs(det - 1.0) <= tolerance


def rigid_transform_defect(T: ArrayLike, *, tolerance: float = 1e-6) -> str | None:
    """What keeps ``T`` from being a rigid transform (4×4, finite, orthonormal rotation with
    det +1, last row [0, 0, 0, 1]), as a phrase for an error message; None when it is one.

    ``tolerance`` bounds max|RRᵀ − I| and |det R − 1|. A scaled rotation (‖R‖ ≠ 1) and a
    mirror (det R = −1) are both refused.
    """
    if type(T) is np.ndarray and T.dtype == np.float64 and T.shape == (4, 4) and is_rigid_rows(
            T.tolist(), tolerance=tolerance):
        return None  # (the per-cycle case, a servo target: the message only when something is wrong)
    try:
        if isinstance(T, str | bytes) or np.iscomplexobj(T):
            raise TypeError("T")
        A = np.asarray(T, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return f"is not an array of real numbers (got {type(T).__name__})"
    if A.shape != (4, 4):
        return f"must be a 4x4 homogeneous transform, got shape {A.shape}"
    if not np.all(np.isfinite(A)):
        return "is not a rigid transform: it contains NaN or infinite entries"
    if np.any(A[3] != (0.0, 0.0, 0.0, 1.0)):
        return f"is not a rigid transform: its last row must be [0, 0, 0, 1], got {A[3].tolist()}"
    R = A[:3, :3]
    ortho = float(np.max(np.abs(R @ R.T - np.eye(3))))
    if ortho > tolerance:
        return ("is not a rigid transform: its rotation block is not orthonormal "
                f"(max|R Rᵀ − I| = {ortho:.3g}, allowed {tolerance:g}; scaled or sheared)")
    det = float(np.linalg.det(R))
    if abs(det - 1.0) > tolerance:
        return (f"is not a rigid transform: its rotation block has det {det:+.6g}, must be +1 "
                "(a mirror is not a rotation)")
    return None


def quat_from_rotation(R: ArrayLike) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` (w ≥ 0) of a rotation matrix, robust for all angles."""
    R = _as_array(R, "R", (3, 3))
    w = so3_log(R)
    th = np.linalg.norm(w, axis=-1)
    half = th / 2.0
    small = th < _SMALL
    k = np.where(small, 0.5 - th**2 / 48.0, np.sin(half) / np.where(small, 1.0, th))
    q = np.concatenate([np.cos(half)[..., None], k[..., None] * w], axis=-1)
    return q


def rotation_from_quat(q: ArrayLike) -> np.ndarray:
    """Rotation matrix of a quaternion ``[w, x, y, z]`` (normalised first; zero raises)."""
    q = _as_array(q, "q", (4,))
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0.0) or not np.all(np.isfinite(n)):
        raise InputError("quaternion must be finite and non-zero", argument="q", value=q)
    w, x, y, z = np.moveaxis(q / n, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def rotation_from_rpy(rpy: ArrayLike) -> np.ndarray:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` from ``[roll, pitch, yaw]`` [rad] (URDF convention)."""
    rpy = _as_array(rpy, "rpy", (3,))
    return rotz(rpy[..., 2]) @ roty(rpy[..., 1]) @ rotx(rpy[..., 0])


def rpy_from_rotation(R: ArrayLike) -> np.ndarray:
    """``[roll, pitch, yaw]`` [rad] with ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    At pitch = ±π/2 (gimbal lock) roll is set to 0 and yaw takes the whole angle.
    """
    R = _as_array(R, "R", (3, 3))
    sp = np.clip(-R[..., 2, 0], -1.0, 1.0)
    cp = np.hypot(R[..., 0, 0], R[..., 1, 0])
    pitch = np.arctan2(sp, cp)
    lock = cp < 1e-9
    roll = np.where(lock, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    yaw = np.where(lock, np.arctan2(-R[..., 0, 1], R[..., 1, 1]),
                   np.arctan2(R[..., 1, 0], R[..., 0, 0]))
    return np.stack([roll, pitch, yaw], axis=-1)


def adjoint(T: ArrayLike) -> np.ndarray:
    """Twist adjoint of ``T`` for ``[v; ω]`` twists: ``[[R, [p]×R], [0, R]]``, ``(..., 6, 6)``."""
    T = _as_array(T, "T", (4, 4))
    R = T[..., :3, :3]
    out = np.zeros(T.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = skew(T[..., :3, 3]) @ R
    return out


def interpolate(T0: ArrayLike, T1: ArrayLike, s: ArrayLike, *, method: str = "decoupled") -> np.ndarray:
    """Interpolate between two poses at fraction ``s`` ∈ [0, 1] (broadcasts over ``s``).

    Args:
        T0, T1: start and end poses, ``(4, 4)``.
        s: fraction(s); 0 gives ``T0`` and 1 gives ``T1``.
        method: ``"decoupled"`` — the position moves on the straight line and the
            orientation on the SO(3) geodesic, ``R0 exp(s log(R0ᵀR1))`` (what a
            Cartesian line means); ``"screw"`` — the SE(3) geodesic
            ``T0 exp(s log(T0⁻¹T1))`` (a constant twist, a helix in space).
    """
    T0 = _as_array(T0, "T0", (4, 4))
    T1 = _as_array(T1, "T1", (4, 4))
    s = np.asarray(s, dtype=float)
    if method == "decoupled":
        R0 = T0[..., :3, :3]
        w = so3_log(np.swapaxes(R0, -1, -2) @ T1[..., :3, :3])
        R = R0 @ so3_exp(s[..., None] * w)
        p = T0[..., :3, 3] + s[..., None] * (T1[..., :3, 3] - T0[..., :3, 3])
        return transform(R, p)
    if method == "screw":
        xi = se3_log(inverse_transform(T0) @ T1)
        return T0 @ se3_exp(s[..., None] * xi)
    raise InputError(f"method must be 'decoupled' or 'screw', got {method!r}",
                     argument="method", value=method)
