"""Read a serial arm from a URDF description (`parse_urdf`).

URDF is parsed with `xml.etree.ElementTree` behind `parse_xml_safely`
(no document type or entity declarations: nothing expands, no external reference is
followed). The ``<mujoco>`` extension element is ignored. The links' ``<visual>`` and
``<collision>`` geometry is kept (`VisualDescription`, for drawing the arm): mesh
file names (``package://``, ``file://``, relative or absolute) are looked up on disk
(`find_mesh`) but never opened by the reader. Fixed joints are folded into the next moving joint's ``pre``
or, after the last one, into the tool transform; the base is the base link.

Everything that cannot become a serial chain raises
`ImportModelError` whose message and ``element`` attribute
name the element at fault (for example ``"joint 'finger_2'"``).
"""

from __future__ import annotations

import os
import pathlib
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ImportModelError
from ..spatial import rotation_from_rpy, transform
from .description import (
    MAX_LENGTH,
    SHAPES,
    JointDescription,
    ModelDescription,
    VisualDescription,
    movable_joint,
    unit_axis,
)
from .xml import float_attr, floats, parse_xml_safely, read_source

if TYPE_CHECKING:
    from ..paths.base import Path

__all__ = ["parse_urdf", "find_mesh", "mesh_candidates", "GEOMETRY_SHAPES"]

_URDF_MOVABLE = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_URDF_UNSUPPORTED = {"floating": "a floating joint has 6 degrees of freedom",
                     "planar": "a planar joint has 3 degrees of freedom"}


def parse_urdf(path: Path, *, tip: str | None = None, base_link: str | None = None,
                    name: str | None = None) -> ModelDescription:
    """Chain of the joints between ``base_link`` and ``tip`` of a URDF robot.

    Args:
        path: path to a ``.urdf`` file (or the XML text itself).
        tip: name of the link that becomes the tool frame. Optional when the tree
            below ``base_link`` has a single leaf; required when it branches
            (e.g. a gripper with two fingers).
        base_link: name of the link that becomes the world/base frame; default the
            root link of the tree.
        name: chain name; default the ``<robot name>``.

    Returns:
        A `ModelDescription` of a chain whose fk(q) is
        ``T_base_link_tip`` and whose
        joints carry the URDF names and limits: ``<limit lower upper>`` [rad or m] for
        revolute/prismatic joints (continuous joints are unlimited) and
        ``<limit velocity>`` [rad/s or m/s] as ``vmax`` (absent or 0 → unlimited).

    Raises:
        ImportModelError: malformed XML, DTD/entity declarations, missing links,
            several parents, cycles, a branch without a chosen tip, floating or
            planar joints, mimic joints on the chain, unknown joint types, bad
            numbers; the ``element`` attribute names the element at fault.
    """
    data, label, directory = read_source(path, "URDF")
    root = parse_xml_safely(data, label=label)
    if root.tag != "robot":
        raise ImportModelError(f"{label}: the root element must be <robot>, got <{root.tag}>",
                               element=f"<{root.tag}>")
    tree = _read_tree(root, label)
    base_link = _choose_base(tree, base_link, label)
    auto_tip = tip is None
    tip = _choose_tip(tree, base_link, tip, label)
    path_joints = _path(tree, base_link, tip, label)
    if auto_tip:
        _refuse_end_effector_joint(label, path_joints, tree.joints, tip)
    chain_joints, A, links = _describe_joints(tree, path_joints, label, base_link)
    if not chain_joints:
        raise ImportModelError(f"{label}: no revolute, continuous or prismatic joint between "
                               f"{base_link!r} and {tip!r}", element=f"link {tip!r}")
    rname = name if name is not None else (root.get("name") or "urdf")
    visuals = _link_geometry(root, tree, base_link, path_joints, directory)
    return ModelDescription(joints=tuple(chain_joints), tool=A, name=rname, label=label,
                            links=tuple(links), visuals=visuals)


