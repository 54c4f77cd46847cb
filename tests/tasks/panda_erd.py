"""The Panda of the example-robot-data package (URDF with real collision meshes), shared by
the tasks/collision tests, the benchmark and the example: where its files are, the chain with
acceleration limits, and an independent measure of the distance between its links
(Pinocchio's own collision model on the URDF's meshes, with coal)."""

from __future__ import annotations

import glob
import os
import sys

import numpy as np

import ratectl as rc


def panda_urdf() -> str | None:
    """Path of example-robot-data's panda.urdf, or None when the package is not installed."""
    roots = [os.path.join(p, "cmeel.prefix", "share") for p in sys.path if p]
    roots += [os.path.join(sys.prefix, "share")]
    for root in roots:
        hits = glob.glob(os.path.join(root, "example-robot-data", "robots", "panda_description", "urdf",
                                      "panda.urdf"))
        if hits:
            return hits[0]
    return None


def panda_chain(path: str) -> rc.Chain:
    """The Panda to its TCP with the datasheet's acceleration limits (the URDF has none)."""
    amax = [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]
    return rc.Chain.from_urdf(path, tip="panda_hand_tcp").with_limits(amax=amax)


def default_overlaps(sc) -> tuple[tuple[str, str], ...]:
    """The link pairs a `SelfCollision` model leaves out because their shapes overlap in the
    default configuration (the Panda: link 5 with link 7 and with the hand, which the SRDF of
    example-robot-data disables too, reason "Default"): left out of the measure as well."""
    return tuple((a, b) for a, b, why in sc.excluded if why.startswith("overlap in the default"))


def srdf_default_pairs(path: str) -> set[frozenset[str]]:
    """The link pairs the package's SRDF (beside the URDF) disables with reason "Default"."""
    import re

    srdf = os.path.join(os.path.dirname(os.path.dirname(path)), "srdf", "panda.srdf")
    text = open(srdf, encoding="utf-8").read()
    return {frozenset(m.groups()) for m in re.finditer(
        r'<disable_collisions link1="([^"]+)" link2="([^"]+)" reason="Default"', text)}

HOME = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])


class PinocchioDistance:
    """Smallest distance between non-adjacent links of the Panda, measured by Pinocchio
    (its URDF parser and its own geometry model, coal distances): a second method beside
    ratectl's collision module. Adjacent = joined by one joint (parent/child bodies), and the
    hand/fingers group counts as one body. Fingers are held at 0 (closed).

    ``convex=False`` measures the meshes themselves (coal's BVH: 0 when two meshes
    intersect, ~20 ms a call); ``convex=True`` their convex hulls (signed: negative is the
    penetration depth; ~1 ms a call), a lower bound of the mesh distance."""

    def __init__(self, path: str, *, exclude=(), convex: bool = False) -> None:
        import pinocchio as pin

        self.pin = pin
        pkg = path.split("example-robot-data")[0]
        self.model = pin.buildModelFromUrdf(path)
        self.geom = pin.buildGeomFromUrdf(self.model, path, pin.GeometryType.COLLISION, package_dirs=[pkg])
        if convex:
            for g in self.geom.geometryObjects:
                if hasattr(g.geometry, "buildConvexHull"):
                    g.geometry.buildConvexHull(True, "Qt")
                    g.geometry = g.geometry.convex
        self.geom.addAllCollisionPairs()
        names = [g.name for g in self.geom.geometryObjects]
        parents = [self.model.frames[g.parentFrame].name for g in self.geom.geometryObjects]
        order = {f"panda_link{i}": i for i in range(8)}
        for nm in ("panda_link8", "panda_hand", "panda_leftfinger", "panda_rightfinger"):
            order[nm] = 7  # rigidly fixed to link7 (fingers held)
        keep = []
        for k, cp in enumerate(self.geom.collisionPairs):
            a, b = order[parents[cp.first]], order[parents[cp.second]]
            pa, pb = parents[cp.first], parents[cp.second]
            if abs(a - b) > 1 and {pa, pb} not in [set(e) for e in exclude]:
                keep.append(k)
        self.pairs = [(names[self.geom.collisionPairs[k].first], names[self.geom.collisionPairs[k].second])
                      for k in keep]
        self.keep = keep
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geom)

    def __call__(self, q: np.ndarray) -> float:
        pin = self.pin
        qp = np.zeros(self.model.nq)
        qp[:7] = q
        pin.computeDistances(self.model, self.data, self.geom, self.gdata, qp)
        return float(min(self.gdata.distanceResults[k].min_distance for k in self.keep))
