"""Workspace maps of a singularity measure over two joints or a Cartesian plane, and their plot.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from .measures import _BOUNDARY, _ELBOW, _RANKDEF, _SHOULDER, _WRIST, KINDS, _ro, check_chain
from .scan import scan

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..model.chain import Chain

__all__ = ['workspace_map', 'WorkspaceMap', 'plot_workspace_map', 'joint_pair']


def joint_pair(chain: Chain, joints: Any) -> tuple[int, int]:
    """Two different joints of ``chain`` as 0-based indices, from indices (0-based) or the
    chain's joint names; `InputError` naming what is allowed otherwise."""
    names = list(chain.joint_names)
    n = chain.dof
    out = []
    try:
        if isinstance(joints, str | bytes) or len(joints) != 2:
            raise TypeError("joints")
        for v in joints:
            if isinstance(v, str):
                out.append(names.index(v))
            elif isinstance(v, bool) or not isinstance(v, int | np.integer) or not 0 <= v < n:
                raise ValueError(v)
            else:
                out.append(int(v))
    except (TypeError, ValueError):
        raise InputError(f"joints must be two different joints of {chain.name}, as 0-based indices in "
                         f"0..{n - 1} or joint names {names}; got {joints!r}", argument="joints",
                         value=joints) from None
    if out[0] == out[1]:
        raise InputError(f"joints must be two different joints, got {joints!r} (both {names[out[0]]!r})",
                         argument="joints", value=joints)
    return out[0], out[1]


# ====================================================================== workspace maps
_MEASURES = ("manipulability", "manipulability_scaled", "sigma_min_scaled", "inverse_condition_scaled")


@dataclass(frozen=True, kw_only=True)
class WorkspaceMap:
    """A 2-D map of a singularity measure (see `workspace_map`).

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


def workspace_map(chain: Chain, *, joints: tuple[int, int] | None = None, plane: str | None = None,
                  q: ArrayLike | None = None, ranges: Any = None, resolution: int = 121, offset: float = 0.0,
                  slab: float = 0.02, samples: int = 400_000, measure: str = "manipulability",
                  length: float | None = None, rng: np.random.Generator | int | None = 0) -> WorkspaceMap:
    """Map a singularity measure over two joints, or over a plane of tool positions.

    Exactly one of:

    * ``joints=(i, j)`` (0-based indices, or the chain's joint names): a
      ``resolution × resolution`` grid of q_i, q_j over
      ``ranges = ((lo_i, hi_i), (lo_j, hi_j))`` (default the joints' own limits, the whole
      range however wide; ±π for a joint without limits), other joints at ``q`` (default
      zeros, clipped into the limits); the axes are labelled with the joint names;
    * ``plane="xz"`` (or ``"xy"``, ``"yz"``; world axes): random configurations
      (``samples``, uniform in the limits) whose tool origin lies within ``slab/2`` m of
      the plane (third coordinate = ``offset`` [m]) are binned into a grid over
      ``ranges`` (default ±1.1·reach); each cell holds the **best** (largest) value
      reached there, NaN where no sample fell.

    Args:
        measure: one of "manipulability" (raw w), "manipulability_scaled",
            "sigma_min_scaled", "inverse_condition_scaled".
        length: characteristic length L [m] for the scaled measures.
        rng: seed or Generator for plane mode.
    """
    check_chain(chain)
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
        i, j = joint_pair(chain, joints)
        base = np.clip(np.zeros(n), lo, hi) if q is None else chain.check_q(q).copy()
        if ranges is None:
            ranges = ((lo[i], hi[i]), (lo[j], hi[j]))
        x = np.linspace(float(ranges[0][0]), float(ranges[0][1]), resolution)
        y = np.linspace(float(ranges[1][0]), float(ranges[1][1]), resolution)
        Q = np.broadcast_to(base, (resolution, resolution, n)).copy()
        Q[..., i] = x[None, :]
        Q[..., j] = y[:, None]
        res = scan(chain, Q, length=length)
        vals = getattr(res, measure)
        names = chain.joint_names
        unit = ["m" if chain.prismatic[k] else "rad" for k in (i, j)]
        return WorkspaceMap(mode="joints", x=_ro(x), y=_ro(y), values=_ro(np.array(vals)),
                            measure=measure, xlabel=f"{names[i]} [{unit[0]}]",
                            ylabel=f"{names[j]} [{unit[1]}]",
                            title=f"{chain.name}: {measure} over {names[i]}, {names[j]}",
                            kind_code=res.kind_code)
    axes = {"xy": (0, 1, 2), "xz": (0, 2, 1), "yz": (1, 2, 0)}
    if plane not in axes:
        raise InputError(f"plane must be 'xy', 'xz' or 'yz', got {plane!r}", argument="plane", value=plane)
    ax0, ax1, ax2 = axes[plane]
    R = 1.1 * chain.reach()
    if ranges is None:
        base_p = chain.base[:3, 3]
        ranges = ((base_p[ax0] - R, base_p[ax0] + R), (base_p[ax1] - R, base_p[ax1] + R))
    x = np.linspace(float(ranges[0][0]), float(ranges[0][1]), resolution)
    y = np.linspace(float(ranges[1][0]), float(ranges[1][1]), resolution)
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


def plot_workspace_map(wmap: WorkspaceMap, *, ax: Axes | None = None, cmap: str = "viridis",
                       colorbar: bool = True, show_kinds: bool = True):
    """Plot a `WorkspaceMap` with matplotlib (imported here; ``pip install matplotlib``).

    In joints mode with ``show_kinds``, the near-singular grid points are outlined by
    kind (white contours labelled wrist/elbow/shoulder/...). Returns the Axes.
    """
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("plot_workspace_map needs matplotlib: pip install matplotlib") from exc
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
