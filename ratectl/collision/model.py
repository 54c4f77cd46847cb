"""Distances between the arm's links and obstacles as velocity-damper rows ``G q̇ ≤ h``
(`CollisionModel`, `CollisionRows`).

For a pair of shapes at signed distance d (coal: GJK/EPA on convex shapes, negative when
they overlap) with witness points p₁, p₂ and unit normal n̂ from shape 1 to shape 2, the
distance changes at ḋ = n̂ᵀ(J₂(p₂) − J₁(p₁)) q̇, with Jᵢ(p) the linear rows of the
Jacobian of shape i's link at the point p (zero for an obstacle). The velocity damper
(Faverjon & Tournassoud 1987) keeps d above the security distance d_s (``margin``):

    ḋ ≥ −ξ (d − d_s)/(d_i − d_s)       for d < d_i (the influence distance)

i.e. the row ``−n̂ᵀ(J₂ − J₁) q̇ ≤ ξ (d − d_s)/(d_i − d_s)`` [m/s]. Far from d_s the pair may
approach at up to ξ [m/s]; at d_s it may not approach at all, and below d_s it must
separate. In continuous time d never crosses d_s from above (d − d_s decays at most
exponentially, at rate ξ/(d_i − d_s)).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..arrays import read_only
from ..checks import positive_number
from ..errors import InputError
from ..kinematics import shift_jacobian
from .shapes import coal_geometry, import_coal

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["CollisionModel", "CollisionRows", "Shape"]


@dataclass
class Shape:
    """One collision shape: on a link (``link``: a name of ``chain.link_names``, at
    ``placement`` in the link frame) or in the base frame (``link`` None, pose from
    ``obstacle.pose`` or ``placement``). ``centre`` and ``radius`` bound the geometry (in its
    own frame) for the broad phase."""

    name: str
    link: str | None
    placement: np.ndarray
    geometry: Any
    centre: np.ndarray
    radius: float
    group: str
    obstacle: Any = None


@dataclass(frozen=True, kw_only=True)
class CollisionRows:
    """The damper rows of one configuration.

    Attributes:
        G: (k, n) rows, h: (k,) bounds [m/s]: G q̇ ≤ h (pairs closer than the influence distance).
        distance: (k,) signed distances of those pairs [m].
        pairs: (k,) the pairs' shape names.
        closest: the smallest distance over all pairs checked [m] (inf when none is near).
        closest_pair: its shape names.
    """

    G: np.ndarray
    h: np.ndarray
    distance: np.ndarray
    pairs: tuple[tuple[str, str], ...]
    closest: float
    closest_pair: tuple[str, str] | None

    def __post_init__(self) -> None:
        for name in ("G", "h", "distance"):
            object.__setattr__(self, name, read_only(getattr(self, name)))


class CollisionModel:
    """Shapes on the arm's links and in the base frame, the pairs to keep apart, and their
    velocity-damper rows (see the module docstring). Build one with
    `ratectl.collision.SelfCollision.from_urdf` or `ratectl.collision.Obstacles.from_urdf`.

    Args:
        chain: the arm.
        shapes: the `Shape` list.
        pairs: index pairs (i, j) into ``shapes``.
        margin: d_s, the security distance [m].
        influence: d_i [m] (> margin), where a pair starts to count; default margin + 0.1.
        gain: ξ [m/s], the approach speed allowed at the influence distance.
        excluded: the pairs left out, with the reason (for `describe`).
    """

    def __init__(self, chain: Chain, shapes: list[Shape], pairs: list[tuple[int, int]], *,
                 margin: float = 0.02, influence: float | None = None, gain: float = 0.5,
                 excluded: tuple[tuple[str, str, str], ...] = ()) -> None:
        self.chain = chain
        self.shapes = list(shapes)
        self.pairs = [(int(i), int(j)) for i, j in pairs]
        self.margin = positive_number("margin", margin, allow_zero=True, unit="[m]")
        infl = self.margin + 0.1 if influence is None else positive_number("influence", influence,
                                                                            unit="[m]")
        if not infl > self.margin:
            raise InputError(f"influence ({infl} m) must exceed margin ({self.margin} m)",
                             argument="influence", value=influence)
        self.influence = infl
        self.gain = positive_number("gain", gain, unit="[m/s]")
        self.excluded = tuple(excluded)
        #: links whose shapes hang below joints off the chain, held at those joints' zero
        self.held_links: tuple[str, ...] = ()
        coal = import_coal()
        self._coal = coal
        self._req = coal.DistanceRequest()
        self._res = coal.DistanceResult()
        links = sorted({s.link for s in self.shapes if s.link is not None})
        self._links = links
        self._pi = np.array([i for i, _ in self.pairs], dtype=int)
        self._pj = np.array([j for _, j in self.pairs], dtype=int)
        self._rsum = np.array([self.shapes[i].radius + self.shapes[j].radius for i, j in self.pairs])

    # ------------------------------------------------------------------ description
    @property
    def pair_names(self) -> tuple[tuple[str, str], ...]:
        """The shape names of the pairs checked."""
        return tuple((self.shapes[i].name, self.shapes[j].name) for i, j in self.pairs)

    def describe(self) -> str:
        """The pairs checked and the pairs left out, with why."""
        lines = [f"{len(self.pairs)} pairs checked (margin {self.margin * 1e3:.3g} mm, influence "
                 f"{self.influence * 1e3:.3g} mm):"]
        lines += [f"  {a} – {b}" for a, b in self.pair_names]
        lines.append(f"{len(self.excluded)} pairs left out:")
        lines += [f"  {a} – {b}: {why}" for a, b, why in self.excluded]
        return "\n".join(lines)

    # ------------------------------------------------------------------ geometry
    def _poses(self, q: np.ndarray) -> dict[str | None, np.ndarray]:
        chain = self.chain
        out: dict[str | None, np.ndarray] = {None: np.eye(4)}
        for link in self._links:
            out[link] = chain.fk(q, link=link)
        return out

    def _world(self, s: Shape, poses) -> np.ndarray:
        if s.link is None:
            return s.obstacle.pose if s.obstacle is not None else s.placement
        return poses[s.link] @ s.placement

    def _distance(self, a: Shape, Ta: np.ndarray, b: Shape, Tb: np.ndarray):
        coal = self._coal
        res = self._res
        res.clear()
        d = coal.distance(a.geometry, coal.Transform3s(Ta[:3, :3], Ta[:3, 3]), b.geometry,
                          coal.Transform3s(Tb[:3, :3], Tb[:3, 3]), self._req, res)
        return float(d), np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()), \
            np.array(res.normal)

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Signed distance [m] of every pair at q (no broad phase), in `pair_names` order."""
        qv = self.chain.check_q(q)
        poses = self._poses(qv)
        W = [self._world(s, poses) for s in self.shapes]
        return np.array([self._distance(self.shapes[i], W[i], self.shapes[j], W[j])[0]
                         for i, j in self.pairs])

    # ------------------------------------------------------------------ rows
    def rows(self, q: np.ndarray) -> CollisionRows:
        """The damper rows ``G q̇ ≤ h`` at q for the pairs closer than the influence distance
        (a bounding-sphere test skips the others)."""
        chain = self.chain
        n = chain.dof
        poses = self._poses(q)
        W = [self._world(s, poses) for s in self.shapes]
        centres = np.array([T[:3, :3] @ s.centre + T[:3, 3] for T, s in zip(W, self.shapes, strict=True)])
        jac: dict[str, np.ndarray] = {}
        G, h, dist, names = [], [], [], []
        closest, closest_pair = np.inf, None
        ds, di, xi = self.margin, self.influence, self.gain
        gap = np.sqrt(((centres[self._pi] - centres[self._pj]) ** 2).sum(axis=1)) - self._rsum
        for k in np.flatnonzero(gap <= di).tolist():
            i, j = self.pairs[k]
            a, b = self.shapes[i], self.shapes[j]
            d, p1, p2, nrm = self._distance(a, W[i], b, W[j])
            if d < closest:
                closest, closest_pair = d, (a.name, b.name)
            if d >= di:
                continue
            row = np.zeros(n)
            for s, p, sign in ((a, p1, -1.0), (b, p2, 1.0)):
                if s.link is None:
                    continue
                J = jac.get(s.link)
                if J is None:
                    J = jac[s.link] = chain.jacobian(q, link=s.link)
                Jp = shift_jacobian(J, p - poses[s.link][:3, 3])[:3]
                row += sign * (nrm @ Jp)
            G.append(-row)  # −ḋ ≤ ξ (d − d_s)/(d_i − d_s)
            h.append(xi * (d - ds) / (di - ds))
            dist.append(d)
            names.append((a.name, b.name))
        return CollisionRows(G=np.array(G).reshape(-1, n), h=np.array(h), distance=np.array(dist),
                             pairs=tuple(names), closest=float(closest), closest_pair=closest_pair)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.chain.name!r}, {len(self.shapes)} shapes, {len(self.pairs)} "
                f"pairs, margin={self.margin:g} m)")


def shape_from_element(element: Any, link: str, placement: np.ndarray, group: str, name: str) -> Shape:
    """A link `Shape` from a URDF collision element (`ratectl.io.urdf_geometry.CollisionElement`)."""
    geom, centre, radius = coal_geometry(element.kind, element.size, element.filename, element.scale)
    return Shape(name=name, link=link, placement=placement, geometry=geom, centre=centre, radius=radius,
                 group=group)
