"""ratectl — resolved-rate motion control for serial robot arms.

Jacobian core → singularity analysis → inverse velocity (exact, damped, QP) →
resolved-rate controller and path following → Ruckig smoothing.
"""

from . import errors, robots, spatial
from .chain import DH, MDH, Chain, Joint
from .errors import (
    ImportModelError,
    InputError,
    ModelError,
    RatectlError,
    SingularityError,
    SolverError,
)

__version__ = "0.1.0"

__all__ = [
    "DH",
    "MDH",
    "Chain",
    "Joint",
    "errors",
    "robots",
    "spatial",
    "RatectlError",
    "ModelError",
    "InputError",
    "SingularityError",
    "SolverError",
    "ImportModelError",
]
