"""The joint path q(s) along a Cartesian path: integrated tangents, corrected onto the path
by Newton steps (step 1 of the governor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, RatectlError
from ..singularity import analyze
from ..spatial import pose_error

__all__ = ['JointPath', 'joint_path']


# ---------------------------------------------------------------------- joint path
@dataclass(frozen=True)
class JointPath:
    """The joint path q(s) along a Cartesian path (step 1 of the governor).

    Attributes:
        s: (N,) path parameters [m], increasing from 0.
        q: (N, n) joint positions with fk(q[k]) = P(s[k]) (to ~1e-10).
        dq: (N, n) q'(s) = dq/ds [rad/m].
        ddq: (N, n) q''(s) [rad/m²].
        sigma_min: (N,) smallest singular value of J along the path.
        complete: True when the whole path was integrated.
        message: why the integration stopped early ("" when complete).
    """

    s: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    sigma_min: np.ndarray
    complete: bool
    message: str = ""

    def interpolate(self, s) -> np.ndarray:
        """q at path parameters ``s`` (scalar or (M,)) by cubic Hermite interpolation of q, q'."""
        s = np.asarray(s, dtype=float)
        flat = np.atleast_1d(s)
        grid = self.s
        k = np.clip(np.searchsorted(grid, flat, side="right") - 1, 0, len(grid) - 2)
        h = grid[k + 1] - grid[k]
        u = np.clip((flat - grid[k]) / h, 0.0, 1.0)[:, None]
        h = h[:, None]
        u2, u3 = u * u, u * u * u
        h00, h10, h01, h11 = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2
        out = (h00 * self.q[k] + h10 * h * self.dq[k] + h01 * self.q[k + 1] + h11 * h * self.dq[k + 1])
        return out[0] if s.ndim == 0 else out

    def derivatives(self, s):
        """(q'(s), q''(s)) at ``s`` (M,) by linear interpolation of the grid values."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        d1 = np.stack([np.interp(s, self.s, self.dq[:, i]) for i in range(self.dq.shape[1])], axis=1)
        d2 = np.stack([np.interp(s, self.s, self.ddq[:, i]) for i in range(self.ddq.shape[1])], axis=1)
        return d1, d2


def _pinv_step(J, v, *, redundant: bool):
    """Minimum-norm solution of J x = v (exact solve when square)."""
    if not redundant:
        return np.linalg.solve(J, v)
    return J.T @ np.linalg.solve(J @ J.T, v)


def _tangent(J, t, z, *, redundant: bool):
    """q' = J⁺ t + (I − J⁺J) z (the second term only for redundant arms)."""
    if not redundant:
        return np.linalg.solve(J, t)
    JJt = J @ J.T
    x = J.T @ np.linalg.solve(JJt, t)
    if z is not None:
        x = x + z - J.T @ np.linalg.solve(JJt, J @ z)
    return x


def _kind(chain, q) -> str | None:
    """The singularity kind from `ratectl.analyze` (None if unavailable)."""
    try:
        return str(analyze(chain, q).kind)
    except RatectlError:  # the kind only decorates a message
        return None


