"""The plain reference implementation of the kinematics: 4×4 products, joint by joint.

``T_i = T_{i-1} · P_i · M_i(q_i) · Q_i`` evaluated literally with numpy (batched over
leading dimensions), and the geometric Jacobian built column by column from each
joint's world axis ``z_i`` and a point ``o_i`` on it:

* revolute:  ``J_i = [ z_i × (p − o_i) ; z_i ]``
* prismatic: ``J_i = [ z_i ; 0 ]``

This is the readable definition the generated kernels (`ratectl.kinematics.codegen`)
are checked against, the path for frames and joint axes, and what runs when
``RATECTL_KERNELS=reference`` is set (see `ratectl.kinematics.use_reference`) —
for stepping through the kinematics in a debugger.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["frames", "joint_axes", "reference_fk_jacobian", "numerical_jacobian", "MAX_PRISMATIC",
           "check_prismatic_range"]


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


#: Largest |q| [m] of a prismatic joint (like the 1e9 m cap on link lengths): far beyond
#: any robot, and small enough that poses, Jacobians and the products of singular values
#: (manipulability) stay in floating-point range; a larger q is refused with an InputError.
MAX_PRISMATIC = 1e9


def check_prismatic_range(chain: Chain, a: np.ndarray) -> None:
    """Refuse prismatic joint values beyond ±`MAX_PRISMATIC` m in ``a`` (..., n)."""
    pr = chain.prismatic
    if pr.any():
        v = np.abs(a[..., pr])
        if v.size and not float(v.max()) <= MAX_PRISMATIC:
            idx = np.flatnonzero(pr)
            j = int(idx[np.argmax(v.reshape(-1, idx.size).max(axis=0))])
            raise InputError(f"q[{j}] of prismatic joint {chain.joint_names[j]!r} is "
                             f"{float(v.max()):.3g} m; prismatic joint values must be within "
                             f"±{MAX_PRISMATIC:.0e} m (beyond, poses overflow floating point)",
                             argument="q", value=a)


def all_frames(chain: Chain, q: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(DH frames (..., n+1, 4, 4), joint frames T_{i-1}·P_i (..., n, 4, 4), tool pose)."""
    a = chain.check_q(q)
    check_prismatic_range(chain, a)
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


def frames(chain: Chain, q: ArrayLike) -> np.ndarray:
    """World poses of the DH frames ``T_0 … T_n`` (..., n+1, 4, 4); ``T_0`` is the base.

    For standard DH, joint i moves about the z axis of frame i−1 (``T[..., i-1]``);
    for modified DH about the z axis of frame i.
    """
    return all_frames(chain, q)[0]


def joint_axes(chain: Chain, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Unit world axis ``z_i`` (..., n, 3) and a point ``o_i`` on it (..., n, 3) of every joint."""
    _, Js, _ = all_frames(chain, q)
    return Js[..., :3, 2].copy(), Js[..., :3, 3].copy()


def reference_fk_jacobian(chain: Chain, q: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """``(T_world_tool (..., 4, 4), J (..., 6, n))`` by the literal recursion (no generated code)."""
    Ts, Js, T = all_frames(chain, q)
    z = Js[..., :3, 2]
    o = Js[..., :3, 3]
    p = T[..., :3, 3]
    lin = np.cross(z, p[..., None, :] - o)
    prismatic = np.asarray(chain.prismatic)
    lin = np.where(prismatic[:, None], z, lin)
    ang = np.where(prismatic[:, None], 0.0, z)
    J = np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(ang, -1, -2)], axis=-2)
    return T, J


def numerical_jacobian(chain: Chain, q: ArrayLike, *, step: float = 1e-6) -> np.ndarray:
    """Central finite-difference Jacobian of `Chain.fk` (6, n), for checking.

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
