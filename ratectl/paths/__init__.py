"""Cartesian tool paths and their time laws.

A path is a curve of tool poses ``P(s) = (p(s), R(s))`` over a path parameter
``s ∈ [0, length]`` [m], plus a *time law* ``s(t)`` built from Cartesian speed,
acceleration (and jerk) limits. Every path answers four questions:

* ``pose_at(s)`` → 4×4 pose, ``twist_at(s, sd=1)`` → ``[dp/ds; ω/ṡ]·ṡ`` (6,),
* ``pose(t)`` → 4×4 pose at time t, ``twist(t)`` → the tool twist ``[v; ω]`` at time t.

Positions move on the curve (a segment, a circular arc, blended segments); the
orientation moves on the SO(3) geodesic ``R(λ) = R₀ exp(λ w)`` (λ ∈ [0, 1] the
fraction of the segment), so the angular velocity in base axes is
``ω = R₀ w dλ/dt``.

The path parameter is the combined length ``s`` with ``ds² = dp² + (ρ dθ)²``,
ρ = ``rotation_length`` [m/rad] (default 0.1 m): on a path at constant
orientation ``s`` is the arc length of the tool origin, and a pure rotation still
has a positive length (so "speed" limits the angular rate to speed/ρ).

Time laws (``law=``):

* ``"trapezoidal"`` — constant acceleration a, cruise at v, constant deceleration;
  triangular when the path is shorter than v²/a.
* ``"jerk-limited"`` — the same with a jerk limit (a 1-D state-to-state Ruckig
  trajectory from rest at 0 to rest at ``length``).
* ``"quintic"`` — ``s = L(10τ³ − 15τ⁴ + 6τ⁵)``, τ = t/T, with T the shortest time for
  which the peak speed 15L/(8T) ≤ v and peak acceleration 10L/(√3 T²) ≤ a.
"""

from .arc import Arc
from .base import MAX_STEPS, Path
from .line import Line
from .time_laws import LAWS, JerkLimited, Quintic, TimeLaw, Trapezoidal, make_time_law
from .waypoints import Waypoints

__all__ = ["TimeLaw", "Trapezoidal", "JerkLimited", "Quintic", "make_time_law", "Path", "Line", "Arc",
           "Waypoints", "LAWS", "MAX_STEPS"]
