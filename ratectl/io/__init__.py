"""Model files in: URDF and MJCF readers behind a safe XML parser.

* `xml` — sources (path, text, bytes), size caps, XML without entities;
* `description` — `ModelDescription`, what a file says about a chain;
* `urdf` — `parse_urdf`;
* `mjcf` — `parse_mjcf` (compiled by MuJoCo), joint addresses.

Build chains with `ratectl.Chain.from_urdf` / `ratectl.Chain.from_mjcf`.
Export to MJCF is `ratectl.interop.mujoco.to_mjcf`.
"""

from .description import JointDescription, ModelDescription, axis_rotation
from .mjcf import compile_mjcf, mjcf_joint_addresses, parse_mjcf
from .urdf import parse_urdf
from .xml import parse_xml_safely, read_source

__all__ = ["JointDescription", "ModelDescription", "axis_rotation", "parse_urdf", "parse_xml_safely",
           "read_source", "parse_mjcf", "compile_mjcf", "mjcf_joint_addresses"]
