"""`SelfCollision` and `Obstacles`: collision models read from a URDF's own collision
geometry (meshes and primitives), the first between the arm's links, the second between
the links and obstacles placed in the base frame."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import InputError
from ..io.urdf_geometry import urdf_collision_geometry
from .model import CollisionModel, Shape, shape_from_element
from .shapes import coal_geometry

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["SelfCollision", "Obstacles", "arm_shapes", "default_configuration"]


def arm_shapes(path: Any, chain: Chain, *, package_dirs: Any = None,
               links: Iterable[str] | None = None) -> tuple[list[Shape], dict[str, int], tuple[str, ...]]:
    """The URDF's collision shapes fixed to the chain's links.

    A URDF link that is one of ``chain.link_names`` carries its shapes; a link hanging below
    them through joints that are not on the chain (a gripper's fingers) carries them at those
    joints' zero position, attached to the nearest chain link above it.

    Returns:
        (shapes, the chain joint index each shape's link follows, the held links' names).
    """
    geo = urdf_collision_geometry(path, package_dirs=package_dirs)
    names = set(chain.link_names)
    wanted = None if links is None else set(links)
    shapes: list[Shape] = []
    index: dict[str, int] = {}
    held: set[str] = set()
    count: dict[str, int] = {}
    for el in geo.elements:
        if wanted is not None and el.link not in wanted:
            continue
        link, T = el.link, np.eye(4)
        while link not in names:
            up = geo.parents.get(link)
            if up is None:
                break
            parent, _, jtype, origin = up
            if jtype != "fixed":
                held.add(el.link)
            T = origin @ T
            link = parent
        if link not in names:
            continue  # above the chain's base: not part of the arm
        k = count[el.link] = count.get(el.link, 0) + 1
        name = el.link if k == 1 else f"{el.link}#{k}"
        shapes.append(shape_from_element(el, link, T @ el.origin, el.link, name))
        index[name] = chain.link_placement(link)[0]
    return shapes, index, tuple(sorted(held))


def _pairs_by_name(pairs: Iterable[Sequence[str]] | None, what: str) -> set[frozenset[str]]:
    out = set()
    for p in pairs or ():
        if isinstance(p, str) or len(p) != 2:
            raise InputError(f"{what} must be pairs of link names, got {p!r}", argument=what, value=p)
        out.add(frozenset(p))
    return out


class SelfCollision(CollisionModel):
    """Keep the arm's links apart (see `CollisionModel` for the damper rows)."""

    @classmethod
    def from_urdf(cls, path: Any, chain: Chain, *, margin: float = 0.02, influence: float | None = None,
                  gain: float = 0.5, exclude: Iterable[Sequence[str]] | None = None,
                  include: Iterable[Sequence[str]] | None = None, obstacles: Sequence[Any] = (),
                  package_dirs: Any = None, default_overlap: bool = True) -> SelfCollision:
        """Self-collision from the URDF's collision geometry (the convex hull of each mesh).

        Left out, each listed in ``excluded`` with its reason:

        * pairs of links on the same or on neighbouring chain joints (adjacent links, which
          touch by construction); a gripper's links count as the link they hang from;
        * with ``default_overlap`` (default), pairs whose shapes overlap in the default
          configuration `default_configuration` (every joint at 0, or at the middle of its
          range where 0 is outside it): a pose the arm takes, so their collision geometry is
          coarser than the links there (a damper on them would hold the arm near that
          pose). This is the "Default" reason of a MoveIt SRDF (e.g. the Panda's link 5
          with link 7 and with the hand);
        * the pairs of ``exclude``.

        Args:
            path: the URDF file (the one ``chain`` was read from).
            chain: the arm (`ratectl.Chain.from_urdf`).
            margin: the security distance d_s [m]; influence, gain: see `CollisionModel`.
            exclude: more link pairs to leave out, e.g. ``[("panda_link3", "panda_hand")]``.
            include: link pairs to check after all (adjacent, or overlapping in the default
                configuration).
            obstacles: `ratectl.collision.Sphere`, `Box`, `Mesh` objects, checked against
                every link.
            package_dirs: directories for ``package://`` mesh URIs.
            default_overlap: leave out the pairs that overlap in the default configuration.
        """
        shapes, index, held = arm_shapes(path, chain, package_dirs=package_dirs)
        ex, inc = _pairs_by_name(exclude, "exclude"), _pairs_by_name(include, "include")
        pairs, excluded = [], []
        seen = set()
        for i, a in enumerate(shapes):
            for j in range(i + 1, len(shapes)):
                b = shapes[j]
                key = frozenset((a.group, b.group))
                ka, kb = index[a.name], index[b.name]
                why = ""
                if a.group == b.group:
                    continue  # shapes of one link
                if key in ex:
                    why = "excluded by the caller"
                elif abs(ka - kb) <= 1 and key not in inc:
                    why = "adjacent (same or neighbouring joint)"
                if why:
                    if key not in seen:
                        excluded.append((a.group, b.group, why))
                        seen.add(key)
                    continue
                pairs.append((i, j))
        if default_overlap and pairs:
            q0 = default_configuration(chain)
            d = cls(chain, shapes, pairs, margin=margin, influence=influence, gain=gain).distances(q0)
            overlap: dict[frozenset[str], float] = {}
            for (i, j), dk in zip(pairs, d.tolist(), strict=True):
                key = frozenset((shapes[i].group, shapes[j].group))
                if dk < 0.0 and key not in inc:
                    overlap[key] = min(overlap.get(key, 0.0), dk)
            for key, dk in overlap.items():
                ga, gb = sorted(key)
                excluded.append((ga, gb, f"overlap in the default configuration (by {-dk * 1e3:.3g} mm)"))
            pairs = [(i, j) for i, j in pairs if frozenset((shapes[i].group, shapes[j].group)) not in overlap]
        obstacle_pairs(shapes, pairs, obstacles)
        model = cls(chain, shapes, pairs, margin=margin, influence=influence, gain=gain,
                    excluded=tuple(excluded))
        model.held_links = held
        return model


def default_configuration(chain: Chain) -> np.ndarray:
    """The chain's default configuration (n,) [rad or m]: every joint at 0, or at the middle of
    its range where 0 is outside it (the default state of a MoveIt robot model)."""
    lo, hi = np.asarray(chain.qlim, dtype=float).T
    return np.where((lo <= 0.0) & (0.0 <= hi), 0.0, 0.5 * (lo + hi))


class Obstacles(CollisionModel):
    """Keep the arm's links away from obstacles in the base frame."""

    @classmethod
    def from_urdf(cls, path: Any, chain: Chain, obstacles: Sequence[Any], *, margin: float = 0.02,
                  influence: float | None = None, gain: float = 0.5, links: Iterable[str] | None = None,
                  package_dirs: Any = None) -> Obstacles:
        """Obstacle avoidance for the links of the URDF (default every link with collision
        geometry; ``links`` names a subset) against ``obstacles`` (`Sphere`, `Box`, `Mesh`)."""
        shapes, _, held = arm_shapes(path, chain, package_dirs=package_dirs, links=links)
        if not shapes:
            raise InputError("no collision geometry on the chosen links", argument="links", value=links)
        pairs: list[tuple[int, int]] = []
        obstacle_pairs(shapes, pairs, obstacles)
        model = cls(chain, shapes, pairs, margin=margin, influence=influence, gain=gain)
        model.held_links = held
        return model


def obstacle_pairs(shapes: list[Shape], pairs: list[tuple[int, int]], obstacles: Sequence[Any]) -> None:
    """Append the obstacles to ``shapes`` and a pair (link shape, obstacle) for each to ``pairs``."""
    arm = [i for i, s in enumerate(shapes) if s.link is not None]
    for ob in obstacles:
        if not hasattr(ob, "kind") or not hasattr(ob, "pose"):
            raise InputError(f"obstacles must be ratectl.collision Sphere, Box or Mesh objects, got {ob!r}",
                             argument="obstacles", value=ob)
        geom, centre, radius = coal_geometry(ob.kind, ob.size, ob.filename, ob.scale)
        shapes.append(Shape(name=ob.name, link=None, placement=np.eye(4), geometry=geom, centre=centre,
                            radius=radius, group=f"obstacle:{ob.name}", obstacle=ob))
        k = len(shapes) - 1
        pairs.extend((i, k) for i in arm)
