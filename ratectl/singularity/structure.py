"""Arm structure: which joint axes stay parallel or intersect, the spherical wrist, and the
geometric factors (sines of angles between axes) that name a singularity.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..kinematics import shift_jacobian
from .measures import _TINY

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ['structure', 'ArmStructure']


def _cross(a, b):
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _norm(a):
    return np.sqrt(_dot(a, a))


# ====================================================================== arm structure
@dataclass(frozen=True)
class ArmStructure:
    """What the classifier knows about an arm's geometry (fixed for all q).

    Attributes:
        dof: number of joints n.
        revolute: tuple of bools, one per joint.
        wrist: indices (0-based) of the last three joints if they are revolute, else None.
        spherical_wrist: the last three axes meet in one point for every q.
        elbow: (a, b): the first pair of consecutive revolute arm joints whose axes are
            parallel for every q, or None.
        elbow_point: (b+1, b+2) — the point P of the elbow test is the point on axis
            b+1 closest to axis b+2 — or None (P is then the wrist point).
        shoulder: joints 1 and 2 are revolute and their axes are never parallel.
        wrist_point: (n−2, n−1): the wrist point W is the point on axis n−2 closest to
            axis n−1 (their intersection when they meet), or None (W = tool origin).
        arm_joints: the joints that position the wrist point (all but the last three
            for n ≥ 6, all joints for n < 6).
        named: the wrist/elbow/shoulder names apply (n = 6).
    """

    dof: int
    revolute: tuple
    wrist: tuple | None
    spherical_wrist: bool
    elbow: tuple | None
    elbow_point: tuple | None
    shoulder: bool
    wrist_point: tuple | None
    arm_joints: tuple
    named: bool


_STRUCTURES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _lines(J):
    """Unit axes z (..., n, 3) and a point c on each axis relative to the reference point."""
    Jv = np.swapaxes(J[..., :3, :], -1, -2)
    z = np.swapaxes(J[..., 3:, :], -1, -2)
    return z, _cross(z, Jv)


def _closest_point(pa, da, pb, db):
    """Point on line (pa, da) closest to line (pb, db); pa where the lines are parallel."""
    w = pa - pb
    b = _dot(da, db)
    d = _dot(da, w)
    e = _dot(db, w)
    den = 1.0 - b * b
    ok = den > 1e-12
    t = np.where(ok, (b * e - d) / np.where(ok, den, 1.0), 0.0)
    return pa + t[..., None] * da


def structure(chain: Chain) -> ArmStructure:
    """Detect the arm's structure from its model (cached per chain).

    The tests are geometric, on the joint axes at a few random configurations (fixed
    seed): axes parallel (|z_a × z_b| < 1e-9) or concurrent (the three wrist axes pass
    within 1e-9·L of one point) at every sample are structural properties.
    """
    s = _STRUCTURES.get(chain)
    if s is not None:
        return s
    n = chain.dof
    L = chain.characteristic_length
    rev = tuple(not p for p in chain.prismatic)
    qs = chain.random_q(5, rng=20240611)
    z, c = _lines(chain.jacobian(qs))

    def always_parallel(a: ArrayLike, b: ArrayLike):
        return bool(np.all(_norm(_cross(z[:, a], z[:, b])) < 1e-9))

    def never_parallel(a: ArrayLike, b: ArrayLike):
        return bool(np.all(_norm(_cross(z[:, a], z[:, b])) > 1e-6))

    wrist = (n - 3, n - 2, n - 1) if n >= 6 and all(rev[n - 3:]) else None
    spherical = False
    if wrist is not None:
        # least-squares point of the three lines: Σ (I − z zᵀ)(x − c) = 0
        P = np.eye(3) - z[:, n - 3:, :, None] * z[:, n - 3:, None, :]
        A = P.sum(axis=1)
        rhs = np.einsum("bkij,bkj->bi", P, c[:, n - 3:])
        if np.all(np.linalg.det(A) > 1e-9):
            x = np.linalg.solve(A, rhs[..., None])[..., 0]
            resid = _norm(np.einsum("bkij,bkj->bki", P, x[:, None, :] - c[:, n - 3:]))
            spherical = bool(np.all(resid < 1e-9 * L))
    arm = tuple(range(n - 3)) if n >= 6 else tuple(range(n))
    elbow = None
    for a in arm[:-1]:
        b = a + 1
        if rev[a] and rev[b] and always_parallel(a, b):
            gap = _norm(_cross(z[:, a], c[:, b] - c[:, a]))
            if np.all(gap > 1e-9 * L):
                elbow = (a, b)
                break
    elbow_point = None
    if elbow is not None and elbow[1] + 2 < n and rev[elbow[1] + 1] and rev[elbow[1] + 2] \
            and never_parallel(elbow[1] + 1, elbow[1] + 2):
        elbow_point = (elbow[1] + 1, elbow[1] + 2)
    shoulder = n >= 2 and rev[0] and rev[1] and never_parallel(0, 1)
    wrist_point = (n - 2, n - 1) if n >= 3 and rev[n - 2] and rev[n - 1] and never_parallel(n - 2, n - 1) \
        else None
    s = ArmStructure(dof=n, revolute=rev, wrist=wrist, spherical_wrist=spherical, elbow=elbow,
                     elbow_point=elbow_point, shoulder=bool(shoulder), wrist_point=wrist_point,
                     arm_joints=arm, named=(n == 6))
    _STRUCTURES[chain] = s
    return s


# ====================================================================== batched core
def _geometry(J, st: ArmStructure, L: float, need_arm=None):
    """Wrist point W (relative to the reference point), factors and the arm block, batched.

    Returns a dict with arrays over the batch: ``W`` (..., 3); ``wrist``, ``elbow``,
    ``shoulder`` factors (NaN where not applicable); ``elbow_stretched`` (bool);
    ``arm_sigma_min`` σ_min of the arm joints' linear block at W divided by L.
    """
    batch = J.shape[:-2]
    z, c = _lines(J)
    nan = np.full(batch, np.nan)
    if st.wrist_point is not None:
        i, k = st.wrist_point
        W = _closest_point(c[..., i, :], z[..., i, :], c[..., k, :], z[..., k, :])
    else:
        W = np.zeros(batch + (3,))
    out = {"W": W, "wrist": nan, "elbow": nan, "shoulder": nan,
           "elbow_stretched": np.zeros(batch, dtype=bool)}
    if st.wrist is not None:
        a, b, k = st.wrist
        out["wrist"] = np.abs(_dot(z[..., a, :], _cross(z[..., b, :], z[..., k, :])))
    if st.elbow is not None:
        a, b = st.elbow
        if st.elbow_point is not None:
            i, k = st.elbow_point
            P = _closest_point(c[..., i, :], z[..., i, :], c[..., k, :], z[..., k, :])
        else:
            P = W
        za, zb = z[..., a, :], z[..., b, :]
        ab = c[..., b, :] - c[..., a, :]
        ab_perp = ab - za * _dot(za, ab)[..., None]
        m = _cross(za, ab)
        m /= np.maximum(_norm(m), _TINY)[..., None]
        bp = P - c[..., b, :]
        r = bp - zb * _dot(zb, bp)[..., None]
        out["elbow"] = np.abs(_dot(m, P - c[..., a, :])) / np.maximum(_norm(r), _TINY)
        out["elbow_stretched"] = _dot(r, ab_perp) > 0
    if st.shoulder:
        z0, z1 = z[..., 0, :], z[..., 1, :]
        ns = _cross(z0, z1)
        ns /= np.maximum(_norm(ns), _TINY)[..., None]
        rel = W - c[..., 0, :]
        radial = rel - z0 * _dot(z0, rel)[..., None]
        out["shoulder"] = np.abs(_dot(ns, rel)) / L
        out["shoulder_offset"] = _dot(ns, rel)
        out["shoulder_radial"] = _norm(radial)
    # the arm joints' linear block at W (for "boundary"); only where ``need_arm`` is set
    cols = list(st.arm_joints)
    arm = np.full(batch, np.inf)
    need = np.ones(batch, dtype=bool) if need_arm is None else need_arm
    if np.any(need):
        Jn = J[need][..., :, cols]
        JW = shift_jacobian(Jn, W[need]) if st.wrist_point is not None else Jn
        arm[need] = np.linalg.svd(JW[..., :3, :], compute_uv=False)[..., -1] / L
    out["arm_sigma_min"] = arm
    return out
