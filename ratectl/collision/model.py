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
        self._tf = [coal.Transform3s() for _ in self.shapes]  # each shape's pose, set per cycle
        links = sorted({s.link for s in self.shapes if s.link is not None})
        self._links = links
        # the rigid bodies the links lie on (the links after the same joint move as one):
        # one pose and Jacobian per body and cycle, each link shape placed on its body
        rep: dict[int, tuple[str, np.ndarray]] = {}
        for lk in links:
            k, T = chain.link_placement(lk)
            rep.setdefault(k, (lk, T))
        self._bodies = sorted(rep)
        self._body_link = [rep[k][0] for k in self._bodies]
        slot = {k: b for b, k in enumerate(self._bodies)}
        self._arm = [i for i, s in enumerate(self.shapes) if s.link is not None]
        self._obst = [i for i, s in enumerate(self.shapes) if s.link is None]
        self._shape_body = np.full(len(self.shapes), len(self._bodies))  # obstacles: a fixed "body"
        rel = []
        for i in self._arm:
            sh = self.shapes[i]
            assert sh.link is not None
            k, T = chain.link_placement(sh.link)
            self._shape_body[i] = slot[k]
            rel.append(np.linalg.solve(rep[k][1], T) @ sh.placement)  # body frame → shape
        self._rel = np.array(rel).reshape(-1, 4, 4)
        self._arm_body = self._shape_body[self._arm]
        B = len(self._bodies)
        self._P = np.zeros((B + 1, 4, 4))  # body poses; the last row stays zero (obstacles)
        self._J = np.zeros((B + 1, 6, chain.dof))  # body Jacobians at the body origins
        self._moving = []
        for b, (k, lk) in enumerate(zip(self._bodies, self._body_link, strict=True)):
            if k == 0:  # on the base: a constant pose, no Jacobian
                self._P[b] = chain.fk(np.zeros(chain.dof), link=lk)
            else:
                self._moving.append((b, lk))
        self._moving_links = tuple(lk for _, lk in self._moving)
        self._pi = np.array([i for i, _ in self.pairs], dtype=int)
        self._pj = np.array([j for _, j in self.pairs], dtype=int)
        self._rsum = np.array([self.shapes[i].radius + self.shapes[j].radius for i, j in self.pairs])
        self._centre = np.array([s.centre for s in self.shapes], dtype=float).reshape(-1, 3)
        self._radius = np.array([s.radius for s in self.shapes], dtype=float)
        # the last distances computed (per pair) and the shapes' poses they are referred to
        self._d0: np.ndarray | None = None
        self._R0 = np.empty((0, 3, 3))
        self._c0 = np.empty((0, 3))

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
    def _lower_bounds(self, R: np.ndarray, c: np.ndarray) -> np.ndarray:
        """A lower bound (P,) of every pair's distance at the shapes' rotations R (S, 3, 3) and
        bounding-sphere centres c (S, 3), from two facts:

        * the bounding spheres: d ≥ |c_i − c_j| − r_i − r_j;
        * the last distance computed, d₀ at rotations R⁰ and centres c⁰: a point of shape i
          (within r_i of its centre) has moved by at most |c_i − c_i⁰| + r_i‖R_i − R_i⁰‖₂
          since, with ‖R − R⁰‖₂ = ‖R − R⁰‖_F/√2 for two rotations, and the distance of two
          shapes changes by at most the sum of their points' largest displacements:
          d ≥ d₀ − δ_i − δ_j.
        """
        pi, pj = self._pi, self._pj
        gap = np.sqrt(((c[pi] - c[pj]) ** 2).sum(axis=1)) - self._rsum
        if self._d0 is None:
            return gap
        move = np.sqrt(((c - self._c0) ** 2).sum(axis=1)) \
            + self._radius * np.sqrt(((R - self._R0) ** 2).sum(axis=(1, 2)) * 0.5)
        return np.maximum(gap, self._d0 - move[pi] - move[pj])

    def rows(self, q: np.ndarray) -> CollisionRows:
        """The damper rows ``G q̇ ≤ h`` at q for the pairs closer than the influence distance.

        Only the pairs whose lower bound (`_lower_bounds`: bounding spheres, and the last
        computed distance less how far the shapes have moved since) is below the influence
        distance go to the geometry library; the model keeps those last distances, so one
        model serves one loop (not thread-safe). Any q may follow any other: the bound is
        computed from the poses, not from a time step.
        """
        chain = self.chain
        n = chain.dof
        coal = self._coal
        shapes = self.shapes
        P, Jb = self._P, self._J
        # every moving link's pose and Jacobian in one pass of the chain
        for (b, _), (T, J) in zip(self._moving, chain.fk_jacobian_links(q, self._moving_links), strict=True):
            P[b] = T
            Jb[b] = J
        S = len(shapes)
        W = np.empty((S, 4, 4))
        W[self._arm] = np.matmul(P[self._arm_body], self._rel)
        for k in self._obst:
            s = shapes[k]
            W[k] = s.obstacle.pose if s.obstacle is not None else s.placement
        R = W[:, :3, :3]
        c = np.einsum("kij,kj->ki", R, self._centre) + W[:, :3, 3]
        lb = self._lower_bounds(R, c)
        ds, di, xi = self.margin, self.influence, self.gain
        near = np.flatnonzero(lb < di)
        # every pair's bound is now referred to the current poses (d₀ ← the bound, exact
        # below for the pairs computed now)
        self._d0, self._R0, self._c0 = lb, R, c  # (W is this call's own)
        d0 = lb
        Rc = np.ascontiguousarray(R)
        tc = np.ascontiguousarray(W[:, :3, 3])
        tfs = self._tf
        placed = [False] * S  # shapes whose coal transform holds this cycle's pose
        req, res = self._req, self._res
        # per row: the signed distance, the pair, and for each side (its link, the witness
        # point, ±n̂); the rows are assembled for all pairs at once after the loop
        dist, names, wit, side_body = [], [], [], []
        body = self._shape_body.tolist()
        closest, closest_pair = np.inf, None
        for k in near.tolist():
            i, j = self.pairs[k]
            a, b = shapes[i], shapes[j]
            ta, tb = tfs[i], tfs[j]
            if not placed[i]:
                ta.setTransform(Rc[i], tc[i])
                placed[i] = True
            if not placed[j]:
                tb.setTransform(Rc[j], tc[j])
                placed[j] = True
            res.clear()
            d = float(coal.distance(a.geometry, ta, b.geometry, tb, req, res))
            d0[k] = d
            if d < closest:
                closest, closest_pair = d, (a.name, b.name)
            if d >= di:
                continue
            nv = res.normal.tolist()
            wit.append(res.getNearestPoint1().tolist() + [-nv[0], -nv[1], -nv[2]])
            wit.append(res.getNearestPoint2().tolist() + nv)
            side_body += [body[i], body[j]]
            dist.append(d)
            names.append((a.name, b.name))
        m = len(dist)
        if not m:
            return CollisionRows(G=np.zeros((0, n)), h=np.zeros(0), distance=np.zeros(0), pairs=(),
                                 closest=float(closest), closest_pair=closest_pair)
        # ḋ = Σ over the two sides of ±n̂ᵀ J_v(p) q̇, with J_v(p) = J_v(o) − [p − o]× J_ω:
        # ±(n̂ᵀ J_v(o) + ((p − o) × n̂)ᵀ J_ω) = w ᵀ J (w = [±n̂; (p − o) × ±n̂], 6 numbers)
        idx = np.array(side_body)
        w = np.array(wit)  # (2m, 6): the witness point, ±n̂
        r = w[:, :3] - P[idx, :3, 3]
        nv = w[:, 3:].copy()
        w[:, :3] = nv
        w[:, 3] = r[:, 1] * nv[:, 2] - r[:, 2] * nv[:, 1]
        w[:, 4] = r[:, 2] * nv[:, 0] - r[:, 0] * nv[:, 2]
        w[:, 5] = r[:, 0] * nv[:, 1] - r[:, 1] * nv[:, 0]
        rows2 = np.matmul(w[:, None, :], Jb[idx])[:, 0, :]  # (2m, n)
        G = -(rows2[0::2] + rows2[1::2])  # −ḋ ≤ ξ (d − d_s)/(d_i − d_s)
        distance = np.array(dist)
        h = xi * (distance - ds) / (di - ds)
        return CollisionRows(G=G, h=h, distance=distance, pairs=tuple(names), closest=float(closest),
                             closest_pair=closest_pair)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.chain.name!r}, {len(self.shapes)} shapes, {len(self.pairs)} "
                f"pairs, margin={self.margin:g} m)")


def shape_from_element(element: Any, link: str, placement: np.ndarray, group: str, name: str) -> Shape:
    """A link `Shape` from a URDF collision element (`ratectl.io.urdf_geometry.CollisionElement`)."""
    geom, centre, radius = coal_geometry(element.kind, element.size, element.filename, element.scale)
    return Shape(name=name, link=link, placement=placement, geometry=geom, centre=centre, radius=radius,
                 group=group)
