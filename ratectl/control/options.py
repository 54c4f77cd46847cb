"""The controller's options, checked once at construction: the solver, the gain, the
smoothing filter, and the default solver."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .. import solvers
from ..errors import InputError
from .smoothing import VelocityFilter

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["default_solver"]


def _checked_solver(solver):
    """The solver option: None → the default solver; an instance with a ``solve`` method;
    otherwise InputError (a solver class instead of an instance is named as such)."""
    solver = default_solver() if solver is None else solver
    if isinstance(solver, type):
        raise InputError(f"solver must be a solver instance: pass {solver.__name__}() (with its "
                         f"options), not the class {solver.__name__}", argument="solver", value=solver)
    if not callable(getattr(solver, "solve", None)):
        raise InputError("solver must have a solve(J, xi, ...) method (see ratectl.solvers), "
                         f"got {type(solver).__name__}", argument="solver", value=solver)
    return solver


def _checked_gain(gain) -> np.ndarray:
    """The gain option as 6 non-negative finite values [1/s], or InputError."""
    try:
        K = np.broadcast_to(np.asarray(gain, dtype=float), (6,)).copy()
    except (TypeError, ValueError):  # not numbers, or not a scalar / 6 values
        K = None
    if K is None or not np.all(np.isfinite(K)) or np.any(K < 0):
        raise InputError(f"gain must be a non-negative scalar or 6 values [1/s], got {gain!r}",
                         argument="gain", value=gain)
    return K


def _checked_filter(smoothing, chain: Chain) -> VelocityFilter | None:
    """The smoothing option as a filter (None without smoothing), or InputError."""
    if smoothing is False or smoothing is None:
        return None
    n = chain.dof
    if smoothing is True:
        for name in ("vmax", "amax", "jmax"):
            a = getattr(chain, name)
            if not np.all(np.isfinite(a)):
                raise InputError(f"smoothing=True needs finite {name} on every joint of {chain.name!r}; "
                                 f"give them with chain.with_limits({name}=...) (or the importer's "
                                 f"{name}= keyword), or pass a VelocityFilter", argument="smoothing",
                                 value=a)
        filt = VelocityFilter(n, dt=1e-3, vmax=chain.vmax, amax=chain.amax, jmax=chain.jmax)
    elif isinstance(smoothing, VelocityFilter):
        filt = smoothing
    else:
        raise InputError("smoothing must be False, True or a ratectl.smoothing.VelocityFilter, "
                         f"got {smoothing!r}", argument="smoothing", value=smoothing)
    if filt.dof != n:
        raise InputError(f"the VelocityFilter has {filt.dof} joints, the chain {n}",
                         argument="smoothing", value=smoothing)
    return filt


def default_solver():
    """The controller's default inverse-velocity solver: ``rc.solvers.AdaptiveDLS()``."""
    return solvers.AdaptiveDLS()