def joint_path(chain, path, q0, *, max_joint_step: float = 0.004, max_step: float | None = None,
               sigma_tolerance: float = 1e-3, nullspace_gain: float = 1.0, pose_tolerance: float = 1e-4,
               max_points: int = 200000) -> JointPath:
    """Integrate the joint path q(s) along ``path`` from ``q0`` (step 1 of the governor).

    Args:
        chain: the arm.
        path: a `ratectl.paths.Path`.
        q0: joint positions at the start (fk(q0) must be within ``pose_tolerance``
            [m / rad] of the path start; it is corrected onto it by Newton iterations).
        max_joint_step: largest joint change per integration step [rad].
        max_step: largest step in s [m] (default length/200).
        sigma_tolerance: stop where σ_min(J) drops below this (workspace boundary / singular).
        nullspace_gain: k of the joint-centring null-space term for redundant arms [1/m].
    """
    q = chain.check_q(q0).astype(float).copy()
    if q.ndim != 1:
        raise InputError(f"q0 must be one configuration (n,), got shape {q.shape}", argument="q0", value=q0)
    n = chain.dof
    redundant = n > 6
    L = path.length
    max_step = max_step or max(L / 200.0, 1e-6)
    lo, hi = chain.lower, chain.upper
    finite = np.isfinite(lo) & np.isfinite(hi)
    lo0, hi0 = np.where(finite, lo, 0.0), np.where(finite, hi, 0.0)
    mid = 0.5 * (lo0 + hi0)
    half = np.where(finite, 0.5 * (hi0 - lo0), np.inf)
    wgt = np.where(finite, 1.0 / half, 0.0)

    def z_of(q):
        if not redundant or nullspace_gain == 0.0:
            return None
        return -nullspace_gain * wgt * wgt * (q - mid)

    def correct(q, Td, iters=8):
        for _ in range(iters):
            T, J = chain.fk_jacobian(q)
            e = pose_error(Td, T)
            if np.max(np.abs(e)) < 1e-11:
                return q, True
            q = q + _pinv_step(J, e, redundant=redundant)
        T = chain.fk(q)
        return q, bool(np.max(np.abs(pose_error(Td, T))) < 1e-8)

    T0 = chain.fk(q)
    err0 = pose_error(path.pose_at(0.0), T0)
    if np.linalg.norm(err0[:3]) > pose_tolerance or np.linalg.norm(err0[3:]) > pose_tolerance * 10:
        ang = math.degrees(np.linalg.norm(err0[3:]))
        raise InputError("q0 is not at the start of the path: tool is "
                         f"{np.linalg.norm(err0[:3]) * 1e3:.3g} mm / {ang:.3g}° "
                         "away; move there first (ratectl.smoothing.move) or pass a matching q0",
                         argument="q0", value=q0)
    q, _ = correct(q, path.pose_at(0.0))

    S, Q, D, SIG = [], [], [], []
    s = 0.0
    complete, message = True, ""
    while True:
        T, J = chain.fk_jacobian(q)
        sig = np.linalg.svd(J, compute_uv=False)
        smin = float(sig[-1]) if len(sig) >= min(6, n) else 0.0
        if smin < sigma_tolerance:
            complete = False
            kind = _kind(chain, q)
            message = (f"{kind + ' ' if kind else ''}singularity (sigma_min = {smin:.2e} < "
                       f"{sigma_tolerance:.0e}) at s = {s:.6g} m of {L:.6g} m, {(L - s) * 1e3:.3g} mm "
                       "before the end: the path cannot be followed further")
            if not S:
                D.append(np.zeros(n))
            break
        dq = _tangent(J, path.twist_at(s), z_of(q), redundant=redundant)
        S.append(s)
        Q.append(q.copy())
        D.append(dq)
        SIG.append(smin)
        if s >= L or len(S) >= max_points:
            if s < L:
                complete, message = False, f"too many integration points ({max_points}) at s = {s:.6g} m"
            break
        h = min(max_step, L - s, max_joint_step / max(float(np.max(np.abs(dq))), 1e-12))
        ok = False
        while h > 1e-12:
            s1 = min(s + h, L)
            if L - s1 < 1e-12:
                s1 = L
            # Heun predictor, then Newton onto the exact pose
            qp = q + (s1 - s) * dq
            _, Jp = chain.fk_jacobian(qp)
            try:
                dqp = _tangent(Jp, path.twist_at(s1), z_of(qp), redundant=redundant)
                qn = q + 0.5 * (s1 - s) * (dq + dqp)
                qn, ok = correct(qn, path.pose_at(s1))
            except np.linalg.LinAlgError:
                ok = False
            if ok and np.max(np.abs(qn - q)) <= 2.5 * max_joint_step + 1e-9:
                break
            ok = False
            h *= 0.5
        if not ok:
            complete = False
            message = (f"cannot follow the path beyond s = {s:.6g} m of {L:.6g} m "
                       f"(sigma_min = {smin:.2e}): Newton iterations do not converge")
            break
        q, s = qn, s1
    S = np.array(S)
    Q = np.array(Q).reshape(-1, n)
    D = np.array(D[: len(S)]).reshape(-1, n)
    DD = np.zeros_like(D)
    if len(S) >= 3:
        DD[1:-1] = (D[2:] - D[:-2]) / (S[2:] - S[:-2])[:, None]
        DD[0] = (D[1] - D[0]) / (S[1] - S[0])
        DD[-1] = (D[-1] - D[-2]) / (S[-1] - S[-2])
    elif len(S) == 2:
        DD[:] = (D[1] - D[0]) / (S[1] - S[0])
    return JointPath(S, Q, D, DD, np.array(SIG), complete, message)
