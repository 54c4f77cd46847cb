"""ratectl — resolved-rate motion control for serial robot arms.

Jacobian core → singularity analysis → inverse velocity (exact, damped, QP) →
resolved-rate controller and path following → Ruckig smoothing.

The core (``DH``, ``MDH``, ``Chain``, ``robots``, ``spatial``) is imported eagerly;
the rest is imported on first use, so ``import ratectl`` stays cheap and optional
extras (matplotlib, mujoco) are only needed by the functions that use them.
"""

from __future__ import annotations

import importlib

from . import errors, kinematics, robots, spatial
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

# public name -> module that defines it (imported lazily)
_LAZY_ATTRS = {
    "singular_values": "singularity",
    "manipulability": "singularity",
    "condition_number": "singularity",
    "analyze": "singularity",
    "scan": "singularity",
    "SingularityReport": "singularity",
    "manipulability_gradient": "singularity",
    "workspace_map": "singularity",
    "ResolvedRateController": "controller",
    "Command": "controller",
    "follow": "follow",
    "Execution": "execution",
}
_LAZY_MODULES = ("solvers", "qp", "singularity", "controller", "paths", "smoothing", "governor",
                 "follow", "execution", "importers", "mujoco", "cli", "hessian", "demo", "offscreen_gl")

__all__ = [
    "DH", "MDH", "Chain", "Joint", "errors", "kinematics", "robots", "spatial",
    "RatectlError", "ModelError", "InputError", "SingularityError", "SolverError",
    "ImportModelError", *_LAZY_ATTRS, *_LAZY_MODULES,
]


def __getattr__(name: str):
    # attributes first: ``follow`` is both a module and the function users call
    if name in _LAZY_ATTRS:
        module = importlib.import_module(f".{_LAZY_ATTRS[name]}", __name__)
        value = getattr(module, name)
        globals()[name] = value
        return value
    if name in _LAZY_MODULES:
        module = importlib.import_module(f".{name}", __name__)
        globals()[name] = module
        return module
    raise AttributeError(f"module 'ratectl' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
