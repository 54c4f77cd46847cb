"""Forward kinematics, the geometric Jacobian and its time derivative.

All functions take a :class:`~ratectl.chain.Chain` and joint positions ``q`` of
shape ``(n,)`` or ``(..., n)`` and broadcast over the leading dimensions.

Conventions (DESIGN.md §1–2): the Jacobian maps q̇ to the tool twist
``ξ = [v; ω]``; by default its rows are in base axes and the linear rows are taken
at the tool origin. Column i is

* revolute:  ``[ z_i × (p − o_i) ; z_i ]``
* prismatic: ``[ z_i ; 0 ]``

where ``z_i`` is the joint's world axis and ``o_i`` a point on it.

``fk`` and ``jacobian`` run chain-specialised generated code
(:mod:`ratectl._codegen`): one configuration on Python floats, a batch on numpy
arrays in chunks. ``frames`` and ``jacobian_dot`` use generic batched 4×4 products.
"""

from __future__ import annotations

import threading

import numpy as np

from ._codegen import compile_kernel
from .errors import InputError

__all__ = [
    "fk",
    "frames",
    "joint_axes",
    "jacobian",
    "fk_jacobian",
    "jacobian_dot",
    "joint_torques",
    "shift_jacobian",
    "rotate_jacobian",
    "numerical_jacobian",
    "build_kernel",
]

_CHUNK = 8192  # columns per batched kernel call: fits L2, amortises ufunc overhead
_FRAMES = ("base", "tool")


def build_kernel(chain, key):
    """Compile (once per chain) and cache the generated kernel ``key = (what, batched)``."""
    fn = chain._kernels.get(key)
    if fn is None:
        what, batched = key
        fn = compile_kernel(chain.joints, chain.base, chain.tool, what=what, batched=batched)
        chain._kernels[key] = fn
    return fn


def _kernel(chain, what: str, batched: bool):
    return build_kernel(chain, (what, batched))


def _single(chain, q):
    """Return q as a list of n Python floats when q is one valid configuration, else None."""
    if type(q) is np.ndarray and q.shape == (chain._n,) and q.dtype == np.float64:
        vals = q.tolist()
    elif isinstance(q, (list, tuple)) and len(q) == chain._n:
        try:
            vals = [float(x) for x in q]
        except (TypeError, ValueError):
            return None
    else:
        return None
    s = sum(vals)
    if s - s != 0.0:  # NaN or inf somewhere
        return None
    return vals


_tls = threading.local()


def _work_buffers(n: int, width: int, m: int):
    """Per-thread kernel work buffers (width, m) and (n, m), reused across calls: fresh
    multi-megabyte buffers cost a page fault per 4 kB on first touch, which at B = 10⁴
    was a third of the batched Jacobian's time."""
    cache = getattr(_tls, "buffers", None)
    if cache is None:
        cache = _tls.buffers = {}
    key = (n, width, m)
    bufs = cache.get(key)
    if bufs is None:
        if len(cache) >= 4:  # a few (n, width, chunk) shapes; ~2.5 MB each at most
            cache.clear()
        bufs = cache[key] = (np.empty((width, m)), np.empty((n, m)))
    return bufs


def _run(chain, q, what: str, width: int):
    """Evaluate a kernel; returns (flat values (..., width), batch shape)."""
    vals = _single(chain, q)
    if vals is not None:
        return np.array(_kernel(chain, what, False)(*vals)), ()
    a = chain.check_q(q)
    batch = a.shape[:-1]
    if batch == ():
        return np.array(_kernel(chain, what, False)(*a.tolist())), ()
    flat = a.reshape(-1, chain._n)
    B = flat.shape[0]
    out = np.empty((B, width))
    kern = _kernel(chain, what, True)
    m0 = min(B, _CHUNK)
    buf, qbuf = _work_buffers(chain._n, width, m0)
    for start in range(0, B, _CHUNK):
        stop = min(start + _CHUNK, B)
        m = stop - start
        if m == m0:
            b, qc = buf, qbuf
        else:
            b, qc = np.empty((width, m)), np.empty((chain._n, m))
        qc[...] = flat[start:stop].T
        kern(qc, b, start == 0 or b is not buf)
        out[start:stop] = b.T
    return out, batch


