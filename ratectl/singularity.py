"""Singularity analysis: measures, classification, explanations and workspace scans.

Measures (all batched over the leading dimensions of a (..., 6, n) Jacobian):

* singular values σ₁ ≥ … ≥ σ_m, m = min(6, n), and the rank with an explicit tolerance;
* Yoshikawa manipulability w = σ₁σ₂⋯σ_m, i.e. √det(J Jᵀ) for n ≥ 6 and √det(Jᵀ J) for
  n < 6 (where √det(J Jᵀ) would be identically zero);
* condition number κ = σ₁/σ_m and its inverse σ_m/σ₁ ∈ [0, 1];
* translational and rotational sub-measures, from the linear rows J_v and the
  angular rows J_ω alone (each is unit-homogeneous);
* unit-consistent variants: the linear rows are divided by a characteristic length L
  [m] (default ``chain.characteristic_length``), J_L = diag(I/L, I)·J, so that every
  entry is dimensionless and σ_min(J_L) is comparable between arms and between
  translation and rotation.

:func:`analyze` returns a :class:`SingularityReport` for one configuration: the
measures, the rank, the lost task-space directions and joint-space null vectors, the
kind of singularity ("regular", "wrist", "elbow", "shoulder", "boundary",
"rank-deficient"), a numeric closeness and a plain-language reason. :func:`scan` does
the measures and the classification for many configurations at once.

Classification (see ``docs/singularity.md`` for the derivation). Everything is computed
from the Jacobian referred to the tool origin: the world axis of a revolute joint i is
``z_i = J_ω,i`` and ``c_i = z_i × J_v,i`` is a point on it (relative to the tool origin),
so the geometry of all joint axes comes for free with J. For 6-joint arms, three
dimensionless factors vanish exactly at the classic singularities:

* wrist: ``|det[z₄ z₅ z₆]|`` — the wrist axes linearly dependent (for a spherical
  wrist this is |det J₂₂|);
* elbow: for the first pair of consecutive arm axes that are parallel for every q
  (the "elbow pair" a, b), the sine of the angle between the plane of the two axes and
  the direction from axis b to the point P where the next axis meets the one after it
  (PUMA: the wrist centre; UR: the point o₄ on axis 4) — upper arm and forearm aligned;
* shoulder: the distance of the wrist point W (the point where the last two axes
  meet) from the plane through axis 1 parallel to axis 2, divided by L — the wrist
  point over the shoulder (with a shoulder offset W is then not on axis 1 itself).

A configuration is *near-singular* when σ_min(J_L) < ``near``; it is then labelled with
the smallest factor if that factor is below ``factor_tol``, else "boundary" when the arm
joints cannot move the wrist point in some direction (σ_min of their linear block at W
divided by L is below ``near``), else "rank-deficient". Arms with n ≠ 6 get only the
last two labels. Whether the configuration is exactly singular is the rank test
σ_i(J_L) ≤ rtol·σ₁(J_L).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .errors import InputError
from .hessian import hessian_from_jacobian
from .kinematics import shift_jacobian

__all__ = [
    "KINDS",
    "singular_values",
    "manipulability",
    "condition_number",
    "rank",
    "analyze",
    "classify",
    "SingularityReport",
    "scan",
    "ScanResult",
    "manipulability_gradient",
    "path_distance",
    "PathDistance",
    "fixed_lost_directions",
    "structure",
    "ArmStructure",
    "workspace_map",
    "WorkspaceMap",
    "plot_workspace_map",
]

#: Singularity kinds; ``ScanResult.kind_code`` indexes this tuple.
KINDS = ("regular", "wrist", "elbow", "shoulder", "boundary", "rank-deficient")
_REGULAR, _WRIST, _ELBOW, _SHOULDER, _BOUNDARY, _RANKDEF = range(6)

DEFAULT_RTOL = 1e-8  # rank: σ_i(J_L) > rtol·σ₁(J_L)
DEFAULT_NEAR = 0.01  # near-singular: σ_min(J_L) < near (dimensionless; κ(J_L) ≳ 100-200)
DEFAULT_FACTOR_TOL = 0.2  # a geometric factor (sine of an angle) below this names the kind

_TINY = 1e-300


# ====================================================================== measures from J
def _as_jacobian(J, name="J") -> np.ndarray:
    a = np.asarray(J, dtype=float)
    if a.ndim < 2 or a.shape[-1] < 1 or a.shape[-2] < 1:
        raise InputError(f"{name} must have shape (..., m, n), typically (..., 6, n); got {a.shape}",
                         argument=name, value=J)
    return a


def _scaled(J: np.ndarray, length) -> np.ndarray:
    """J_L = diag(I/L, I)·J for a 6-row Jacobian; J itself when length is None."""
    if length is None:
        return J
    L = float(length)
    if not (L > 0 and math.isfinite(L)):
        raise InputError(f"length must be a positive characteristic length [m], got {length!r}",
                         argument="length", value=length)
    if J.shape[-2] != 6:
        raise InputError(f"length scaling needs a (..., 6, n) Jacobian, got {J.shape}",
                         argument="J", value=J)
    out = J.copy()
    out[..., :3, :] /= L
    return out


def singular_values(J, *, length: float | None = None) -> np.ndarray:
    """Singular values σ₁ ≥ … ≥ σ_m of J, (..., m) with m = min(rows, n).

    Args:
        J: Jacobian (..., 6, n) (or any (..., r, n) matrix when ``length`` is None).
        length: if given, the characteristic length L [m]: the singular values of
            J_L = diag(I/L, I)·J (dimensionless) are returned.
    """
    return np.linalg.svd(_scaled(_as_jacobian(J), length), compute_uv=False)


def manipulability(J, *, length: float | None = None) -> np.ndarray:
    """Yoshikawa manipulability w = σ₁⋯σ_m, (...,).

    w = √det(J Jᵀ) when J has at least as many columns as rows (n ≥ 6), and
    √det(Jᵀ J) otherwise (for n < 6, √det(J Jᵀ) is identically 0). Units: product of
    the singular values' units (m³/rad⁶ · … for the raw 6×n J); dimensionless for J_L.
    """
    A = _scaled(_as_jacobian(J), length)
    G = A @ np.swapaxes(A, -1, -2) if A.shape[-1] >= A.shape[-2] else np.swapaxes(A, -1, -2) @ A
    return np.sqrt(np.maximum(np.linalg.det(G), 0.0))


def condition_number(J, *, length: float | None = None, inverse: bool = False) -> np.ndarray:
    """Condition number κ = σ₁/σ_m (inf where σ_m = 0), or its inverse σ_m/σ₁ ∈ [0, 1].

    Args:
        J: Jacobian (..., 6, n) or any (..., r, n).
        length: characteristic length L [m] for the unit-consistent κ(J_L). The raw κ(J)
            mixes m/rad and rad/rad and changes with the choice of units.
        inverse: return 1/κ (0 at a singularity, well-behaved for plotting).
    """
    s = singular_values(J, length=length)
    return _cond(s[..., 0], s[..., -1], inverse)


def _cond(smax, smin, inverse):
    if inverse:
        return np.divide(smin, smax, out=np.zeros_like(smin), where=smax > 0)
    return np.divide(smax, smin, out=np.full_like(smax, np.inf), where=smin > 0)


def rank(J, *, length: float | None = None, rtol: float = DEFAULT_RTOL) -> np.ndarray:
    """Numerical rank: the number of σ_i > rtol·σ₁ (an int array of the batch shape)."""
    s = singular_values(J, length=length)
    return np.sum(s > rtol * s[..., :1], axis=-1)


def _others_product(s: np.ndarray) -> np.ndarray:
    """c_i = Π_{j≠i} s_j without division (exact at zeros), over the last axis."""
    m = s.shape[-1]
    left = np.ones_like(s)
    right = np.ones_like(s)
    for i in range(1, m):
        left[..., i] = left[..., i - 1] * s[..., i - 1]
        right[..., m - 1 - i] = right[..., m - i] * s[..., m - i]
    return left * right


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


def structure(chain) -> ArmStructure:
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

    def always_parallel(a, b):
        return bool(np.all(_norm(_cross(z[:, a], z[:, b])) < 1e-9))

    def never_parallel(a, b):
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


def _classify(sig_min_s, geo, st: ArmStructure, near, factor_tol):
    """Kind codes (int8 array) from the scaled σ_min and the geometric factors."""
    kind = np.zeros(sig_min_s.shape, dtype=np.int8)
    is_near = sig_min_s < near
    if st.named:
        names = [(code, geo[key]) for code, key in ((_WRIST, "wrist"), (_ELBOW, "elbow"),
                                                    (_SHOULDER, "shoulder"))
                 if not np.all(np.isnan(geo[key]))]
        if names:
            F = np.stack([np.nan_to_num(f, nan=np.inf) for _, f in names], axis=-1)
            idx = np.argmin(F, axis=-1)
            fmin = np.take_along_axis(F, idx[..., None], axis=-1)[..., 0]
            codes = np.array([code for code, _ in names], dtype=np.int8)
            named = is_near & (fmin < factor_tol)
            kind = np.where(named, codes[idx], kind)
    rest = is_near & (kind == _REGULAR)
    boundary = rest & (geo["arm_sigma_min"] < near)
    kind = np.where(boundary, _BOUNDARY, kind)
    kind = np.where(rest & ~boundary, _RANKDEF, kind)
    return kind.astype(np.int8)


def _check_options(chain, length, rtol, near, factor_tol):
    L = chain.characteristic_length if length is None else length
    try:
        L = float(L)
    except (TypeError, ValueError):
        raise InputError(f"length must be a positive length [m], got {length!r}",
                         argument="length", value=length) from None
    if not (L > 0 and math.isfinite(L)):
        raise InputError(f"length must be a positive, finite characteristic length [m], got {length!r}",
                         argument="length", value=length)
    for name, v in (("rtol", rtol), ("near", near), ("factor_tol", factor_tol)):
        if not (isinstance(v, (int, float)) and v >= 0 and math.isfinite(v)):
            raise InputError(f"{name} must be a non-negative finite number, got {v!r}",
                             argument=name, value=v)
    return L


def _fast_singular_values(A: np.ndarray, refine: float = 1e-3) -> np.ndarray:
    """Singular values (descending) of a batch A (B, r, c) via the eigenvalues of the smaller
    Gram matrix, with an SVD for the rows where σ_min < refine·σ_max.

    The eigenvalues λ of A Aᵀ carry an absolute error ~ε·σ_max², so √λ is accurate to
    ~1e-9 relative for σ ≥ 1e-3·σ_max; smaller singular values are recomputed by SVD
    (so exact singularities give σ_min ~ 1e-16, not ~1e-8). Deterministic per matrix:
    a batch gives the same numbers as one matrix at a time.
    """
    r, c = A.shape[-2:]
    At = np.swapaxes(A, -1, -2)
    G = A @ At if r <= c else At @ A
    lam = np.linalg.eigvalsh(G)[..., ::-1]
    s = np.sqrt(np.maximum(lam, 0.0))
    redo = s[..., -1] < refine * s[..., 0]
    if np.any(redo):
        s[redo] = np.linalg.svd(A[redo], compute_uv=False)
    return s


def _core(chain, J, L, rtol, near, factor_tol, raw):
    """All batched measures of J (B, 6, n) referred to the tool origin."""
    n = J.shape[-1]
    JL = J.copy()
    JL[..., :3, :] /= L
    s = _fast_singular_values(JL)
    smax, smin = s[..., 0], s[..., -1]
    w_s = np.prod(s, axis=-1)
    if n >= 6:
        w = w_s * L ** 3
    else:
        w = np.sqrt(np.maximum(np.linalg.det(np.swapaxes(J, -1, -2) @ J), 0.0))
    st = structure(chain)
    geo = _geometry(J, st, L, smin < near)
    kind = _classify(smin, geo, st, near, factor_tol)
    st_v = _fast_singular_values(J[..., :3, :])
    st_w = _fast_singular_values(J[..., 3:, :])
    out = dict(
        sigma_scaled=s, sigma_min_scaled=smin, manipulability=w, manipulability_scaled=w_s,
        condition_scaled=_cond(smax, smin, False),
        rank=np.sum(s > rtol * s[..., :1], axis=-1), kind_code=kind,
        sigma_translational=st_v, sigma_rotational=st_w,
        manipulability_translational=np.prod(st_v, axis=-1),
        manipulability_rotational=np.prod(st_w, axis=-1),
        condition_translational=_cond(st_v[..., 0], st_v[..., -1], False),
        condition_rotational=_cond(st_w[..., 0], st_w[..., -1], False),
        geo=geo,
    )
    if raw:
        sr = np.linalg.svd(J, compute_uv=False)
        out["sigma"] = sr
        out["condition"] = _cond(sr[..., 0], sr[..., -1], False)
    return out


def classify(chain, q=None, *, J=None, length: float | None = None, near: float = DEFAULT_NEAR,
             factor_tol: float = DEFAULT_FACTOR_TOL) -> tuple[str, float]:
    """Fast kind of one configuration: ``(kind, σ_min(J_L))`` — for control loops.

    The same classification as :func:`analyze` and :func:`scan` (identical results), but
    regular configurations cost one small eigenvalue problem (~20 µs) and the geometry
    is only evaluated when σ_min(J_L) < ``near``.

    Args:
        chain: the robot model.
        q: joint positions (n,); not needed when ``J`` is given.
        J: the Jacobian (6, n) at q (base axes, tool origin) if already computed.
        length, near, factor_tol: as in :func:`analyze`.
    """
    if J is None:
        if q is None:
            raise InputError("classify needs q or J", argument="q", value=None)
        J = chain.jacobian(q)
    else:
        J = np.asarray(J, dtype=float)
        if J.shape != (6, chain.dof):
            raise InputError(f"J must have shape (6, {chain.dof}), got {J.shape}", argument="J", value=J)
    L = chain.characteristic_length if length is None else _check_options(chain, length, 0.0, near,
                                                                           factor_tol)
    JL = J[None].copy()
    JL[..., :3, :] /= L
    smin = _fast_singular_values(JL)[..., -1]
    if smin[0] >= near:
        return "regular", float(smin[0])
    geo = _geometry(J[None], structure(chain), L, smin < near)
    return KINDS[int(_classify(smin, geo, structure(chain), near, factor_tol)[0])], float(smin[0])


# ====================================================================== the report
def _ro(a):
    a = np.asarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True)
class SingularityReport:
    """Singularity analysis of one configuration (see :func:`analyze`).

    Measures: ``sigma`` (raw singular values of J, mixed units), ``sigma_scaled``
    (of J_L = diag(I/L, I)·J, dimensionless), ``sigma_min``/``sigma_min_scaled``,
    ``manipulability`` (√det(J Jᵀ), n ≥ 6; √det(Jᵀ J), n < 6) and its scaled version,
    ``condition``/``condition_scaled`` (σ₁/σ_m, inf at a singularity) and
    ``inverse_condition`` (σ_m/σ₁ of J_L), translational (J_v, m/rad) and rotational
    (J_ω, rad/rad) sub-measures.

    Classification: ``kind`` ∈ :data:`KINDS`, ``singular`` (rank < min(6, n)),
    ``near_singular`` (σ_min(J_L) < ``near``), ``causes`` (every named kind whose factor
    is below ``factor_tol``), ``factors`` (the geometric factors of 6-joint arms, see the module docstring),
    ``joint_distance`` (first-order estimate σ_min(J_L)/‖∇_q σ_min(J_L)‖ [rad] of how far
    q is from the singular set), ``reason`` (plain language).

    Directions: ``lost_directions_task`` (6, k): an orthonormal basis of the task
    directions the arm cannot produce at q, in the scaled twist coordinates [v/L; ω]
    (multiply the first three rows by L for a twist in m/s; a pure translation or
    rotation is the same unit vector in both); ``null_space`` (n, n − rank): joint
    velocities that do not move the tool; ``weakest_direction_task`` and
    ``weakest_direction_joint``: the singular vectors of σ_min(J_L) (the direction being
    lost near a singularity).

    Spherical wrists (6 joints): ``wrist_center`` (world, m), ``det_arm`` = det J₁₁ and
    ``det_wrist`` = det J₂₂ of the Jacobian referred to the wrist centre (J₁₂ = 0 there,
    det J = det J₁₁·det J₂₂); None otherwise.
    """

    q: np.ndarray
    kind: str
    singular: bool
    near_singular: bool
    rank: int
    max_rank: int
    length: float
    sigma: np.ndarray
    sigma_scaled: np.ndarray
    sigma_min: float
    sigma_min_scaled: float
    manipulability: float
    manipulability_scaled: float
    condition: float
    condition_scaled: float
    inverse_condition: float
    sigma_translational: np.ndarray
    sigma_rotational: np.ndarray
    manipulability_translational: float
    manipulability_rotational: float
    condition_translational: float
    condition_rotational: float
    lost_directions_task: np.ndarray
    null_space: np.ndarray
    weakest_direction_task: np.ndarray
    weakest_direction_joint: np.ndarray
    joint_distance: float
    factors: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    causes: tuple = ()
    reason: str = ""
    spherical_wrist: bool = False
    wrist_point: np.ndarray | None = None
    wrist_center: np.ndarray | None = None
    det_arm: float | None = None
    det_wrist: float | None = None
    rtol: float = DEFAULT_RTOL
    near: float = DEFAULT_NEAR

    def __str__(self) -> str:
        return (f"{self.kind} (rank {self.rank}/{self.max_rank}, σ_min(J_L) = {self.sigma_min_scaled:.3g}, "
                f"≈{self.joint_distance:.3g} rad from singular): {self.reason}")


def _joint_phrase(idx) -> str:
    idx = [i + 1 for i in idx]
    if len(idx) == 1:
        return f"joint {idx[0]}"
    return "joints " + ", ".join(str(i) for i in idx[:-1]) + f" and {idx[-1]}"


def _direction_phrase(u: np.ndarray) -> str:
    """Describe a unit scaled-twist direction [v/L; ω] in words."""
    lin, ang = u[:3], u[3:]
    nl, na = float(np.linalg.norm(lin)), float(np.linalg.norm(ang))

    def vec(x):
        x = x / np.linalg.norm(x)
        return "[" + ", ".join(f"{v:+.2f}" for v in x) + "]"

    if na < 0.05:
        return f"translation along {vec(lin)}"
    if nl < 0.05:
        return f"rotation about {vec(ang)}"
    return f"translation along {vec(lin)} combined with rotation about {vec(ang)}"


def _reason(kind, report_bits, J, geo, st: ArmStructure, L) -> str:
    z, c = _lines(J)
    n = st.dof
    pre = "singular" if report_bits["singular"] else (
        "near-singular" if report_bits["near"] else "regular")
    lost = _direction_phrase(report_bits["u_min"])
    if kind == _REGULAR:
        txt = (f"regular: σ_min(J_L) = {report_bits['smin']:.3g} ≥ {report_bits['near_thr']:.3g}; "
               f"the weakest direction is {lost}")
        if report_bits["trans_rank_lost"]:
            txt += ("; note: the translational part J_v has lost rank — the tool point cannot "
                    f"translate in one direction (σ_min(J_v) = {report_bits['trans_smin']:.3g} m/rad)")
        if n < 6:
            txt += (f"; with {n} joints the arm spans at most {n} of the 6 task directions "
                    f"({6 - report_bits['rank']} are unreachable at this q)")
        return txt
    if kind == _WRIST:
        a, b, k = st.wrist
        pairs = [(a, b), (a, k), (b, k)]
        sines = [float(np.linalg.norm(np.cross(z[p], z[r]))) for p, r in pairs]
        p, r = pairs[int(np.argmin(sines))]
        d = c[r] - c[p]
        gap = float(np.linalg.norm(d - z[p] * np.dot(z[p], d)))
        how = "aligned (collinear)" if gap < 1e-6 * L else f"parallel ({gap:.4g} m apart)"
        ang = math.degrees(math.asin(min(1.0, min(sines))))
        off = "" if ang < 1e-6 else f", {ang:.3g}° from it"
        return f"{pre} wrist: axes of joints {p + 1} and {r + 1} are {how}{off}; lost: {lost}"
    if kind == _ELBOW:
        a, b = st.elbow
        state = "stretched" if geo["elbow_stretched"] else "folded"
        ang = math.degrees(math.asin(min(1.0, float(geo["elbow"]))))
        where = "the outer" if state == "stretched" else "an inner"
        pt = (f"the point where the axis of joint {st.elbow_point[0] + 1} meets the axis of joint "
              f"{st.elbow_point[1] + 1}" if st.elbow_point else "the wrist point")
        off = "" if ang < 1e-6 else f", {ang:.3g}° from it"
        return (f"{pre} elbow: the axes of joints {a + 1} and {b + 1} and {pt} lie in one plane — "
                f"upper arm and forearm are aligned ({state}{off}; the wrist is on {where} boundary "
                f"of its reach); lost: {lost}")
    if kind == _SHOULDER:
        off = abs(float(geo["shoulder_offset"]))
        dist = "in" if off < 1e-9 else f"{off * 1e3:.3g} mm from"
        return (f"{pre} shoulder: the wrist point lies {dist} the plane through the "
                f"axis of joint 1 parallel to the axis of joint 2 (the wrist is over the shoulder); "
                f"joint 1 cannot move it sideways; lost: {lost}")
    if kind == _BOUNDARY:
        arm = _joint_phrase(st.arm_joints)
        return (f"{pre} workspace boundary: {arm} cannot move the "
                f"{'wrist point' if st.wrist_point else 'tool point'} in one direction "
                f"(σ_min of their linear block / L = {float(geo['arm_sigma_min']):.3g}); lost: {lost}")
    # rank-deficient: participating joints and axis coincidences
    v = report_bits["v_min"]
    part = [i for i in range(n) if abs(v[i]) > 0.1 * np.max(np.abs(v))]
    extra = []
    rev = [i for i in range(n) if st.revolute[i]]
    for ii, i in enumerate(rev):
        for k in rev[ii + 1:]:
            sn = float(np.linalg.norm(np.cross(z[i], z[k])))
            if sn < 1e-3:
                d = c[k] - c[i]
                gap = float(np.linalg.norm(d - z[i] * np.dot(z[i], d)))
                if gap < 1e-3 * L:
                    extra.append(f"axes of joints {i + 1} and {k + 1} are aligned")
    txt = (f"{pre} (rank {report_bits['rank']} of {min(6, n)}): {_joint_phrase(part)} move the tool "
           f"in dependent ways; lost: {lost}")
    if extra:
        txt += "; " + "; ".join(extra)
    return txt


def analyze(chain, q, *, length: float | None = None, rtol: float = DEFAULT_RTOL,
            near: float = DEFAULT_NEAR, factor_tol: float = DEFAULT_FACTOR_TOL) -> SingularityReport:
    """Full singularity analysis of ``chain`` at one configuration q (n,).

    Args:
        chain: the robot model.
        q: joint positions (n,) [rad or m].
        length: characteristic length L [m] of the unit-consistent measures (default
            ``chain.characteristic_length``).
        rtol: rank tolerance: σ_i(J_L) ≤ rtol·σ₁(J_L) counts as zero.
        near: a configuration is near-singular when σ_min(J_L) < near (dimensionless).
        factor_tol: a geometric factor (sine of an angle) below this names the kind.

    Returns:
        A frozen :class:`SingularityReport`.
    """
    a = chain.check_q(q)
    if a.ndim != 1:
        raise InputError(f"analyze takes one configuration of shape ({chain.dof},); "
                         f"use scan() for a batch of shape {a.shape}", argument="q", value=q)
    L = _check_options(chain, length, rtol, near, factor_tol)
    n = chain.dof
    m = min(6, n)
    T, J = chain.fk_jacobian(a)
    core = _core(chain, J[None], L, rtol, near, factor_tol, True)
    geo = {k: v[0] for k, v in core["geo"].items()}
    JL = J.copy()
    JL[:3] /= L
    U, s, Vt = np.linalg.svd(JL)
    rk = int(core["rank"][0])
    lost = U[:, rk:]
    null = Vt[rk:].T
    u_min, v_min = U[:, m - 1], Vt[m - 1]
    g = np.einsum("a,kab,b->k", u_min, hessian_from_jacobian(JL), v_min)
    gn = float(np.linalg.norm(g))
    smin = float(core["sigma_min_scaled"][0])
    jdist = smin / gn if gn > 0 else (0.0 if smin == 0 else math.inf)
    st = structure(chain)
    kind = int(core["kind_code"][0])
    factors = {k: float(geo[k]) for k in ("wrist", "elbow", "shoulder") if not np.isnan(geo[k])}
    causes = tuple(k for k, f in factors.items() if f < factor_tol) if st.named else ()
    singular = rk < m
    sv = core["sigma_translational"][0]
    bits = dict(singular=singular, near=bool(smin < near), smin=smin, near_thr=near, rank=rk,
                u_min=u_min, v_min=v_min, trans_rank_lost=bool(sv[-1] < near * L), trans_smin=float(sv[-1]))
    reason = _reason(kind, bits, J, geo, st, L)
    W = T[:3, 3] + geo["W"] if st.wrist_point is not None else None
    det_arm = det_wrist = wc = None
    if st.spherical_wrist and n == 6:
        JW = shift_jacobian(J, geo["W"])
        det_arm = float(np.linalg.det(JW[:3, :3]))
        det_wrist = float(np.linalg.det(JW[3:, 3:]))
        wc = _ro(W)
    sr = core["sigma"][0]
    return SingularityReport(
        q=_ro(a.copy()), kind=KINDS[kind], singular=singular, near_singular=bits["near"], rank=rk,
        max_rank=m, length=L, sigma=_ro(sr), sigma_scaled=_ro(core["sigma_scaled"][0]),
        sigma_min=float(sr[-1]), sigma_min_scaled=float(core["sigma_min_scaled"][0]),
        manipulability=float(core["manipulability"][0]),
        manipulability_scaled=float(core["manipulability_scaled"][0]),
        condition=float(core["condition"][0]), condition_scaled=float(core["condition_scaled"][0]),
        inverse_condition=float(_cond(core["sigma_scaled"][0, 0], core["sigma_min_scaled"][0], True)),
        sigma_translational=_ro(core["sigma_translational"][0]),
        sigma_rotational=_ro(core["sigma_rotational"][0]),
        manipulability_translational=float(core["manipulability_translational"][0]),
        manipulability_rotational=float(core["manipulability_rotational"][0]),
        condition_translational=float(core["condition_translational"][0]),
        condition_rotational=float(core["condition_rotational"][0]),
        lost_directions_task=_ro(lost), null_space=_ro(null),
        weakest_direction_task=_ro(u_min), weakest_direction_joint=_ro(v_min),
        joint_distance=jdist, factors=MappingProxyType(factors), causes=causes, reason=reason,
        spherical_wrist=st.spherical_wrist, wrist_point=None if W is None else _ro(W),
        wrist_center=wc, det_arm=det_arm, det_wrist=det_wrist, rtol=rtol, near=near,
    )


# ====================================================================== batched scan
@dataclass(frozen=True, kw_only=True)
class ScanResult:
    """Measures over a batch of configurations (see :func:`scan`); arrays of shape batch + (...).

    ``kind_code`` indexes :data:`KINDS`; :attr:`kinds` gives the names. ``sigma_scaled``
    are the singular values of J_L (batch + (m,)); ``sigma`` and ``condition`` (raw J)
    are present only with ``raw=True``.
    """

    q: np.ndarray
    length: float
    sigma_scaled: np.ndarray
    sigma_min_scaled: np.ndarray
    manipulability: np.ndarray
    manipulability_scaled: np.ndarray
    condition_scaled: np.ndarray
    inverse_condition: np.ndarray
    rank: np.ndarray
    singular: np.ndarray
    near_singular: np.ndarray
    kind_code: np.ndarray
    manipulability_translational: np.ndarray
    manipulability_rotational: np.ndarray
    condition_translational: np.ndarray
    condition_rotational: np.ndarray
    factor_wrist: np.ndarray
    factor_elbow: np.ndarray
    factor_shoulder: np.ndarray
    sigma: np.ndarray | None = None
    condition: np.ndarray | None = None

    @property
    def kinds(self) -> np.ndarray:
        """Kind names, an array of str of the batch shape."""
        return np.asarray(KINDS)[self.kind_code]

    def count(self) -> dict:
        """How many configurations of each kind."""
        codes = np.bincount(self.kind_code.ravel(), minlength=len(KINDS))
        return {k: int(v) for k, v in zip(KINDS, codes, strict=True)}


_SCAN_CHUNK = 16384


def scan(chain, qs, *, length: float | None = None, rtol: float = DEFAULT_RTOL,
         near: float = DEFAULT_NEAR, factor_tol: float = DEFAULT_FACTOR_TOL,
         raw: bool = False) -> ScanResult:
    """Singularity measures and kinds for many configurations, batched.

    Args:
        chain: the robot model.
        qs: joint positions (..., n).
        length, rtol, near, factor_tol: as in :func:`analyze`.
        raw: also compute the singular values and condition number of the raw J (one
            more batched SVD).

    Returns:
        A frozen :class:`ScanResult`; entry ``[i]`` equals the corresponding field of
        ``analyze(chain, qs[i], ...)``.
    """
    a = chain.check_q(qs, name="qs")
    L = _check_options(chain, length, rtol, near, factor_tol)
    batch = a.shape[:-1]
    flat = a.reshape(-1, chain.dof)
    parts = []
    for start in range(0, max(flat.shape[0], 1), _SCAN_CHUNK):
        J = chain.jacobian(flat[start:start + _SCAN_CHUNK])
        parts.append(_core(chain, J, L, rtol, near, factor_tol, raw))

    def cat(get, tail=0):
        x = np.concatenate([get(p) for p in parts], axis=0)
        return _ro(x.reshape(batch + x.shape[1:]))

    m = min(6, chain.dof)
    s = cat(lambda p: p["sigma_scaled"])
    smin = cat(lambda p: p["sigma_min_scaled"])
    rk = cat(lambda p: p["rank"])
    return ScanResult(
        q=_ro(a.copy()), length=L, sigma_scaled=s, sigma_min_scaled=smin,
        manipulability=cat(lambda p: p["manipulability"]),
        manipulability_scaled=cat(lambda p: p["manipulability_scaled"]),
        condition_scaled=cat(lambda p: p["condition_scaled"]),
        inverse_condition=_ro(_cond(s[..., 0], smin, True)),
        rank=rk, singular=_ro(rk < m), near_singular=_ro(smin < near),
        kind_code=cat(lambda p: p["kind_code"]),
        manipulability_translational=cat(lambda p: p["manipulability_translational"]),
        manipulability_rotational=cat(lambda p: p["manipulability_rotational"]),
        condition_translational=cat(lambda p: p["condition_translational"]),
        condition_rotational=cat(lambda p: p["condition_rotational"]),
        factor_wrist=cat(lambda p: p["geo"]["wrist"]),
        factor_elbow=cat(lambda p: p["geo"]["elbow"]),
        factor_shoulder=cat(lambda p: p["geo"]["shoulder"]),
        sigma=cat(lambda p: p["sigma"]) if raw else None,
        condition=cat(lambda p: p["condition"]) if raw else None,
    )


# ====================================================================== gradient, paths
def manipulability_gradient(chain, q, *, length: float | None = None) -> np.ndarray:
    """Analytic gradient ∂w/∂q of the Yoshikawa manipulability, (n,) or (..., n).

    With J = U Σ Vᵀ (thin SVD, m = min(6, n) singular values) and the kinematic Hessian
    H_k = ∂J/∂q_k (:mod:`ratectl.hessian`), ∂σ_i/∂q_k = u_iᵀ H_k v_i, so

        ∂w/∂q_k = Σ_i (Π_{j≠i} σ_j) · u_iᵀ H_k v_i,

    which equals the classic w·tr(J⁺ H_k) where w > 0 and needs no inverse (it stays
    finite at a singularity; there w = Π σ_i has a kink for a square J and this is the
    one-sided derivative along the lost singular direction).

    Args:
        chain: the robot model.
        q: joint positions (n,) or (..., n).
        length: if given, the gradient of the unit-consistent w(J_L) (J_L = diag(I/L, I)·J,
            H scaled the same way); default the raw w(J) of :func:`manipulability`.

    Returns:
        ∂w/∂q in the units of w per rad (or per m for prismatic joints).
    """
    J = chain.jacobian(q)
    if length is not None:
        J = _scaled(J, length)
    H = hessian_from_jacobian(J)
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    c = _others_product(s)
    M = np.swapaxes(Vt, -1, -2) @ (c[..., :, None] * np.swapaxes(U, -1, -2))  # V diag(c) Uᵀ, (..., n, 6)
    return np.einsum("...kab,...ba->...k", H, M)


@dataclass(frozen=True, kw_only=True)
class PathDistance:
    """Distance to singularity along a path of configurations (see :func:`path_distance`).

    Attributes (one entry per configuration):
        s: cumulative joint-space arc length ‖Δq‖ summed along the path [rad, mixed
            with m for prismatic joints].
        sigma_min_scaled: σ_min(J_L), the spectral-norm distance of J_L to the nearest
            rank-deficient matrix (Eckart–Young).
        inverse_condition: σ_min/σ_max of J_L.
        manipulability: Yoshikawa w of the raw J.
        joint_distance: σ_min(J_L)/‖∇_q σ_min(J_L)‖, a first-order estimate of the
            joint-space distance to the singular set [rad].
        kind_code: as in :class:`ScanResult`; ``kinds`` gives names.
        closest: index of the configuration with the smallest σ_min(J_L).
    """

    s: np.ndarray
    sigma_min_scaled: np.ndarray
    inverse_condition: np.ndarray
    manipulability: np.ndarray
    joint_distance: np.ndarray
    kind_code: np.ndarray
    closest: int

    @property
    def kinds(self) -> np.ndarray:
        return np.asarray(KINDS)[self.kind_code]


def path_distance(chain, qs, *, length: float | None = None, near: float = DEFAULT_NEAR,
                  factor_tol: float = DEFAULT_FACTOR_TOL) -> PathDistance:
    """Distance to singularity along a path of configurations qs (N, n).

    Returns σ_min(J_L), 1/κ, w, a first-order joint-space distance to the singular set
    (σ_min / ‖∂σ_min/∂q‖, with ∂σ_min/∂q_k = u_minᵀ H_k v_min from the kinematic
    Hessian) and the kind at each configuration.
    """
    a = chain.check_q(qs, name="qs")
    if a.ndim != 2:
        raise InputError(f"qs must be a path of shape (N, {chain.dof}), got {a.shape}",
                         argument="qs", value=qs)
    L = _check_options(chain, length, DEFAULT_RTOL, near, factor_tol)
    J = chain.jacobian(a)
    core = _core(chain, J, L, DEFAULT_RTOL, near, factor_tol, False)
    JL = _scaled(J, L)
    U, sv, Vt = np.linalg.svd(JL, full_matrices=False)
    m = sv.shape[-1]
    g = np.einsum("...a,...kab,...b->...k", U[..., :, m - 1], hessian_from_jacobian(JL),
                  Vt[..., m - 1, :])
    gn = np.linalg.norm(g, axis=-1)
    smin = sv[..., -1]
    jd = np.divide(smin, gn, out=np.where(smin == 0, 0.0, np.inf), where=gn > 0)
    ds = np.linalg.norm(np.diff(a, axis=0), axis=-1)
    return PathDistance(
        s=_ro(np.concatenate([[0.0], np.cumsum(ds)])), sigma_min_scaled=_ro(smin),
        inverse_condition=_ro(_cond(sv[..., 0], smin, True)),
        manipulability=_ro(core["manipulability"]), joint_distance=_ro(jd),
        kind_code=_ro(core["kind_code"]), closest=int(np.argmin(smin)))


def fixed_lost_directions(chain, *, samples: int = 64, rng=0, rtol: float = 1e-9) -> np.ndarray:
    """Task directions the arm can never move in, at any configuration: (6, k) orthonormal.

    These are the unit twists u (raw [v; ω] coordinates) with uᵀ J(q) = 0 for every q —
    the common left null space of J over ``samples`` random configurations (the null
    space of the stacked Jᵀ). Example: the RPR arm gives [0, 0, 1, 0, 0, 0] (v_z: the
    tool height is fixed).
    """
    if not (isinstance(samples, int) and samples >= 1):
        raise InputError(f"samples must be a positive int, got {samples!r}", argument="samples",
                         value=samples)
    J = chain.jacobian(chain.random_q(samples, rng=rng))  # (S, 6, n)
    M = np.concatenate(list(J), axis=1)  # 6 × (S·n)
    U, s, _ = np.linalg.svd(M)
    k = int(np.sum(s > rtol * max(s[0], _TINY)))
    return U[:, k:]


# ====================================================================== workspace maps
_MEASURES = ("manipulability", "manipulability_scaled", "sigma_min_scaled", "inverse_condition")


@dataclass(frozen=True, kw_only=True)
class WorkspaceMap:
    """A 2-D map of a singularity measure (see :func:`workspace_map`).

    ``values[iy, ix]`` is the measure at (``x[ix]``, ``y[iy]``); NaN where no sample fell
    (plane mode). ``kind_code`` (joints mode) gives the kind at every grid point.
    """

    mode: str
    x: np.ndarray
    y: np.ndarray
    values: np.ndarray
    measure: str
    xlabel: str
    ylabel: str
    title: str
    kind_code: np.ndarray | None = None


def workspace_map(chain, *, joints: tuple[int, int] | None = None, plane: str | None = None,
                  q=None, ranges=None, resolution: int = 121, offset: float = 0.0,
                  slab: float = 0.02, samples: int = 400_000, measure: str = "manipulability",
                  length: float | None = None, rng=0) -> WorkspaceMap:
    """Map a singularity measure over two joints, or over a plane of tool positions.

    Exactly one of:

    * ``joints=(i, j)`` (0-based): a ``resolution × resolution`` grid of q_i, q_j over
      ``ranges = ((lo_i, hi_i), (lo_j, hi_j))`` (default the joint limits clipped to ±π),
      other joints at ``q`` (default zeros, clipped into the limits);
    * ``plane="xz"`` (or ``"xy"``, ``"yz"``; world axes): random configurations
      (``samples``, uniform in the limits) whose tool origin lies within ``slab/2`` m of
      the plane (third coordinate = ``offset`` [m]) are binned into a grid over
      ``ranges`` (default ±1.1·reach); each cell holds the **best** (largest) value
      reached there, NaN where no sample fell.

    Args:
        measure: one of "manipulability" (raw w), "manipulability_scaled",
            "sigma_min_scaled", "inverse_condition".
        length: characteristic length L [m] for the scaled measures.
        rng: seed or Generator for plane mode.
    """
    if (joints is None) == (plane is None):
        raise InputError("give exactly one of joints=(i, j) or plane='xz'/'xy'/'yz'",
                         argument="joints", value=(joints, plane))
    if measure not in _MEASURES:
        raise InputError(f"measure must be one of {_MEASURES}, got {measure!r}",
                         argument="measure", value=measure)
    if not (isinstance(resolution, int) and resolution >= 2):
        raise InputError(f"resolution must be an int ≥ 2, got {resolution!r}",
                         argument="resolution", value=resolution)
    if ranges is not None:
        try:
            rg = np.asarray(ranges, dtype=float)
        except (TypeError, ValueError):
            rg = None
        if rg is None or rg.shape != (2, 2) or not np.all(np.isfinite(rg)) or np.any(rg[:, 1] <= rg[:, 0]):
            raise InputError("ranges must be ((x_lo, x_hi), (y_lo, y_hi)) with finite lo < hi "
                             f"[rad or m], got {ranges!r}", argument="ranges", value=ranges)
    n = chain.dof
    lo = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    if joints is not None:
        try:
            i, j = (int(v) for v in joints)
        except (TypeError, ValueError):
            raise InputError(f"joints must be a pair of joint indices, got {joints!r}",
                             argument="joints", value=joints) from None
        if not (0 <= i < n and 0 <= j < n and i != j):
            raise InputError(f"joints must be two different indices in 0..{n - 1}, got {joints!r}",
                             argument="joints", value=joints)
        base = np.clip(np.zeros(n), lo, hi) if q is None else chain.check_q(q).copy()
        if ranges is None:
            ranges = ((max(lo[i], -np.pi), min(hi[i], np.pi)), (max(lo[j], -np.pi), min(hi[j], np.pi)))
        x = np.linspace(*ranges[0], resolution)
        y = np.linspace(*ranges[1], resolution)
        Q = np.broadcast_to(base, (resolution, resolution, n)).copy()
        Q[..., i] = x[None, :]
        Q[..., j] = y[:, None]
        res = scan(chain, Q, length=length)
        vals = getattr(res, measure)
        names = chain.joint_names
        return WorkspaceMap(mode="joints", x=_ro(x), y=_ro(y), values=_ro(np.array(vals)),
                            measure=measure, xlabel=f"q{i + 1} ({names[i]}) [rad]",
                            ylabel=f"q{j + 1} ({names[j]}) [rad]",
                            title=f"{chain.name}: {measure} over q{i + 1}, q{j + 1}",
                            kind_code=res.kind_code)
    axes = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
    if plane not in axes:
        raise InputError(f"plane must be 'xy', 'xz' or 'yz', got {plane!r}", argument="plane", value=plane)
    ax0, ax1, ax2 = axes[plane]
    R = 1.1 * chain.reach()
    if ranges is None:
        base_p = chain.base[:3, 3]
        ranges = ((base_p[ax0] - R, base_p[ax0] + R), (base_p[ax1] - R, base_p[ax1] + R))
    x = np.linspace(*ranges[0], resolution)
    y = np.linspace(*ranges[1], resolution)
    grid = np.full((resolution, resolution), -np.inf)
    gen = np.random.default_rng(rng)
    chunk = 100_000
    for start in range(0, samples, chunk):
        qs = chain.random_q(min(chunk, samples - start), rng=gen)
        T = chain.fk(qs)
        p = T[:, :3, 3]
        keep = np.abs(p[:, ax2] - offset) <= slab / 2
        if not np.any(keep):
            continue
        res = scan(chain, qs[keep], length=length)
        vals = np.asarray(getattr(res, measure))
        ix = np.rint((p[keep, ax0] - x[0]) / (x[1] - x[0])).astype(int)
        iy = np.rint((p[keep, ax1] - y[0]) / (y[1] - y[0])).astype(int)
        ok = (ix >= 0) & (ix < resolution) & (iy >= 0) & (iy < resolution)
        np.maximum.at(grid, (iy[ok], ix[ok]), vals[ok])
    grid[np.isneginf(grid)] = np.nan
    lab = "xyz"
    return WorkspaceMap(mode="plane", x=_ro(x), y=_ro(y), values=_ro(grid), measure=measure,
                        xlabel=f"{lab[ax0]} [m]", ylabel=f"{lab[ax1]} [m]",
                        title=f"{chain.name}: best {measure} with the tool in the plane "
                              f"{lab[ax2]} = {offset:g} m (±{slab / 2:g} m)")


def plot_workspace_map(wmap: WorkspaceMap, *, ax=None, cmap: str = "viridis", colorbar: bool = True,
                       show_kinds: bool = True):
    """Plot a :class:`WorkspaceMap` with matplotlib (imported here; ``pip install ratectl[plot]``).

    In joints mode with ``show_kinds``, the near-singular grid points are outlined by
    kind (white contours labelled wrist/elbow/shoulder/...). Returns the Axes.
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("plot_workspace_map needs matplotlib: pip install 'ratectl[plot]'") from exc
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5))
    mesh = ax.pcolormesh(wmap.x, wmap.y, wmap.values, cmap=cmap, shading="nearest")
    if colorbar:
        ax.figure.colorbar(mesh, ax=ax, label=wmap.measure)
    if show_kinds and wmap.kind_code is not None:
        styles = {_WRIST: ("w", "-"), _ELBOW: ("r", "-"), _SHOULDER: ("orange", "-"),
                  _BOUNDARY: ("m", "-"), _RANKDEF: ("k", "-")}
        handles = []
        for code, (col, ls) in styles.items():
            mask = (wmap.kind_code == code).astype(float)
            if mask.any():
                ax.contour(wmap.x, wmap.y, mask, levels=[0.5], colors=col, linestyles=ls, linewidths=1.2)
                handles.append(plt.Line2D([], [], color=col, ls=ls, label=f"near {KINDS[code]}"))
        if handles:
            ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.7)
    ax.set_xlabel(wmap.xlabel)
    ax.set_ylabel(wmap.ylabel)
    ax.set_title(wmap.title, fontsize=9)
    return ax
