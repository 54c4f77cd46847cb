"""A live 3-D view of an arm in the browser, served by `viser <https://viser.studio>`_.

``Viewer(chain, q)`` serves a scene on loopback from a background thread and gives its
``url``: the arm (the URDF's meshes where they can be read, capsules along the links
otherwise), the tool frame, a draggable target, σ_min and the singularity kind with
arrows along the directions being lost, and the path when there is one. ``update(q)``
redraws from a control loop at any rate without slowing it (the viewer draws at most
``rate_hz`` times a second, the latest state, on its own thread); ``replay(run)`` plays an
`ratectl.Execution` with a time slider.

viser (the ``view`` extra: ``pip install -e ".[view]"``) is imported here only; ``import
ratectl`` never loads it.
"""


from .. import errors as _errors

try:
    import viser as _viser  # noqa: F401  (the check that the extra is installed)
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise _errors.RatectlError(
        "ratectl.viewer needs viser (and trimesh, which comes with it): pip install -e \".[view]\" in "
        f"ratectl's source tree, or pip install 'viser>=1.0' (import failed: {exc})") from exc

from .geometry import body_polylines, lost_directions, path_points
from .viewer import Viewer

__all__ = ["Viewer", "body_polylines", "lost_directions", "path_points"]