@dataclass
class _Tree:
    """The kinematic tree of a URDF: link names, joint elements by name, and the links' relations."""

    links: set[str] = field(default_factory=set)
    joints: dict[str, ET.Element] = field(default_factory=dict)
    parent_joint: dict[str, str] = field(default_factory=dict)  # child link -> joint name
    children: dict[str, list[str]] = field(default_factory=dict)  # parent link -> child links

    def parent_of(self, link: str) -> str | None:
        j = self.parent_joint.get(link)
        if j is None:
            return None
        parent_el = self.joints[j].find("parent")
        return None if parent_el is None else parent_el.get("link")


def _read_tree(root: ET.Element, label: str) -> _Tree:
    """Links and joints of ``<robot>``, checked to form a tree with defined links."""
    tree = _Tree()
    links = tree.links
    for el in root.findall("link"):
        lname = el.get("name")
        if not lname:
            raise ImportModelError(f"{label}: a <link> has no name attribute", element="link")
        if lname in links:
            raise ImportModelError(f"{label}: link {lname!r} is defined twice", element=f"link {lname!r}")
        links.add(lname)
    for el in root.findall("joint"):
        jname = el.get("name")
        if not jname:
            raise ImportModelError(f"{label}: a <joint> has no name attribute", element="joint")
        what = f"joint {jname!r}"
        if jname in tree.joints:
            raise ImportModelError(f"{label}: {what} is defined twice", element=what)
        p_el, c_el = el.find("parent"), el.find("child")
        if p_el is None or c_el is None or not p_el.get("link") or not c_el.get("link"):
            raise ImportModelError(f"{label}: {what} needs <parent link=...> and <child link=...>",
                                   element=what)
        parent, child = str(p_el.get("link")), str(c_el.get("link"))  # both checked non-empty above
        for role, lk in (("parent", parent), ("child", child)):
            if lk not in links:
                raise ImportModelError(f"{label}: {what} refers to {role} link {lk!r}, which is "
                                       "not defined by any <link>", element=what)
        if child in tree.parent_joint:
            raise ImportModelError(
                f"{label}: link {child!r} is the child of two joints ({tree.parent_joint[child]!r} and "
                f"{jname!r}); a URDF must be a tree", element=what)
        tree.joints[jname] = el
        tree.parent_joint[child] = jname
        tree.children.setdefault(parent, []).append(child)
    if not links:
        raise ImportModelError(f"{label}: the robot has no <link> elements; a URDF chain needs links "
                               "connected by joints", element="robot")
    return tree


def _choose_base(tree: _Tree, base_link: str | None, label: str) -> str:
    roots = sorted(lk for lk in tree.links if lk not in tree.parent_joint)
    if base_link is None:
        if len(roots) != 1:
            raise ImportModelError(
                f"{label}: the links do not form a single tree: roots {roots}; pass base_link= "
                "one of them" if roots else f"{label}: every link has a parent joint (a cycle)",
                element=f"link {roots[0]!r}" if roots else "joint")
        return roots[0]
    if base_link not in tree.links:
        raise ImportModelError(f"{label}: base_link {base_link!r} is not a link of this robot; links: "
                               f"{sorted(tree.links)}", element=f"link {base_link!r}")
    return base_link


def _choose_tip(tree: _Tree, base_link: str, tip: str | None, label: str) -> str:
    if tip is not None:
        if tip not in tree.links:
            raise ImportModelError(f"{label}: tip {tip!r} is not a link of this robot; links: "
                                   f"{sorted(tree.links)}", element=f"link {tip!r}")
        return tip
    tip = base_link
    while True:
        kids = tree.children.get(tip, [])
        if not kids:
            return tip
        if len(kids) > 1:
            leaves = _leaves(tip, tree.children)
            raise ImportModelError(
                f"{label}: the chain branches at link {tip!r} into {sorted(kids)}; pass tip= one "
                f"of the leaf links {leaves} to choose the serial chain", element=f"link {tip!r}")
        tip = kids[0]


