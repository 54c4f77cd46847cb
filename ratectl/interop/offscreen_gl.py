"""Pick an offscreen OpenGL backend for MuJoCo rendering, before mujoco is imported.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, and a headless machine
needs ``egl`` (GPU or Mesa's EGL) or ``osmesa`` (software). Which one works is found by
rendering an 8×8 image in a child process for each candidate, so a failing backend
cannot take the caller's process down. This module imports nothing of mujoco itself.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence

__all__ = ["pick_gl_backend"]

_PROBE = ("import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco/>'); "
          "r = mujoco.Renderer(m, 8, 8); r.render()")


def pick_gl_backend(candidates: Sequence[str] = ("egl", "osmesa"), *, timeout: float = 60.0) -> str | None:
    """Set ``MUJOCO_GL`` to the first backend that renders and return its name, or None
    when none does (then render nothing and plot instead).

    A ``MUJOCO_GL`` already set by the user is the only candidate tried. Call this before
    the first ``import mujoco`` of the process (``import ratectl`` does not import it).

    Args:
        candidates: backend names to try in order.
        timeout: seconds allowed for each probe.
    """
    if "mujoco" in sys.modules:
        return os.environ.get("MUJOCO_GL")  # too late to choose: report what is in force
    user = os.environ.get("MUJOCO_GL")
    for backend in [user] if user else list(candidates):
        try:
            ok = subprocess.run([sys.executable, "-c", _PROBE],
                                env={**os.environ, "MUJOCO_GL": backend},
                                capture_output=True, timeout=timeout).returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            ok = False
        if ok:
            os.environ["MUJOCO_GL"] = backend
            return backend
    return None
