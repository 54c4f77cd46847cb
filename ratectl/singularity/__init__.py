"""Singularity analysis: measures, classification, explanations and workspace scans.

Modules: `.measures`, `.structure`, `.analysis` (classify, analyze),
`.scan` (scan, path distance), `.gradient`, `.maps`.

Measures (all batched over the leading dimensions of a (..., 6, n) Jacobian):

* singular values σ₁ ≥ … ≥ σ_m, m = min(6, n), and the rank with an explicit tolerance;
* Yoshikawa manipulability w = σ₁σ₂⋯σ_m, i.e. √det(J Jᵀ) for n ≥ 6 and √det(Jᵀ J) for
  n < 6 (where √det(J Jᵀ) would be identically zero);
* condition number κ = σ₁/σ_m and its inverse σ_m/σ₁ ∈ [0, 1];
* translational and rotational sub-measures, from the linear rows J_v and the
  angular rows J_ω alone (each is unit-homogeneous);
* unit-consistent variants: the linear rows are divided by a characteristic length L
  [m] (default ``chain.characteristic_length``), J_L = diag(I/L, I)·J, so that every
  entry is dimensionless and σ_min(J_L) is comparable between arms and between
  translation and rotation.

`analyze` returns a `SingularityReport` for one configuration: the
measures, the rank, the lost task-space directions and joint-space null vectors, the
kind of singularity ("regular", "wrist", "elbow", "shoulder", "boundary",
"rank-deficient"), a numeric closeness and a plain-language reason. `scan` does
the measures and the classification for many configurations at once.

Classification (see ``docs/singularity.md`` for the derivation). Everything is computed
from the Jacobian referred to the tool origin: the world axis of a revolute joint i is
``z_i = J_ω,i`` and ``c_i = z_i × J_v,i`` is a point on it (relative to the tool origin),
so the geometry of all joint axes comes for free with J. For 6-joint arms, three
dimensionless factors vanish exactly at the classic singularities:

* wrist: ``|det[z₄ z₅ z₆]|`` — the wrist axes linearly dependent (for a spherical
  wrist this is |det J₂₂|);
* elbow: for the first pair of consecutive arm axes that are parallel for every q
  (the "elbow pair" a, b), the sine of the angle between the plane of the two axes and
  the direction from axis b to the point P where the next axis meets the one after it
  (PUMA: the wrist centre; UR: the point o₄ on axis 4) — upper arm and forearm aligned;
* shoulder: the distance of the wrist point W (the point where the last two axes
  meet) from the plane through axis 1 parallel to axis 2, divided by L — the wrist
  point over the shoulder (with a shoulder offset W is then not on axis 1 itself).

A configuration is *near-singular* when σ_min(J_L) < ``near``; it is then labelled with
the smallest factor if that factor is below ``factor_tol``, else "boundary" when the arm
joints cannot move the wrist point in some direction (σ_min of their linear block at W
divided by L is below ``near``), else "rank-deficient". Arms with n ≠ 6 get only the
last two labels. Whether the configuration is exactly singular is the rank test
σ_i(J_L) ≤ rtol·σ₁(J_L).
"""

from .analysis import SingularityReport, analyze, classify
from .gradient import manipulability_gradient
from .maps import WorkspaceMap, plot_workspace_map, workspace_map
from .measures import (
    DEFAULT_FACTOR_TOL,
    DEFAULT_NEAR,
    DEFAULT_RTOL,
    KINDS,
    condition_number,
    manipulability,
    rank,
    singular_values,
)
from .scan import PathDistance, ScanResult, fixed_lost_directions, path_distance, scan
from .structure import ArmStructure, structure

__all__ = [
    "KINDS", "DEFAULT_RTOL", "DEFAULT_NEAR", "DEFAULT_FACTOR_TOL",
    "singular_values", "manipulability", "condition_number", "rank", "analyze", "classify",
    "SingularityReport", "scan", "ScanResult", "manipulability_gradient", "path_distance",
    "PathDistance", "fixed_lost_directions", "structure", "ArmStructure", "workspace_map",
    "WorkspaceMap", "plot_workspace_map",
]