def _path(tree: _Tree, base_link: str, tip: str, label: str) -> list[str]:
    """Joint names on the path base_link → tip, in that order."""
    path_joints: list[str] = []
    link = tip
    seen = set()
    while link != base_link:
        if link in seen:
            raise ImportModelError(f"{label}: the joints form a cycle through link {link!r}",
                                   element=f"link {link!r}")
        seen.add(link)
        j = tree.parent_joint.get(link)
        if j is None:
            raise ImportModelError(f"{label}: tip {tip!r} is not below base_link {base_link!r}",
                                   element=f"link {tip!r}")
        path_joints.append(j)
        up = tree.parent_of(link)
        if up is None:  # pragma: no cover - every joint on the path was checked to have a parent
            break
        link = up
    path_joints.reverse()
    return path_joints


def _describe_joints(tree: _Tree, path_joints: list[str], label: str, base_link: str,
                     ) -> tuple[list[JointDescription], np.ndarray, list[tuple[str, int, np.ndarray]]]:
    """The moving joints of the path in general form, the constant transform after the last,
    and the links rigidly attached to the chain (``(name, k, T)``: ``T`` after the frame of
    moving joint k; the path's links, and links hanging from them by fixed joints only)."""
    chain_joints: list[JointDescription] = []
    links: list[tuple[str, int, np.ndarray]] = [(base_link, 0, np.eye(4))]
    on_path = {base_link}
    A = np.eye(4)
    for jname in path_joints:
        el = tree.joints[jname]
        what = f"joint {jname!r}"
        jtype = el.get("type")
        if jtype in _URDF_UNSUPPORTED:
            raise ImportModelError(
                f"{label}: {what} is of type {jtype!r}: {_URDF_UNSUPPORTED[jtype]}; ratectl chains "
                "support revolute, continuous, prismatic and fixed joints", element=what)
        if jtype not in _URDF_MOVABLE and jtype != "fixed":
            raise ImportModelError(
                f"{label}: {what} has unknown type {jtype!r}; allowed: revolute, continuous, "
                "prismatic, fixed", element=what)
        O = _urdf_origin(el.find("origin"), what)
        child = str(el.find("child").get("link"))  # type: ignore[union-attr]  # checked by _read_tree
        on_path.add(child)
        if jtype == "fixed":
            A = A @ O
            links.append((child, len(chain_joints), A))
            continue
        if (mimic := el.find("mimic")) is not None:
            raise ImportModelError(
                f"{label}: {what} mimics joint {mimic.get('joint')!r}: coupled (mimic) "
                "joints are not supported on the chain; choose a tip that excludes it", element=what)
        ax_el = el.find("axis")
        axis = floats(None if ax_el is None else ax_el.get("xyz"), 3, default=[1.0, 0.0, 0.0],
                      what=f"{what} <axis xyz>")
        axis = unit_axis(axis, what, label=label)
        qlim, vmax = _urdf_limits(el, jtype, what, label)
        chain_joints.append(movable_joint(_URDF_MOVABLE[str(jtype)], A @ O, axis, name=jname,
                                          qlim=qlim, vmax=vmax, what=what))
        A = np.eye(4)
        links.append((child, len(chain_joints), A))
    # links hanging from the path by fixed joints only (a hand's frames, sensors)
    stack = list(links)
    while stack:
        lname, k, T = stack.pop()
        for child in tree.children.get(lname, []):
            el = tree.joints[tree.parent_joint[child]]
            if child in on_path or el.get("type") != "fixed":
                continue
            on_path.add(child)
            item = (child, k, T @ _urdf_origin(el.find("origin"), f"joint {el.get('name')!r}"))
            links.append(item)
            stack.append(item)
    return chain_joints, A, links


_END_EFFECTOR_WORDS = re.compile(r"finger|gripper|jaw|knuckle|claw|grasp|suction", re.IGNORECASE)


