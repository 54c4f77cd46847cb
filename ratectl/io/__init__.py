"""Model files in: URDF and MJCF readers behind a safe XML parser.

* :mod:`~ratectl.io.xml` — sources (path, text, bytes), size caps, XML without entities;
* :mod:`~ratectl.io.description` — :class:`ModelDescription`, what a file says about a chain;
* :mod:`~ratectl.io.urdf` — :func:`parse_urdf`;
* :mod:`~ratectl.io.mjcf` — :func:`parse_mjcf` (compiled by MuJoCo), joint addresses.

Build chains with :meth:`ratectl.Chain.from_urdf` / :meth:`ratectl.Chain.from_mjcf`.
Export to MJCF is :func:`ratectl.interop.mujoco.to_mjcf`.
"""

from __future__ import annotations

from .description import JointDescription, ModelDescription, axis_rotation
from .mjcf import compile_mjcf, mjcf_joint_addresses, parse_mjcf
from .urdf import parse_urdf
from .xml import parse_xml_safely, read_source

__all__ = ["JointDescription", "ModelDescription", "axis_rotation", "parse_urdf", "parse_xml_safely",
           "read_source", "parse_mjcf", "compile_mjcf", "mjcf_joint_addresses"]
