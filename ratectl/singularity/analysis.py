"""Classify a configuration and explain it: `classify` (fast kind) and `analyze`
(a `SingularityReport` with lost directions, null vectors and a plain-language reason).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..kinematics import shift_jacobian
from ..kinematics.hessian import hessian_from_jacobian
from .measures import (
    _BOUNDARY,
    _ELBOW,
    _RANKDEF,
    _REGULAR,
    _SHOULDER,
    _WRIST,
    DEFAULT_FACTOR_TOL,
    DEFAULT_NEAR,
    DEFAULT_RTOL,
    KINDS,
    _cond,
    _fast_singular_values,
    _ro,
    check_chain,
)
from .structure import ArmStructure, _geometry, _lines, structure

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ['analyze', 'classify', 'SingularityReport']


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
    kind = np.where((kind == _REGULAR) & _translation_lost(chain, st_v, L, near), _BOUNDARY, kind)
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


def classify(chain: Chain, q: ArrayLike | None = None, *, J: ArrayLike | None = None,
             length: float | None = None, near: float = DEFAULT_NEAR,
             factor_tol: float = DEFAULT_FACTOR_TOL) -> tuple[str, float]:
    """Fast kind of one configuration: ``(kind, σ_min(J_L))`` — for control loops.

    The same classification as `analyze` and `scan` (identical results), but
    regular configurations cost one small eigenvalue problem (~20 µs) and the geometry
    is only evaluated when σ_min(J_L) < ``near``.

    Args:
        chain: the robot model.
        q: joint positions (n,); not needed when ``J`` is given.
        J: the Jacobian (6, n) at q (base axes, tool origin) if already computed.
        length: characteristic length [m], as in `analyze`.
        near: near-singularity threshold, as in `analyze`.
        factor_tol: geometric-factor tolerance, as in `analyze`.
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
    lost = chain.dof < 6 and bool(_translation_lost(chain, _fast_singular_values(J[None, :3]), L, near)[0])
    if smin[0] >= near:
        return ("boundary" if lost else "regular"), float(smin[0])
    geo = _geometry(J[None], structure(chain), L, smin < near)
    kind = int(_classify(smin, geo, structure(chain), near, factor_tol)[0])
    return KINDS[_BOUNDARY if kind == _REGULAR and lost else kind], float(smin[0])


@dataclass(frozen=True, kw_only=True)
class SingularityReport:
    """Singularity analysis of one configuration (see `analyze`).

    Measures, named by one rule: a name without suffix is of J as given (mixed units, the
    same σ_min every `Command` and `Execution` carries), the suffix ``_scaled`` means of
    J_L = diag(I/L, I)·J (dimensionless, L = ``length``): ``sigma``/``sigma_scaled`` (the
    singular values), ``sigma_min``/``sigma_min_scaled``, ``manipulability``/
    ``manipulability_scaled`` (√det(J Jᵀ), n ≥ 6; √det(Jᵀ J), n < 6),
    ``condition``/``condition_scaled`` (σ₁/σ_m, inf at a singularity) and
    ``inverse_condition``/``inverse_condition_scaled`` (σ_m/σ₁ = 1/condition, 0 at a
    singularity); translational (J_v, m/rad) and rotational (J_ω, rad/rad) sub-measures.

    Classification: ``kind`` ∈ `KINDS`, ``singular`` (rank < min(6, n)),
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
    inverse_condition_scaled: float
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
        label = self.kind
        if self.kind == "rank-deficient" and not self.singular:
            label = "near rank-deficient"
        return (f"{label} (rank {self.rank}/{self.max_rank}, σ_min(J) = {self.sigma_min:.3g}, "
                f"σ_min(J_L) = {self.sigma_min_scaled:.3g}, estimated {self.joint_distance:.3g} rad from "
                f"singular to first order): {self.reason}")


def _joint_phrase(idx, names) -> str:
    """"joint 'a'" or "joints 'a', 'b' and 'c'": joints are named by the chain's joint names."""
    idx = [repr(names[i]) for i in idx]
    if len(idx) == 1:
        return f"joint {idx[0]}"
    return "joints " + ", ".join(idx[:-1]) + f" and {idx[-1]}"


def _direction_phrase(u: np.ndarray) -> str:
    """Describe a unit scaled-twist direction [v/L; ω] in words."""
    lin, ang = u[:3], u[3:]
    nl, na = float(np.linalg.norm(lin)), float(np.linalg.norm(ang))

    def vec(x: np.ndarray) -> str:
        x = x / np.linalg.norm(x)
        return "[" + ", ".join(f"{v:+.2f}" for v in x) + "]"

    if na < 0.05:
        return f"translation along {vec(lin)}"
    if nl < 0.05:
        return f"rotation about {vec(ang)}"
    return f"translation along {vec(lin)} combined with rotation about {vec(ang)}"


