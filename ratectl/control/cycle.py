"""The working state of one control cycle, and what the controller's stages share.

* `Cycle` — what one `step` computes, passed from stage to stage (J, the pose error, the
  solve, q̇, q̈, the status flags and reasons);
* `Motion` — the motion the controller last commanded (q̇, q̈), which the stages read as
  "the previous cycle";
* small helpers on a cycle's numbers (`_finite_sum`, `_same`, `_same_rotation`, `_scaled_like`,
  `_info`).
"""

from __future__ import annotations

from collections.abc import Mapping
from itertools import repeat
from operator import gt as _gt
from operator import sub as _sub
from types import MappingProxyType
from typing import Any

import numpy as np

__all__ = ["Cycle", "Motion"]


def _finite_sum(a: np.ndarray) -> bool:
    """True when the sum of the entries of ``a`` is finite (no NaN, no inf), through a
    Python list: ~5× cheaper than ``ndarray.sum`` on the few numbers of one cycle."""
    s = sum(a.ravel().tolist())
    return s - s == 0.0


def _same(a: np.ndarray, b: np.ndarray | None) -> bool:
    """``np.array_equal(a, b)`` for the few numbers of one cycle (a pose, a twist), through
    Python lists: the same answer (−0.0 equals 0.0, NaN equals nothing), ~5× cheaper."""
    return b is not None and a.shape == b.shape and a.tolist() == b.tolist()


def _same_rotation(t: list[list[float]], o: list[list[float]]) -> bool:
    """Whether two poses given as their rows of floats (``tolist()``) have the same rotation
    block, entry for entry (a target that only translates)."""
    (a0, a1, a2, _), (b0, b1, b2, _), (c0, c1, c2, _) = t[0], t[1], t[2]
    (u0, u1, u2, _), (v0, v1, v2, _), (w0, w1, w2, _) = o[0], o[1], o[2]
    return (a0 == u0 and a1 == u1 and a2 == u2 and b0 == v0 and b1 == v1 and b2 == v2
            and c0 == w0 and c1 == w1 and c2 == w2)


def _info(res: Any) -> Mapping[str, Any]:
    """The ``info`` mapping of a solve result (a `SolveResult` keeps a read-only
    ``MappingProxyType``, recognised by its exact type first: cheaper than the ABC check),
    or an empty one when a solver gave something else."""
    info = res.info
    if type(info) is MappingProxyType or isinstance(info, Mapping):
        return info
    return _NO_INFO


_NO_INFO: Mapping[str, Any] = MappingProxyType({})


def _scaled_like(wanted: np.ndarray, clipped: np.ndarray) -> np.ndarray:
    """``wanted`` scaled uniformly by the smallest ratio clipped/wanted over the joints a
    clip changed (a ratio in [0, 1]; a clip that reversed a joint gives 0): the motion
    slows along its direction instead of turning."""
    changed = clipped != wanted
    if not changed.any():
        return wanted
    ratio = np.where(changed, clipped / np.where(changed, wanted, 1.0), 1.0)
    return wanted * float(np.clip(ratio.min(), 0.0, 1.0))


_AT_REST = 1e-9  # [rad or m] a command that moves a joint by less over a period holds it at rest


class Motion:
    """The motion the controller last commanded: ``qd`` q̇ [rad/s or m/s] and ``qdd`` q̈
    [rad/s² or m/s²], (n,) each, ``q_next`` the position it commanded (None before the
    first command), and ``q_lead`` the position its commands have sent the arm to (see
    `commanded`; None before the first command). One object shared by the controller (which
    writes it when it commands) and its stages (which read it as the previous cycle's)."""

    __slots__ = ("qd", "qdd", "q_next", "q_lead")

    def __init__(self, n: int) -> None:
        self.qd = np.zeros(n)
        self.qdd = np.zeros(n)
        self.q_next: np.ndarray | None = None
        self.q_lead: np.ndarray | None = None

    def commanded(self, q: np.ndarray, q_prev: np.ndarray | None, q_next: np.ndarray) -> None:
        """A command from ``q`` (the measured or base position, (n,)) to ``q_next``: the
        lead moves by the commanded displacement,

            q_lead ← q_lead + (q_next − q)        (q_lead = q_next after the first command),

        so ``q_lead − q`` is what the commands moved the arm beyond what it was measured to
        move: the travel an arm that lags its velocity command still owes. An arm whose servo
        tracks velocity without a steady-state error covers, once at rest, every displacement
        it was commanded, so it comes to rest at ``q_lead`` — with the command at zero, however
        long its velocity lags. A joint the last command held at rest (it moved the joint by
        at most ``_AT_REST``, rounding) that was measured not moving toward its lead since
        ``q_prev`` owes nothing: its lead is its measured q again (a gap a sag or friction
        left, which the arm will never travel, is forgotten)."""
        # (Python floats: a per-cycle hot path on a handful of joints)
        lead = self.q_lead
        if lead is None or q_prev is None or self.q_next is None:
            self.q_lead = q + (q_next - q)
            return
        pl, ml = q_prev.tolist(), self.q_next.tolist()
        if all(map(_gt, map(abs, map(_sub, ml, pl)), repeat(_AT_REST))):
            # every joint was moved by the last command: each keeps its lead (the common case)
            self.q_lead = lead + (q_next - q)
            return
        self.q_lead = np.array([
            (ld if (abs(m - p) > _AT_REST or (a - p) * (ld - a) > 0.0) else a) + (b - a)
            for a, b, p, m, ld in zip(q.tolist(), q_next.tolist(), pl, ml, lead.tolist(), strict=True)])


class Cycle:
    """The working state of one control cycle, passed from stage to stage."""

    __slots__ = ("J", "e", "ep", "eo", "xi", "target", "res", "qd", "qdd", "q_next", "flags", "reasons",
                 "active", "scale", "smin", "braking", "approach", "qdd_ff", "approach_qd", "kind",
                 "blocked", "enforced")

    J: np.ndarray
    e: np.ndarray
    ep: float
    eo: float
    xi: np.ndarray
    target: bool
    res: Any
    smin: float | None
    qd: np.ndarray
    qdd: np.ndarray
    q_next: np.ndarray
    braking: Any
    qdd_ff: np.ndarray | None
    approach_qd: np.ndarray | None

    def __init__(self) -> None:
        self.flags: list[str] = []
        self.reasons: list[str] = []
        self.active: list[str] = []
        self.braking = None
        self.approach = 1.0
        self.qdd_ff = None
        self.approach_qd = None
        self.kind: str | None = None
        self.blocked = ""
        self.scale = 1.0
        self.smin = None  # σ_min of the solve, read on demand (`sigma`)
        # q̇ is a limit-enforcing solver's answer under its own bounds (then the limiter only
        # reports them); any other q̇ (a direction scaled by a progress, a joint line) is
        # limited by the limiter
        self.enforced = False

    def sigma(self) -> float:
        """σ_min of the cycle's solve, computed on the first call only."""
        smin = self.smin
        if smin is None:
            smin = self.smin = float(self.res.sigma_min)
        return smin

    def sigma_at_least(self, threshold: float) -> bool:
        """σ_min ≥ threshold for the cycle's solve: by the result's ``sigma_min_at_least``
        (a `SolveResult`'s: the QP usually decides it without computing σ_min), else by
        the value."""
        at_least = getattr(self.res, "sigma_min_at_least", None) if self.smin is None else None
        if at_least is not None:
            return bool(at_least(threshold))
        return self.sigma() >= threshold