def _refuse_end_effector_joint(label, path_joints, joints, tip) -> None:
    """With no ``tip`` given, the single leaf may hang below a gripper joint (a jaw or
    finger slide): that joint is not part of the arm. Ask for ``tip`` instead of silently
    adding it as one more arm joint."""
    movable = [j for j in path_joints if joints[j].get("type") in _URDF_MOVABLE]
    if not movable:
        return
    last = joints[movable[-1]]
    child = last.find("child").get("link") if last.find("child") is not None else ""
    parent = last.find("parent").get("link") if last.find("parent") is not None else ""
    revolute_before = sum(joints[j].get("type") in ("revolute", "continuous") for j in movable[:-1])
    gripper_like = bool(_END_EFFECTOR_WORDS.search(f"{movable[-1]} {child}")) or (
        last.get("type") == "prismatic" and revolute_before >= 6)
    if gripper_like:
        raise ImportModelError(
            f"{label}: no tip given, and the only leaf link {tip!r} is reached through joint "
            f"{movable[-1]!r} ({last.get('type')}), which looks like a gripper joint, not part of the "
            f"arm; pass tip={parent!r} to end the arm before it (or tip={tip!r} to include it as "
            f"joint {len(movable)})", element=f"joint {movable[-1]!r}")


def _leaves(link: str, children: dict[str, list[str]]) -> list[str]:
    out, stack = [], [link]
    while stack:
        lk = stack.pop()
        kids = children.get(lk, [])
        if kids:
            stack.extend(kids)
        else:
            out.append(lk)
    return sorted(out)


def _urdf_origin(el: ET.Element | None, what: str) -> np.ndarray:
    if el is None:
        return np.eye(4)
    xyz = floats(el.get("xyz"), 3, default=[0.0, 0.0, 0.0], what=f"{what} <origin xyz>")
    if not float(np.max(np.abs(xyz))) <= MAX_LENGTH:
        raise ImportModelError(f"{what} <origin xyz={el.get('xyz')!r}>: offsets beyond "
                               f"{MAX_LENGTH:.0e} m are refused (lengths are in metres)",
                               element=what)
    rpy = floats(el.get("rpy"), 3, default=[0.0, 0.0, 0.0], what=f"{what} <origin rpy>")
    return transform(rotation_from_rpy(rpy), xyz)


def _urdf_limits(el: ET.Element, jtype: str, what: str, label: str):
    lim = el.find("limit")
    vmax = None
    lo = hi = None
    if lim is not None:
        v = float_attr(lim, "velocity", what=f"{what} <limit>")
        if v is not None:
            if v < 0:
                raise ImportModelError(f"{label}: {what} <limit velocity={v}> must be >= 0 [rad/s or m/s]",
                                       element=what)
            vmax = v if v > 0 else None
        lo = float_attr(lim, "lower", what=f"{what} <limit>")
        hi = float_attr(lim, "upper", what=f"{what} <limit>")
    if jtype == "continuous":
        return None, vmax
    if lim is None:
        raise ImportModelError(f"{label}: {what} ({jtype}) has no <limit> element; URDF requires "
                               "<limit lower upper velocity effort> (use type 'continuous' for an "
                               "unlimited revolute joint)", element=what)
    if lo is None and hi is None:
        raise ImportModelError(f"{label}: {what} ({jtype}) <limit> has neither lower nor upper: URDF "
                               "reads both as 0, which leaves the joint no motion; give its range "
                               "(or use type 'continuous' for an unlimited revolute joint, 'fixed' "
                               "for none)", element=what)
    lo = 0.0 if lo is None else lo
    hi = 0.0 if hi is None else hi
    if not lo < hi:
        raise ImportModelError(f"{label}: {what} <limit lower={lo} upper={hi}>: lower must be below "
                               "upper", element=what)
    return (lo, hi), vmax