def _reason(kind, report_bits, J, geo, st: ArmStructure, L, names) -> str:
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
            k = 6 - report_bits['rank']
            txt += (f"; with {n} joints the arm spans at most {n} of the 6 task directions "
                    f"({k} {'is' if k == 1 else 'are'} unreachable at this q)")
        return txt
    if kind == _WRIST:
        assert st.wrist is not None  # the wrist kind is only given to arms with a spherical wrist
        a, b, k = st.wrist
        pairs = [(a, b), (a, k), (b, k)]
        sines = [float(np.linalg.norm(np.cross(z[p], z[r]))) for p, r in pairs]
        p, r = pairs[int(np.argmin(sines))]
        d = c[r] - c[p]
        gap = float(np.linalg.norm(d - z[p] * np.dot(z[p], d)))
        how = "aligned (collinear)" if gap < 1e-6 * L else f"parallel ({gap:.4g} m apart)"
        ang = math.degrees(math.asin(min(1.0, min(sines))))
        off = "" if ang < 1e-6 else f", {ang:.3g}° from it"
        return f"{pre} wrist: the axes of {_joint_phrase((p, r), names)} are {how}{off}; lost: {lost}"
    if kind == _ELBOW:
        assert st.elbow is not None  # the elbow kind is only given to arms with an elbow pair
        a, b = st.elbow
        state = "stretched" if geo["elbow_stretched"] else "folded"
        ang = math.degrees(math.asin(min(1.0, float(geo["elbow"]))))
        where = "the outer" if state == "stretched" else "an inner"
        pt = (f"the point where the axis of joint {names[st.elbow_point[0]]!r} meets the axis of joint "
              f"{names[st.elbow_point[1]]!r}" if st.elbow_point else "the wrist point")
        off = "" if ang < 1e-6 else f", {ang:.3g}° from it"
        return (f"{pre} elbow: the axes of {_joint_phrase((a, b), names)} and {pt} lie in one plane — "
                f"upper arm and forearm are aligned ({state}{off}; the wrist is on {where} boundary "
                f"of its reach); lost: {lost}")
    if kind == _SHOULDER:
        offset = abs(float(geo["shoulder_offset"]))
        dist = "in" if offset < 1e-9 else f"{offset * 1e3:.3g} mm from"
        return (f"{pre} shoulder: the wrist point lies {dist} the plane through the "
                f"axis of joint {names[0]!r} parallel to the axis of joint {names[1]!r} (the wrist is "
                f"over the shoulder); joint {names[0]!r} cannot move it sideways; lost: {lost}")
    if kind == _BOUNDARY:
        arm = _joint_phrase(st.arm_joints, names)
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
                    extra.append(f"the axes of {_joint_phrase((i, k), names)} are aligned")
    if report_bits["singular"]:
        txt = (f"singular (rank {report_bits['rank']} of {min(6, n)}): {_joint_phrase(part, names)} "
               f"move the tool in dependent ways; lost: {lost}")
    else:  # full rank, close to losing it, with no named cause
        txt = (f"near-singular (full rank {report_bits['rank']}, σ_min(J_L) = {report_bits['smin']:.3g} < "
               f"{report_bits['near_thr']:.3g}): {_joint_phrase(part, names)} move the tool in nearly "
               f"dependent ways; weakest: {lost}")
    if extra:
        txt += "; " + "; ".join(extra)
    return txt


def _translation_lost(chain, st_v, L: float, near: float):
    """For arms with fewer than 6 joints: the tool point has lost a translation direction
    it has at generic configurations (a stretched or folded planar arm), from the
    singular values of J_v (B, k) — that is the singularity that matters for such an arm
    (its 6×n Jacobian may keep full column rank through the angular rows)."""
    if chain.dof >= 6:
        return np.zeros(st_v.shape[:-1], dtype=bool)
    generic = _GENERIC_TRANSLATION_RANK.get(chain)
    if generic is None:
        Jr = chain.jacobian(chain.random_q(8, rng=0))
        generic = max(int(np.sum(np.linalg.svd(Jk[:3], compute_uv=False) > 1e-9 * L)) for Jk in Jr)
        _GENERIC_TRANSLATION_RANK[chain] = generic
    return np.sum(st_v > near * L, axis=-1) < generic


_GENERIC_TRANSLATION_RANK: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def analyze(chain: Chain, q: ArrayLike, *, length: float | None = None, rtol: float = DEFAULT_RTOL,
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
        A frozen `SingularityReport`.
    """
    check_chain(chain)
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
    reason = _reason(kind, bits, J, geo, st, L, chain.joint_names)
    if kind == _BOUNDARY and not bits["near"]:      # set by _translation_lost (n < 6)
        pre = "singular" if bits["trans_smin"] <= 1e-9 * L else "near-singular"
        reason = (f"{pre} workspace boundary: the tool point cannot translate in one direction "
                  f"(σ_min(J_v) = {bits['trans_smin']:.3g} m/rad, the arm is stretched or folded); "
                  f"lost: {_direction_phrase(bits['u_min'])}")
    if singular:
        jdist = 0.0      # on the singular set (the first-order estimate is meaningless there)
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
        inverse_condition=float(_cond(sr[0], sr[-1], True)),
        inverse_condition_scaled=float(_cond(core["sigma_scaled"][0, 0], core["sigma_min_scaled"][0], True)),
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
