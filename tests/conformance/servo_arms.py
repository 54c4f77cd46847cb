"""Arms for the servo conformance suites: URDF arms imported from the ``example-robot-data``
package (written by others, not for this project), the built-ins, random DH chains, and
seeded regular start configurations.

The URDF files carry joint ranges and velocity limits but no acceleration or jerk limits;
`urdf_arms` gives every joint amax = 10 rad/s² and jmax = 100 rad/s³ (the values of the
built-in UR5e, PUMA and iiwa7) with ``chain.with_limits``, as a user would before turning
smoothing on. The velocity limits and ranges stay the file's.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, distribution

import numpy as np

import ratectl as rc

AMAX = 10.0    # rad/s² given to the URDF arms (no acceleration limit in the files)
JMAX = 100.0   # rad/s³

# name → (file under the package's robots/ directory, tip link): the serial arms it ships
URDF_FILES = {
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef"),
    "jaco2": ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector"),  # Kinova j2s6s200
}

# built-ins with 6 or more joints: a straight line of poses is reachable for them (the
# 2- and 3-joint arms reach only a subset of poses, so a 6-D step target is not defined)
BUILTIN_6D = ("ur5e", "panda", "puma560", "stanford", "iiwa7")


def robots_dir() -> str | None:
    """The ``robots/`` directory of the installed example-robot-data package, or None."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return None
    path = str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    return path if os.path.isdir(path) else None


def urdf_arm(name: str) -> rc.Chain:
    """The example-robot-data arm ``name`` (see `URDF_FILES`) with amax and jmax added."""
    root = robots_dir()
    if root is None:
        raise FileNotFoundError("example-robot-data is not installed")
    rel, tip = URDF_FILES[name]
    chain = rc.Chain.from_urdf(os.path.join(root, rel), tip=tip)
    return chain.with_limits(amax=AMAX, jmax=JMAX)


def urdf_arms() -> dict[str, Callable[[], rc.Chain]]:
    """Name → factory of the example-robot-data arms (empty if the package is missing)."""
    if robots_dir() is None:
        return {}
    return {f"erd:{k}": (lambda k=k: urdf_arm(k)) for k in URDF_FILES}


def builtin_arms() -> dict[str, Callable[[], rc.Chain]]:
    return {f"builtin:{k}": rc.robots.BUILTIN[k] for k in BUILTIN_6D}


def sweep_arms() -> dict[str, Callable[[], rc.Chain]]:
    """Every arm of the straight-approach sweep: the imported URDF arms, then the built-ins."""
    return {**urdf_arms(), **builtin_arms()}


def random_chain(rng: np.random.Generator, n: int = 6, *, name: str | None = None) -> rc.Chain:
    """A random revolute DH arm of ``n`` joints, robot-like: twists from {0, ±π/2}, link
    lengths a ∈ {0} ∪ [0.1, 0.45] m and offsets d ∈ {0} ∪ [0.05, 0.35] m (at least 0.6 m of
    reach), ranges ±2.8 rad, vmax ∈ [1.5, 3] rad/s, amax 10 rad/s², jmax 100 rad/s³; drawn
    again until at least 6 of 20 random configurations have a scaled σ_min ≥ 0.05 (a
    degenerate draw, whose axes stay parallel, never does)."""
    while True:
        rows = []
        for i in range(n):
            alpha = float(rng.choice([0.0, math.pi / 2, -math.pi / 2]))
            a = 0.0 if rng.random() < 0.4 else float(rng.uniform(0.1, 0.45))
            d = 0.0 if rng.random() < 0.4 else float(rng.uniform(0.05, 0.35))
            if i == 0:
                alpha, a = math.pi / 2, 0.0   # a shoulder: the first two axes cross
            rows.append(rc.DH(a=a, alpha=alpha, d=d, theta=float(rng.uniform(-0.5, 0.5)),
                              qlim=(-2.8, 2.8), vmax=float(rng.uniform(1.5, 3.0)),
                              amax=AMAX, jmax=JMAX))
        tool = np.eye(4)
        tool[2, 3] = float(rng.uniform(0.0, 0.15))
        if sum(r.a + r.d for r in rows) < 0.6:
            continue
        chain = rc.Chain.from_dh(rows, tool=tool, name=name or f"random{n}")
        # keep arms whose configurations are mostly regular (no axes parallel for good)
        qs = rng.uniform(-2.5, 2.5, size=(20, n))
        if sum(sigma_min(chain, q) >= 0.05 for q in qs) >= 6:
            return chain


def sigma_min(chain: rc.Chain, q: np.ndarray) -> float:
    """The smallest singular value of the length-scaled Jacobian at q (what
    ``rc.analyze(chain, q).sigma_min_scaled`` reports): units-consistent, so one threshold
    serves arms of different sizes."""
    return float(rc.analyze(chain, q).sigma_min_scaled)


def window(chain: rc.Chain, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """A sampling box for start configurations: the joint range shrunk by ``margin`` (at
    most a quarter of the range), and ±π where a joint is continuous (unlimited)."""
    m = np.minimum(margin, 0.25 * (chain.upper - chain.lower))
    lo = np.where(np.isfinite(chain.lower), chain.lower + m, -math.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper - m, math.pi)
    return lo, hi


def regular_start(chain: rc.Chain, rng: np.random.Generator, *, sigma: float = 0.05,
                  margin: float = 0.3, tries: int = 500) -> np.ndarray:
    """A random configuration inside the range (``margin`` [rad or m] from every limit) whose
    scaled σ_min is at least ``sigma``: a start away from singularities and limits."""
    lo, hi = window(chain, margin)
    for _ in range(tries):
        q = rng.uniform(lo, hi)
        if sigma_min(chain, q) >= sigma:
            return q
    raise RuntimeError(f"{chain.name}: no regular start with σ_min ≥ {sigma} in {tries} draws")