# --------------------------------------------------------------------------- link geometry
def _link_geometry(root: ET.Element, tree: _Tree, base_link: str, path_joints: list[str],
                   directory: pathlib.Path | None) -> tuple[VisualDescription, ...]:
    """The ``<visual>`` and ``<collision>`` geometry of every link below ``base_link``, placed
    on the chain frame it moves with. Joints off the chain (a gripper's fingers) are drawn
    at zero; geometry that cannot be read (a bad number, an unknown shape) is left out —
    drawing is never a reason to refuse a model."""
    frame_of_joint = {}
    k = 0
    for jname in path_joints:
        if tree.joints[jname].get("type") in _URDF_MOVABLE:
            k += 1
            frame_of_joint[jname] = k
    place: dict[str, tuple[int, np.ndarray]] = {base_link: (0, np.eye(4))}
    stack = [base_link]
    while stack:
        link = stack.pop()
        frame, T = place[link]
        for child in tree.children.get(link, []):
            if child in place:  # pragma: no cover - a tree has no second path
                continue
            jname = tree.parent_joint[child]
            if jname in frame_of_joint:
                place[child] = (frame_of_joint[jname], np.eye(4))
            else:
                try:
                    O = _urdf_origin(tree.joints[jname].find("origin"), f"joint {jname!r}")
                except ImportModelError:
                    continue
                place[child] = (frame, T @ O)
            stack.append(child)
    colours = _materials(root)
    out: list[VisualDescription] = []
    for el in root.findall("link"):
        lname = el.get("name")
        if lname not in place:
            continue
        frame, T = place[lname]
        for role in ("visual", "collision"):
            for g in el.findall(role):
                v = _geometry(g, lname, role, frame, T, colours, directory)
                if v is not None:
                    out.append(v)
    return tuple(out)


def _materials(root: ET.Element) -> dict[str, tuple[float, float, float, float]]:
    """Named ``<material><color rgba>`` entries of the robot (URDF lets links refer to them)."""
    out = {}
    for m in root.findall("material"):
        c = _rgba(m)
        if m.get("name") and c is not None:
            out[str(m.get("name"))] = c
    return out


def _rgba(material: ET.Element | None) -> tuple[float, float, float, float] | None:
    if material is None or (c := material.find("color")) is None:
        return None
    try:
        v = floats(c.get("rgba"), 4, default=[0.0, 0.0, 0.0, -1.0], what="<color rgba>")
    except ImportModelError:
        return None
    if v[3] < 0.0:
        return None
    r, g, b, a = (float(x) for x in np.clip(v, 0.0, 1.0))
    return (r, g, b, a)


#: Shapes a URDF ``<geometry>`` may hold (``capsule`` is a common extension).
GEOMETRY_SHAPES = ("mesh", "box", "cylinder", "sphere", "capsule")


@dataclass(frozen=True)
class _Geometry:
    """One ``<visual>``/``<collision>`` element as the file gives it: ``origin`` (4×4, in
    the link frame), ``shape`` (one of `GEOMETRY_SHAPES`), ``size`` (box sides; (radius,);
    (radius, length); () for a mesh), and for a mesh its ``filename`` (as written, possibly
    empty) and ``scale`` (3,)."""

    origin: np.ndarray
    shape: str
    size: tuple[float, ...] = ()
    filename: str | None = None
    scale: np.ndarray | None = None


def _read_geometry(el: ET.Element, what: str, label: str) -> _Geometry:
    """The one reader of a link's ``<visual>`` or ``<collision>`` element (the viewer's
    `VisualDescription` and the collision model's `CollisionElement` are built from it).

    Raises:
        ImportModelError: no ``<geometry>``, an unknown shape, a missing or bad number.
    """
    origin = _urdf_origin(el.find("origin"), what)
    geo = el.find("geometry")
    shape = None if geo is None else next(iter(geo), None)
    if shape is None:
        raise ImportModelError(f"{label}: {what} has no <geometry>", element=what)
    tag = shape.tag
    if tag == "mesh":
        scale = floats(shape.get("scale"), 3, default=[1.0, 1.0, 1.0], what=f"{what} <mesh scale>")
        return _Geometry(origin=origin, shape=tag, filename=shape.get("filename") or "", scale=scale)
    if tag not in GEOMETRY_SHAPES:
        raise ImportModelError(f"{label}: {what} has geometry <{tag}>; allowed: "
                               f"{', '.join(GEOMETRY_SHAPES)}", element=what)
    attrs = {"box": ("size",), "sphere": ("radius",)}.get(tag, ("radius", "length"))
    size: list[float] = []
    for attr in attrs:
        text = shape.get(attr)
        if text is None:
            raise ImportModelError(f"{label}: {what} <{tag}> has no {attr}", element=what)
        size.extend(float(x) for x in floats(text, 3 if attr == "size" else 1, default=None,
                                             what=f"{what} <{tag} {attr}>"))
    return _Geometry(origin=origin, shape=tag, size=tuple(size))