def fk(chain, q) -> np.ndarray:
    """Pose of the tool in the world, ``T_world_tool = base · A_1 ⋯ A_n · tool``, (..., 4, 4)."""
    vals, batch = _run(chain, q, "fk", 16)
    return vals.reshape(batch + (4, 4))


def _check_frame(frame):
    if frame not in _FRAMES:
        raise InputError(f"frame must be 'base' or 'tool', got {frame!r}",
                         argument="frame", value=frame)


def _check_point(point):
    p = np.asarray(point, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputError("point must be a finite 3-vector in tool-frame coordinates [m], "
                         f"got {point!r}", argument="point", value=point)
    return p


def shift_jacobian(J, r) -> np.ndarray:
    """Refer a base-axes Jacobian's linear rows to a point displaced by ``r`` [m] (base axes).

    ``v' = v + ω × r``, so ``J_v' = J_v − [r]× J_ω``.
    """
    J = np.asarray(J, dtype=float)
    r = np.asarray(r, dtype=float)
    out = J.copy()
    Jw = J[..., 3:, :]
    rx, ry, rz = r[..., 0, None], r[..., 1, None], r[..., 2, None]
    out[..., 0, :] -= ry * Jw[..., 2, :] - rz * Jw[..., 1, :]
    out[..., 1, :] -= rz * Jw[..., 0, :] - rx * Jw[..., 2, :]
    out[..., 2, :] -= rx * Jw[..., 1, :] - ry * Jw[..., 0, :]
    return out


def rotate_jacobian(J, R) -> np.ndarray:
    """Express a Jacobian's rows in the axes of a frame with world rotation ``R``: blockdiag(Rᵀ, Rᵀ)·J."""
    J = np.asarray(J, dtype=float)
    Rt = np.swapaxes(np.asarray(R, dtype=float), -1, -2)
    out = np.empty(np.broadcast_shapes(J.shape, Rt.shape[:-2] + J.shape[-2:]))
    out[..., :3, :] = Rt @ J[..., :3, :]
    out[..., 3:, :] = Rt @ J[..., 3:, :]
    return out


def _post(J, T, frame, point):
    if point is not None:
        p = _check_point(point)
        J = shift_jacobian(J, T[..., :3, :3] @ p)
    if frame == "tool":
        J = rotate_jacobian(J, T[..., :3, :3])
    return J


def jacobian(chain, q, *, frame: str = "base", point=None) -> np.ndarray:
    """Geometric Jacobian ``J(q)`` (..., 6, n) with rows ``[v; ω]``.

    Args:
        frame: ``"base"``: rows in world axes (default); ``"tool"``: in tool axes.
        point: reference point of the linear rows, given in tool-frame coordinates
            [m]; default the tool origin.
    """
    n = chain._n
    if frame == "base" and point is None:
        vals, batch = _run(chain, q, "jac", 6 * n)
        return vals.reshape(batch + (6, n))
    _check_frame(frame)
    T, J = fk_jacobian(chain, q)
    return _post(J, T, frame, point)


def fk_jacobian(chain, q, *, frame: str = "base", point=None):
    """``(T_world_tool, J)`` evaluated together; see :func:`fk` and :func:`jacobian`."""
    n = chain._n
    vals, batch = _run(chain, q, "fkjac", 16 + 6 * n)
    T = vals[..., :16].reshape(batch + (4, 4))
    J = vals[..., 16:].reshape(batch + (6, n))
    if frame == "base" and point is None:
        return T, J
    _check_frame(frame)
    return T, _post(J, T, frame, point)


def _motion(kind: str, q: np.ndarray) -> np.ndarray:
    M = np.zeros(q.shape + (4, 4))
    M[..., 3, 3] = 1.0
    if kind == "revolute":
        c, s = np.cos(q), np.sin(q)
        M[..., 0, 0] = c
        M[..., 0, 1] = -s
        M[..., 1, 0] = s
        M[..., 1, 1] = c
        M[..., 2, 2] = 1.0
    else:
        M[..., 0, 0] = M[..., 1, 1] = M[..., 2, 2] = 1.0
        M[..., 2, 3] = q
    return M


def _all_frames(chain, q):
    """(DH frames (..., n+1, 4, 4), joint frames T_{i-1}·P_i (..., n, 4, 4), tool pose)."""
    a = chain.check_q(q)
    batch = a.shape[:-1]
    n = chain._n
    Ts = np.empty(batch + (n + 1, 4, 4))
    Js = np.empty(batch + (n, 4, 4))
    T = np.broadcast_to(chain.base, batch + (4, 4))
    Ts[..., 0, :, :] = T
    for i, joint in enumerate(chain.joints):
        Tj = T @ joint.pre
        Js[..., i, :, :] = Tj
        T = Tj @ _motion(joint.kind, a[..., i]) @ joint.post
        Ts[..., i + 1, :, :] = T
    return Ts, Js, T @ chain.tool


def frames(chain, q) -> np.ndarray:
    """World poses of the DH frames ``T_0 … T_n`` (..., n+1, 4, 4); ``T_0`` is the base.

    For standard DH, joint i moves about the z axis of frame i−1 (``T[..., i-1]``);
    for modified DH about the z axis of frame i.
    """
    return _all_frames(chain, q)[0]


def joint_axes(chain, q):
    """Unit world axis ``z_i`` (..., n, 3) and a point ``o_i`` on it (..., n, 3) of every joint."""
    _, Js, _ = _all_frames(chain, q)
    return Js[..., :3, 2].copy(), Js[..., :3, 3].copy()


def jacobian_dot(chain, q, qd, *, frame: str = "base", point=None) -> np.ndarray:
    """Time derivative of the geometric Jacobian along the motion ``q̇``, (..., 6, n).

    With ω_i = Σ_{j<i, revolute} z_j q̇_j the angular velocity of the body carrying
    axis i, ż_i = ω_i × z_i, ȯ_i the velocity of the point o_i (fixed on that body)
    and ṗ = J_v q̇ the tool velocity:

    * revolute:  ``[ ż_i × (p − o_i) + z_i × (ṗ − ȯ_i) ; ż_i ]``
    * prismatic: ``[ ż_i ; 0 ]``

    The tool acceleration is ``ξ̇ = J q̈ + J̇ q̇``.
    """
    _check_frame(frame)
    a = chain.check_q(q)
    qd = chain.check_q(qd, name="qd")
    a, qd = np.broadcast_arrays(a, qd)
    _, Js, Ttool = _all_frames(chain, a)
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
        pt = _check_point(point)
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


def joint_torques(chain, q, wrench, *, frame: str = "base", point=None) -> np.ndarray:
    """Static joint torques ``τ = Jᵀ F`` balancing a tool wrench ``F = [f; τ]`` [N; N·m].

    The wrench is expressed in the same axes (``frame``) and at the same point as the
    Jacobian. Returns (..., n) in N·m (revolute) or N (prismatic).
    """
    J = jacobian(chain, q, frame=frame, point=point)
    F = np.asarray(wrench, dtype=float)
    if F.shape[-1:] != (6,) or not np.all(np.isfinite(F)):
        raise InputError(f"wrench must be finite with shape (..., 6) = [f; τ], got {F.shape}",
                         argument="wrench", value=wrench)
    return np.einsum("...ji,...j->...i", J, F)


def numerical_jacobian(chain, q, *, step: float = 1e-6) -> np.ndarray:
    """Central finite-difference Jacobian of :meth:`Chain.fk` (6, n), for checking.

    Linear rows: ``(p(q + h e_i) − p(q − h e_i)) / 2h``; angular rows:
    ``vee(Ṙ Rᵀ)`` with ``Ṙ`` by the same central difference. Error O(h²) + O(ε/h).
    """
    a = chain.check_q(q)
    if a.ndim != 1:
        raise InputError("numerical_jacobian takes one configuration (n,)", argument="q", value=q)
    n = chain.dof
    E = np.eye(n) * step
    Tp = chain.fk(a + E)
    Tm = chain.fk(a - E)
    R = chain.fk(a)[:3, :3]
    J = np.empty((6, n))
    J[:3] = ((Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * step)).T
    W = ((Tp[:, :3, :3] - Tm[:, :3, :3]) / (2 * step)) @ R.T
    J[3] = 0.5 * (W[:, 2, 1] - W[:, 1, 2])
    J[4] = 0.5 * (W[:, 0, 2] - W[:, 2, 0])
    J[5] = 0.5 * (W[:, 1, 0] - W[:, 0, 1])
    return J
