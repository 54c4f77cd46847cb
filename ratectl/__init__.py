"""ratectl — resolved-rate motion control for serial robot arms.

The package follows the data flow of a control cycle, one subpackage per stage:

    model ─► kinematics ─► singularity ─► solvers ─► control ─► paths/planning ─► execution

* `ratectl.model` — joints (DH, MDH), the `Chain`, built-in robots, limits;
* `ratectl.io` — URDF and MJCF readers behind a safe XML parser;
* `ratectl.kinematics` — generated fk/Jacobian kernels, J̇, the Hessian;
* `ratectl.singularity` — measures, classification, reports, scans, maps;
* `ratectl.solvers` — exact, pseudo-inverse, damped, null-space and QP inverse velocity;
* `ratectl.tasks` — tasks on links and joints with strict priorities;
* `ratectl.collision` — self-collision and obstacles as velocity-damper rows (coal);
* `ratectl.control` — the resolved-rate controller, its command, Ruckig smoothing;
* `ratectl.paths` — lines, arcs, blended waypoints and their time laws;
* `ratectl.planning` — inverse kinematics, joint paths, the path-speed governor;
* `ratectl.drivers` — the robot interface: the driver protocol, franky, a scripted arm;
* `ratectl.execution` — `follow`, `run` (real time, on a driver) and the
  `Execution` record;
* `ratectl.interop` — MuJoCo and mink;
* `ratectl.viewer` — a live 3-D view in the browser (viser, the ``view`` extra);
* `ratectl.cli` — the ``ratectl`` command and its demo.

The core (model, kinematics, spatial, errors) is imported eagerly; the rest on first
use, so ``import ratectl`` stays cheap and optional extras (matplotlib, mujoco, viser) are
only needed by the functions that use them.
"""

import importlib as _importlib
import warnings as _warnings

from . import compiled as _compiled
from . import errors, kinematics, spatial
from .errors import (
    DriverError,
    ImportModelError,
    InputError,
    ModelError,
    RatectlError,
    SingularityError,
    SolverError,
)
from .model import DH, MDH, Chain, Joint, robots
from .model.limits import Limits

__version__ = "0.1.0"

if _stale := _compiled.stale():  # a source checkout whose compiled modules lag their sources
    _warnings.warn(
        f"ratectl: the compiled {', '.join(_stale)} "
        + ("was built from an older source and runs" if len(_stale) == 1 else
           "were built from older sources and run")
        + " the old code: rebuild with `pip install -e .`, or delete the compiled files "
        "(`find ratectl -name '*.so' -delete`) to run the sources as plain Python",
        RuntimeWarning, stacklevel=2)

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
    "ResolvedRateController": "control",
    "Command": "control",
    "ik": "planning",
    "IKResult": "planning",
    "Governor": "planning",
    "follow": "execution",
    "run": "execution",
    "Execution": "execution",
}
_LAZY_MODULES = ("io", "singularity", "solvers", "tasks", "collision", "control", "paths", "planning",
                 "drivers", "execution", "interop", "viewer", "cli", "compiled")

__all__ = [
    "DH", "MDH", "Chain", "Joint", "Limits", "errors", "kinematics", "robots", "spatial",
    "RatectlError", "ModelError", "InputError", "SingularityError", "SolverError",
    "ImportModelError", "DriverError", *_LAZY_ATTRS, *_LAZY_MODULES,
]


def __getattr__(name: str):
    if name in _LAZY_ATTRS:
        module = _importlib.import_module(f".{_LAZY_ATTRS[name]}", __name__)
        value = getattr(module, name)
        globals()[name] = value
        return value
    if name in _LAZY_MODULES:
        module = _importlib.import_module(f".{name}", __name__)
        globals()[name] = module
        return module
    raise AttributeError(f"module 'ratectl' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