def _geometry(el: ET.Element, link: str, role: str, frame: int, T: np.ndarray, colours: dict,
              directory: pathlib.Path | None) -> VisualDescription | None:
    """One ``<visual>``/``<collision>`` element placed on the chain, or None when it cannot
    be drawn (`_read_geometry` refuses it, or its shape is not one of `SHAPES`)."""
    try:
        g = _read_geometry(el, f"link {link!r} <{role}>", "<URDF>")
    except ImportModelError:
        return None
    if g.shape not in SHAPES:
        return None
    path = None
    size = g.size
    if g.shape == "mesh":
        assert g.filename is not None and g.scale is not None  # a mesh has both
        found = find_mesh(g.filename, directory)
        path = None if found is None else str(found)
        size = tuple(float(x) for x in g.scale)
    material = el.find("material")
    rgba = _rgba(material)
    if rgba is None and material is not None:
        rgba = colours.get(material.get("name") or "")
    return VisualDescription(link=link, role=role, frame=frame, origin=T @ g.origin, shape=g.shape,
                             size=size, filename=g.filename, path=path, rgba=rgba)


def find_mesh(filename: str, directory: pathlib.Path | str | None = None, *,
              package_dirs: Any = ()) -> pathlib.Path | None:
    """The file a URDF mesh name refers to, or None when it is not found.

    The places looked at, in order (`mesh_candidates`):

    * ``package://PKG/REST``: ``PKG/REST`` and ``REST`` inside each of ``package_dirs``;
      then ``REST`` inside the package directory ``PKG``, looked for among ``directory``
      and its parents (a parent named ``PKG``, or a ``PKG`` folder inside one); then in
      the directories of ``ROS_PACKAGE_PATH``;
    * ``file:///abs/path`` and absolute paths: as given (``file://rel`` relative to
      ``directory``);
    * relative names: relative to ``directory`` (the URDF's; None for a URDF given as text).

    The file is looked up (``is_file``), never opened.
    """
    for c in mesh_candidates(filename, directory, package_dirs=package_dirs):
        try:
            if c.is_file():
                return c
        except (OSError, ValueError):
            continue
    return None


def mesh_candidates(filename: str, directory: pathlib.Path | str | None = None, *,
                    package_dirs: Any = ()) -> list[pathlib.Path]:
    """The paths `find_mesh` tries for ``filename``, in order (for messages that say where
    a mesh was looked for)."""
    if not filename:
        return []
    candidates: list[pathlib.Path] = []
    if filename.startswith("package://"):
        pkg, _, rest = filename[len("package://"):].partition("/")
        if not pkg or not rest:
            return []
        for d in package_dirs or ():
            candidates += [pathlib.Path(d) / pkg / rest, pathlib.Path(d) / rest]
        roots: list[pathlib.Path] = []
        if directory is not None:
            d = pathlib.Path(directory).resolve()
            roots.extend([d, *d.parents])
        roots.extend(pathlib.Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p)
        for r in roots:
            if r.name == pkg:
                candidates.append(r / rest)
            candidates.append(r / pkg / rest)
        return candidates
    p = pathlib.Path(filename[len("file://"):] if filename.startswith("file://") else filename)
    if p.is_absolute():
        candidates.append(p)
    elif directory is not None:
        candidates.append(pathlib.Path(directory) / p)
    return candidates
