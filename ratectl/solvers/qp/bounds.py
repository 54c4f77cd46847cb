"""The per-joint velocity box of one control step from velocity, position and acceleration
limits (`joint_velocity_bounds`), with the source of every active bound.
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import gt as _gt
from operator import lt as _lt
from typing import TYPE_CHECKING

import numpy as np

from ...arrays import read_only
from ...errors import InputError
from ...model.limits import Limits, braking_speed_any_dt, speed_toward_limit
from ..base import (
    _positive,
)

if TYPE_CHECKING:
    from ...model.chain import Chain

__all__ = ['joint_velocity_bounds', 'VelocityBounds']


_BIG = 1e15  # stands for an absent (infinite) limit in the bound arithmetic


_CTOL = 1e-9  # conflicts smaller than this are rounding (resolved, not reported)


_NONE, _VEL, _POS, _ACC = 0, 1, 2, 3


_KIND = {_VEL: "velocity", _POS: "position", _ACC: "acceleration"}


@dataclass(frozen=True, kw_only=True)
class VelocityBounds:
    """Per-joint velocity box for one step (see `joint_velocity_bounds`).

    Attributes:
        lower: (n,) lower bounds on q̇ [rad/s or m/s].
        upper: (n,) upper bounds on q̇ [rad/s or m/s].
        source_lower: (n,) int codes of the limit that sets each lower bound
            (0 none, 1 velocity, 2 position, 3 acceleration).
        source_upper: (n,) the same for the upper bounds.
        conflicts: tuple of (joint, kinds) where bounds conflicted and were resolved by
            priority (velocity > position > acceleration).
    """

    lower: np.ndarray
    upper: np.ndarray
    source_lower: np.ndarray
    source_upper: np.ndarray
    conflicts: tuple[tuple[int, tuple[str, ...]], ...] = ()

    def __post_init__(self) -> None:
        for name in ("lower", "upper", "source_lower", "source_upper"):
            object.__setattr__(self, name, read_only(getattr(self, name), dtype=None))


class _BoundCache:
    """Precomputed arrays for the bound arithmetic of one (limits, dt, margin).

    Position bounds are computed on stacked (2n,) arrays, upper side first, lower side
    mirrored: D = [upper − m − q; q − lower − m], bound = min(stop speed(D), vmax) with
    the stop speed `braking_speed_any_dt` (valid when dt changes between steps); the
    lower bound is minus the second half. An absent position limit is a large finite
    number (no inf − inf); an absent acceleration limit is a huge finite one (the stop
    speed becomes D/dt).
    """

    __slots__ = ("src", "dt", "n", "limits", "vmax", "nvmax", "hi_lim", "lo_lim", "amax_dt",
                 "has_pos", "has_acc", "inv_dt", "lim2", "sgn2", "idx2", "vmax2", "adt", "two_over_a",
                 "two_over_a2", "two_a", "vmax_l", "amax_dt_l", "near_hi_l", "near_lo_l", "margins")

    def __init__(self, src, limits, dt, margin):  # private: the numbers are checked by its callers
        self.src, self.dt = src, dt
        self.limits = limits
        n = self.n = limits.vmax.shape[0]
        self.vmax = np.minimum(limits.vmax, _BIG)
        self.nvmax = -self.vmax
        self.vmax_l = self.vmax.tolist()
        # the margin of each joint is at most half its range: a joint narrower than twice
        # the margin (a locked joint, lower == upper) is kept at the centre of its range,
        # never pushed out of it by margins that cross
        with np.errstate(invalid="ignore", over="ignore"):
            m = np.minimum(margin, 0.5 * (limits.upper - limits.lower))
        self.margins = m
        self.hi_lim = np.where(np.isfinite(limits.upper), limits.upper - m, _BIG)
        self.lo_lim = np.where(np.isfinite(limits.lower), limits.lower + m, -_BIG)
        afin = np.isfinite(limits.amax)
        a = np.where(afin, limits.amax, 1e200)
        self.two_a = 2.0 * a
        self.two_over_a = 2.0 / a
        self.two_over_a2 = np.concatenate([self.two_over_a, self.two_over_a])
        self.has_pos = bool(np.any(np.isfinite(limits.upper)) or np.any(np.isfinite(limits.lower)))
        self.has_acc = bool(np.any(afin))
        self.lim2 = np.concatenate([self.hi_lim, -self.lo_lim])
        self.sgn2 = np.concatenate([np.ones(n), -np.ones(n)])
        self.idx2 = np.concatenate([np.arange(n), np.arange(n)])
        self.vmax2 = np.concatenate([self.vmax, self.vmax])
        if dt is None:
            self.amax_dt = self.inv_dt = self.adt = None
            self.amax_dt_l = None
            self.near_hi_l = self.near_lo_l = None
        else:
            tiny = afin & ~(a * dt * dt >= 1e-290)
            if tiny.any():
                j = int(np.flatnonzero(tiny)[0])
                raise InputError(
                    f"amax[{j}] = {limits.amax[j]:.3g} with dt = {dt:.3g} s: amax·dt² underflows "
                    "floating point (below 1e-290); use a larger amax or dt (or inf for no "
                    "acceleration limit)", argument="limits", value=limits)
            self.amax_dt = np.where(afin, a * dt, _BIG)
            self.amax_dt_l = self.amax_dt.tolist()
            self.inv_dt = 1.0 / dt
            self.adt = a * dt
            # the room from which a joint may move at full speed for one period and still
            # stop: vmax·dt + vmax²/(2a) (where braking_speed_any_dt reaches vmax); farther
            # than this from both limits, the velocity limit is the bound
            with np.errstate(over="ignore", invalid="ignore"):
                dstar = self.vmax * dt + self.vmax * self.vmax / self.two_a
            # not finite (overflow): always compute the braking bounds (the safe side)
            dstar = np.where((limits.vmax < _BIG) & np.isfinite(dstar), dstar * (1.0 + 1e-9) + 1e-12,
                             np.inf)
            # a joint is near a limit when its room to it, upper − q or q − lower, is below
            # dstar: q above upper − dstar or below lower + dstar, with a slack of many
            # roundings so that these thresholds never call a joint far that is near (one
            # called near that is not gets the velocity limit from the braking bound too)
            with np.errstate(invalid="ignore"):
                slack = 1e-14 * (np.abs(self.hi_lim) + np.abs(self.lo_lim) + dstar + 1.0)
                self.near_hi_l = np.where(np.isfinite(dstar), self.hi_lim - dstar - slack, -np.inf).tolist()
                self.near_lo_l = np.where(np.isfinite(dstar), self.lo_lim + dstar + slack, np.inf).tolist()
        for arr in (self.vmax, self.nvmax):  # returned as the box when no other bound acts
            arr.setflags(write=False)


def _box(bc: _BoundCache, q, qd_prev):
    """Fast path of `_bounds`: (lo, hi, conflicts) without the sources."""
    n = bc.n
    if q is not None and bc.has_pos and bc.inv_dt is not None:
        # some joint is near a limit: the room to it, D = [upper − q; q − lower], is below
        # the distance from which it may move at full speed and still stop (on Python
        # floats against precomputed thresholds: cheaper than numpy on a few numbers)
        ql = q.tolist()
        if any(map(_gt, ql, bc.near_hi_l)) or any(map(_lt, ql, bc.near_lo_l)):
            D = bc.lim2 - q[bc.idx2] * bc.sgn2
            if (D < 0.0).any():
                return _careful(bc, q, qd_prev)  # beyond a limit: the careful path
            U = np.minimum(braking_speed_any_dt(D, bc.dt, bc.two_over_a2), bc.vmax2)
            hi = U[:n]
            lo = -U[n:]
            if float((hi - lo).min()) < 0.0:
                return _careful(bc, q, qd_prev)  # conflicting bounds: the careful path
        else:
            lo, hi = bc.nvmax, bc.vmax
    elif q is not None and bc.has_pos:
        return _careful(bc, q, qd_prev)
    else:
        lo, hi = bc.nvmax, bc.vmax
    if qd_prev is not None and bc.amax_dt is not None and bc.has_acc:
        nlo = np.maximum(lo, qd_prev - bc.amax_dt)
        nhi = np.minimum(hi, qd_prev + bc.amax_dt)
        if any(map(_gt, nlo.tolist(), nhi.tolist())):
            return _careful(bc, q, qd_prev)
        lo, hi = nlo, nhi
    return lo, hi, ()


def _sources(bc, qd_prev, lo, hi, held) -> tuple[str, ...]:  # private: bc is a _BoundCache
    """Kinds of limit that set the active bounds; ``held[i]`` is +1 / −1 / 0 for a joint
    at its upper / lower bound / free. The box values are exact copies of the velocity
    limit, the acceleration bound or a position bound, so equality identifies them
    (velocity first, then acceleration, else position)."""
    kinds = set()
    vmax = bc.vmax_l
    acc = qd_prev is not None and bc.amax_dt is not None and bc.has_acc
    lol: list[float] = []
    hil: list[float] = []
    qdl: list[float] = []
    for i, st in enumerate(held):
        if not st:
            continue
        if not lol:
            lol, hil = lo.tolist(), hi.tolist()
            qdl = qd_prev.tolist() if acc else []
        v = hil[i] if st > 0 else lol[i]
        if v == st * vmax[i]:
            kinds.add(_VEL)
        elif acc and v == qdl[i] + st * bc.amax_dt_l[i]:
            kinds.add(_ACC)
        else:
            kinds.add(_POS)
    return tuple(_KIND[k] for k in (_VEL, _POS, _ACC) if k in kinds)


def _careful(bc, q, qd_prev):
    lo, hi, _, _, conflicts = _bounds(bc, q, qd_prev, False)
    return lo, hi, conflicts


def _bounds(cache, q, qd_prev, want_sources):  # private: cache is a _BoundCache
    """The velocity box (lo, hi), its sources and the conflicts; see the module docstring."""
    lo = cache.nvmax
    hi = cache.vmax
    conflicts = []
    slo = shi = None
    if want_sources:
        slo = np.where(cache.vmax < _BIG, _VEL, _NONE)
        shi = slo.copy()
    if q is not None and cache.has_pos:
        dup = cache.hi_lim - q
        dlo = q - cache.lo_lim
        if cache.inv_dt is not None:
            # inside the range the braking bound; beyond a limit back into the range (never
            # further out), within vmax and, with qd_prev, within amax (speed_toward_limit)
            acc = qd_prev is not None and cache.has_acc
            pu = speed_toward_limit(dup, qd_prev if acc else None, dt=cache.dt,
                                    two_over_a=cache.two_over_a, adt=cache.adt, vmax=cache.vmax)
            pl = -speed_toward_limit(dlo, -qd_prev if acc else None, dt=cache.dt,
                                     two_over_a=cache.two_over_a, adt=cache.adt, vmax=cache.vmax)
        else:  # no step: the continuous braking bound √(2a·d), and no motion beyond a limit
            pu = np.sqrt(cache.two_a * np.maximum(dup, 0.0))
            pl = -np.sqrt(cache.two_a * np.maximum(dlo, 0.0))
        bad = pl > pu
        if bad.any():  # only beyond a limit (q outside the range): the midpoint of the two
            conflicts += [(int(i), ("position",)) for i in np.flatnonzero(bad & (pl - pu > _CTOL))]
            mid = 0.5 * (pl + pu)
            pl = np.where(bad, mid, pl)
            pu = np.where(bad, mid, pu)
        nlo = np.maximum(lo, pl)
        nhi = np.minimum(hi, pu)
        if want_sources:
            slo = np.where(pl > lo, _POS, slo)
            shi = np.where(pu < hi, _POS, shi)
        bad = nlo > nhi
        big = bad & (nlo - nhi > _CTOL)
        if bad.any():  # the position box lies outside the velocity box: keep the nearest velocity
            pt = np.where(pl > hi, hi, lo)
            nlo = np.where(bad, pt, nlo)
            nhi = np.where(bad, pt, nhi)
            if want_sources:
                slo = np.where(bad, _VEL, slo)
                shi = np.where(bad, _VEL, shi)
            conflicts += [(int(i), ("velocity", "position")) for i in np.flatnonzero(big)]
        lo, hi = nlo, nhi
    if qd_prev is not None and cache.amax_dt is not None and cache.has_acc:
        al = qd_prev - cache.amax_dt
        au = qd_prev + cache.amax_dt
        nlo = np.maximum(lo, al)
        nhi = np.minimum(hi, au)
        bad = nlo > nhi
        big = bad & (nlo - nhi > _CTOL)
        if want_sources:
            pt_src = np.where(al > hi, shi, slo)  # the bound of the kept box at the nearest point
            slo = np.where(bad, pt_src, np.where(al > lo, _ACC, slo))
            shi = np.where(bad, pt_src, np.where(au < hi, _ACC, shi))
        if bad.any():  # cannot reach the box within the acceleration limit: nearest point
            pt = np.where(al > hi, hi, lo)
            nlo = np.where(bad, pt, nlo)
            nhi = np.where(bad, pt, nhi)
            conflicts += [(int(i), ("acceleration",)) for i in np.flatnonzero(big)]
        lo, hi = nlo, nhi
    return lo, hi, slo, shi, tuple(conflicts)


def joint_velocity_bounds(limits: Limits | Chain, *, q: np.ndarray | None = None,
                          qd_prev: np.ndarray | None = None, dt: float | None = None, margin: float = 0.0,
                          n: int | None = None) -> VelocityBounds:
    """The per-joint box on q̇ for one step from velocity, position and acceleration
    limits (see `ratectl.qp`). ``limits`` is a Chain or `Limits`; ``q``
    (n,) enables the position bounds, ``qd_prev`` (n,) with ``dt`` [s] the acceleration
    bounds; ``margin`` [rad or m] keeps that far from the position limits, at most half
    a joint's range: a joint narrower than 2·margin (a locked joint, lower == upper) is
    kept at the centre of its range."""
    if n is None:
        n = np.asarray(limits.vmax).shape[0]
    lim = Limits.of(limits, n)
    if dt is not None:
        dt = _positive("dt", dt)
    margin = _positive("margin", margin, allow_zero=True)
    q = _vec("q", q, n)
    qd_prev = _vec("qd_prev", qd_prev, n)
    cache = _BoundCache(limits, lim, dt, margin)
    lo, hi, slo, shi, conflicts = _bounds(cache, q, qd_prev, True)
    return VelocityBounds(lower=np.array(lo, dtype=float), upper=np.array(hi, dtype=float),
                          source_lower=slo, source_upper=shi, conflicts=conflicts)


def _vec(name, v, n):
    if v is None:
        return None
    try:
        if isinstance(v, str | bytes) or np.iscomplexobj(v):
            raise TypeError(name)
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a finite ({n},) vector of real numbers, got {v!r}"[:300],
                         argument=name, value=v) from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be a finite ({n},) vector, got shape {a.shape}", argument=name,
                         value=v)
    return a
