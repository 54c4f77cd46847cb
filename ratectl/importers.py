"""Import serial arms from URDF and MJCF descriptions.

Both importers turn a kinematic tree into a :class:`~ratectl.chain.Chain` of the
joints on the path from a base link/body to a chosen tip:

* A joint with origin transform ``O`` (relative to its parent link/body frame) and
  unit axis ``a`` becomes a ratectl :class:`~ratectl.chain.Joint` with
  ``pre = A · O · R_a`` and ``post = R_aᵀ`` (revolute: ``T = … pre · Rz(q) · post``,
  prismatic: ``… pre · Tz(q) · post``), where ``R_a`` is the rotation that takes
  the z axis onto ``a`` and ``A`` collects the constant transforms (fixed joints,
  joint-less bodies) met since the previous moving joint. ``R_a Rz(q) R_aᵀ`` is the
  rotation by q about ``a``, so the chain frame after each joint is exactly the
  child link (URDF) or body (MJCF) frame.
* Fixed joints and bodies without joints are folded into the next joint's ``pre``
  or, after the last moving joint, into the chain's ``tool``. The chain's ``base``
  is the identity: world = the base link (URDF) or MuJoCo's world body (MJCF).

URDF is parsed by this module with :mod:`xml.etree.ElementTree` behind a guard that
refuses any document type declaration or entity (no entity expansion, no external
references); mesh files, ``package://`` URIs and the ``<mujoco>`` extension element
are ignored and never opened. MJCF is checked with the same guard, mesh/heightfield/
texture file references are replaced by placeholders, and the result is compiled
by MuJoCo (the authority on MJCF semantics: defaults, angle units, ``euler``
sequences, ``ref`` positions); the chain is read from the compiled ``MjModel``.

Everything that cannot become a serial chain raises
:class:`~ratectl.errors.ImportModelError` whose message and ``element`` attribute
name the element at fault (for example ``"joint 'finger_2'"``).
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .chain import Chain, Joint
from .errors import ImportModelError, ModelError
from .spatial import rotation_from_quat, rotation_from_rpy

__all__ = ["chain_from_urdf", "chain_from_mjcf", "parse_xml_safely", "axis_rotation",
           "mjcf_joint_addresses"]

_FORBIDDEN = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
_MAX_BYTES = 50_000_000


# ---------------------------------------------------------------------- XML helpers
def _read_source(source, kind: str) -> tuple[bytes, str, Path | None]:
    """(bytes, a label for messages, directory of the file or None) of a path or XML text."""
    if isinstance(source, bytes):
        return source, f"<{kind} bytes>", None
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return source.encode("utf-8"), f"<{kind} string>", None
    if not isinstance(source, str | os.PathLike):
        raise ImportModelError(
            f"expected a path to a {kind} file or its XML text, got {type(source).__name__}",
            element="file")
    path = Path(source)
    if not path.is_file():
        raise ImportModelError(f"{kind} file not found: {str(path)!r}", element=f"file {str(path)!r}")
    size = path.stat().st_size
    if size > _MAX_BYTES:
        raise ImportModelError(f"{kind} file {str(path)!r} is {size} bytes; refusing files over "
                               f"{_MAX_BYTES} bytes", element=f"file {str(path)!r}")
    return path.read_bytes(), str(path), path.parent


def parse_xml_safely(data: bytes, *, label: str = "<xml>") -> ET.Element:
    """Parse XML without entity expansion or external references.

    Any ``<!DOCTYPE`` or ``<!ENTITY`` declaration is refused (that is where entity
    bombs and external entities live); without one, ElementTree only knows the five
    predefined entities and character references, so nothing expands.

    Raises:
        ImportModelError: for a declaration (``element="<!DOCTYPE>"``/``"<!ENTITY>"``) or
            malformed XML (``element`` gives the line and column).
    """
    m = _FORBIDDEN.search(data)
    if m:
        decl = m.group(1).decode().upper()
        line = data.count(b"\n", 0, m.start()) + 1
        raise ImportModelError(
            f"{label}: line {line}: <!{decl}> declarations are not allowed (ratectl does not "
            "expand entities or follow external references); remove the declaration",
            element=f"<!{decl}>")
    parser = ET.XMLParser()
    try:
        parser.feed(data)
        return parser.close()
    except ET.ParseError as exc:
        line, col = exc.position
        raise ImportModelError(f"{label}: malformed XML at line {line}, column {col}: {exc}",
                               element=f"XML line {line} column {col}") from None


def _floats(text: str | None, count: int, *, default, what: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    try:
        vals = np.array([float(p) for p in parts], dtype=float)
    except ValueError:
        raise ImportModelError(f"{what}: expected {count} numbers, got {text!r}", element=what) from None
    if vals.shape != (count,) or not np.all(np.isfinite(vals)):
        raise ImportModelError(f"{what}: expected {count} finite numbers, got {text!r}", element=what)
    return vals


def _float_attr(el: ET.Element, name: str, *, what: str) -> float | None:
    text = el.get(name)
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        raise ImportModelError(f"{what}: attribute {name}={text!r} is not a number",
                               element=what) from None
    if math.isnan(v):
        raise ImportModelError(f"{what}: attribute {name} is NaN", element=what)
    return v


def axis_rotation(axis) -> np.ndarray:
    """A rotation ``R_a`` (3×3) with ``R_a · ẑ = a`` for a unit vector ``a``.

    Exact for ±z (identity, Rx(π)); otherwise the rotation about ``ẑ × a`` by the
    angle between them (Rodrigues' formula, written without trigonometric calls:
    ``R = c I + [k]× + (1 − c)/s² k kᵀ`` with ``k = ẑ × a``, ``c = a_z``, ``s = ‖k‖``).
    """
    a = np.asarray(axis, dtype=float)
    c = float(a[2])
    k = np.array([-a[1], a[0], 0.0])
    s2 = float(k @ k)
    if s2 < 1e-30:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return c * np.eye(3) + K + ((1.0 - c) / s2) * np.outer(k, k)


def _transform(R=None, p=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def _unit_axis(v, what: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not n > 1e-12:
        raise ImportModelError(f"{what}: the joint axis {v.tolist()} has zero length", element=what)
    return v / n


def _movable_joint(kind: str, O: np.ndarray, axis: np.ndarray, *, name: str, qlim, vmax,
                   what: str, post_extra: np.ndarray | None = None,
                   offset: float = 0.0) -> Joint:
    """Joint with ``pre = O · R_a · M(−offset)``, ``post = R_aᵀ · post_extra``."""
    Ra = _transform(axis_rotation(axis))
    pre = O @ Ra
    if offset:
        M = np.eye(4)
        if kind == "revolute":
            c, s = math.cos(-offset), math.sin(-offset)
            M[:2, :2] = [[c, -s], [s, c]]
        else:
            M[2, 3] = -offset
        pre = pre @ M
    post = Ra.T.copy()
    if post_extra is not None:
        post = post @ post_extra
    try:
        return Joint(kind=kind, pre=pre, post=post, name=name, qlim=qlim, vmax=vmax)
    except ModelError as exc:
        raise ImportModelError(f"{what}: {exc}", element=what) from None


# ---------------------------------------------------------------------- URDF
_URDF_MOVABLE = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_URDF_UNSUPPORTED = {"floating": "a floating joint has 6 degrees of freedom",
                     "planar": "a planar joint has 3 degrees of freedom"}


def chain_from_urdf(path, *, tip: str | None = None, base_link: str | None = None,
                    name: str | None = None) -> Chain:
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
        A :class:`~ratectl.chain.Chain` whose fk(q) is ``T_base_link_tip`` and whose
        joints carry the URDF names and limits: ``<limit lower upper>`` [rad or m] for
        revolute/prismatic joints (continuous joints are unlimited) and
        ``<limit velocity>`` [rad/s or m/s] as ``vmax`` (absent or 0 → unlimited).

    Raises:
        ImportModelError: malformed XML, DTD/entity declarations, missing links,
            several parents, cycles, a branch without a chosen tip, floating or
            planar joints, mimic joints on the chain, unknown joint types, bad
            numbers; the ``element`` attribute names the element at fault.
    """
    data, label, _ = _read_source(path, "URDF")
    root = parse_xml_safely(data, label=label)
    if root.tag != "robot":
        raise ImportModelError(f"{label}: the root element must be <robot>, got <{root.tag}>",
                               element=f"<{root.tag}>")
    links: set[str] = set()
    for el in root.findall("link"):
        lname = el.get("name")
        if not lname:
            raise ImportModelError(f"{label}: a <link> has no name attribute", element="link")
        if lname in links:
            raise ImportModelError(f"{label}: link {lname!r} is defined twice", element=f"link {lname!r}")
        links.add(lname)
    joints: dict[str, ET.Element] = {}
    parent_joint: dict[str, str] = {}      # child link -> joint name
    children: dict[str, list[str]] = {}     # parent link -> child links
    for el in root.findall("joint"):
        jname = el.get("name")
        if not jname:
            raise ImportModelError(f"{label}: a <joint> has no name attribute", element="joint")
        what = f"joint {jname!r}"
        if jname in joints:
            raise ImportModelError(f"{label}: {what} is defined twice", element=what)
        p_el, c_el = el.find("parent"), el.find("child")
        if p_el is None or c_el is None or not p_el.get("link") or not c_el.get("link"):
            raise ImportModelError(f"{label}: {what} needs <parent link=...> and <child link=...>",
                                   element=what)
        parent, child = p_el.get("link"), c_el.get("link")
        for role, lk in (("parent", parent), ("child", child)):
            if lk not in links:
                raise ImportModelError(f"{label}: {what} refers to {role} link {lk!r}, which is "
                                       "not defined by any <link>", element=what)
        if child in parent_joint:
            raise ImportModelError(
                f"{label}: link {child!r} is the child of two joints ({parent_joint[child]!r} and "
                f"{jname!r}); a URDF must be a tree", element=what)
        joints[jname] = el
        parent_joint[child] = jname
        children.setdefault(parent, []).append(child)

    def parent_of(link: str) -> str | None:
        j = parent_joint.get(link)
        return None if j is None else joints[j].find("parent").get("link")

    roots = sorted(lk for lk in links if lk not in parent_joint)
    if base_link is None:
        if len(roots) != 1:
            raise ImportModelError(
                f"{label}: the links do not form a single tree: roots {roots}; pass base_link= "
                "one of them" if roots else f"{label}: every link has a parent joint (a cycle)",
                element=f"link {roots[0]!r}" if roots else "joint")
        base_link = roots[0]
    elif base_link not in links:
        raise ImportModelError(f"{label}: base_link {base_link!r} is not a link of this robot; links: "
                               f"{sorted(links)}", element=f"link {base_link!r}")
    if tip is None:
        tip = base_link
        while True:
            kids = children.get(tip, [])
            if not kids:
                break
            if len(kids) > 1:
                leaves = _leaves(tip, children)
                raise ImportModelError(
                    f"{label}: the chain branches at link {tip!r} into {sorted(kids)}; pass tip= one "
                    f"of the leaf links {leaves} to choose the serial chain", element=f"link {tip!r}")
            tip = kids[0]
    elif tip not in links:
        raise ImportModelError(f"{label}: tip {tip!r} is not a link of this robot; links: "
                               f"{sorted(links)}", element=f"link {tip!r}")
    # the path base_link -> tip, from the tip upwards
    path_joints: list[str] = []
    link = tip
    seen = set()
    while link != base_link:
        if link in seen:
            raise ImportModelError(f"{label}: the joints form a cycle through link {link!r}",
                                   element=f"link {link!r}")
        seen.add(link)
        j = parent_joint.get(link)
        if j is None:
            raise ImportModelError(f"{label}: tip {tip!r} is not below base_link {base_link!r}",
                                   element=f"link {tip!r}")
        path_joints.append(j)
        link = parent_of(link)
    path_joints.reverse()

    chain_joints: list[Joint] = []
    A = np.eye(4)
    for jname in path_joints:
        el = joints[jname]
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
        if jtype == "fixed":
            A = A @ O
            continue
        if el.find("mimic") is not None:
            raise ImportModelError(
                f"{label}: {what} mimics joint {el.find('mimic').get('joint')!r}: coupled (mimic) "
                "joints are not supported on the chain; choose a tip that excludes it", element=what)
        ax_el = el.find("axis")
        axis = _floats(None if ax_el is None else ax_el.get("xyz"), 3, default=[1.0, 0.0, 0.0],
                       what=f"{what} <axis xyz>")
        axis = _unit_axis(axis, what)
        qlim, vmax = _urdf_limits(el, jtype, what, label)
        chain_joints.append(_movable_joint(_URDF_MOVABLE[jtype], A @ O, axis, name=jname,
                                           qlim=qlim, vmax=vmax, what=what))
        A = np.eye(4)
    if not chain_joints:
        raise ImportModelError(f"{label}: no revolute, continuous or prismatic joint between "
                               f"{base_link!r} and {tip!r}", element=f"link {tip!r}")
    rname = name if name is not None else (root.get("name") or "urdf")
    try:
        return Chain(chain_joints, tool=A, name=rname)
    except ModelError as exc:  # pragma: no cover - joints and transforms are validated above
        raise ImportModelError(f"{label}: {exc}", element=str(exc.field)) from None


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
    xyz = _floats(el.get("xyz"), 3, default=[0.0, 0.0, 0.0], what=f"{what} <origin xyz>")
    rpy = _floats(el.get("rpy"), 3, default=[0.0, 0.0, 0.0], what=f"{what} <origin rpy>")
    return _transform(rotation_from_rpy(rpy), xyz)


def _urdf_limits(el: ET.Element, jtype: str, what: str, label: str):
    lim = el.find("limit")
    vmax = None
    lo = hi = None
    if lim is not None:
        v = _float_attr(lim, "velocity", what=f"{what} <limit>")
        if v is not None:
            if v < 0:
                raise ImportModelError(f"{label}: {what} <limit velocity={v}> must be >= 0 [rad/s or m/s]",
                                       element=what)
            vmax = v if v > 0 else None
        lo = _float_attr(lim, "lower", what=f"{what} <limit>")
        hi = _float_attr(lim, "upper", what=f"{what} <limit>")
    if jtype == "continuous":
        return None, vmax
    if lim is None:
        raise ImportModelError(f"{label}: {what} ({jtype}) has no <limit> element; URDF requires "
                               "<limit lower upper velocity effort> (use type 'continuous' for an "
                               "unlimited revolute joint)", element=what)
    lo = 0.0 if lo is None else lo
    hi = 0.0 if hi is None else hi
    if not lo < hi:
        raise ImportModelError(f"{label}: {what} <limit lower={lo} upper={hi}>: lower must be below "
                               "upper", element=what)
    return (lo, hi), vmax


# ---------------------------------------------------------------------- MJCF
_MJ_JOINT_NAMES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def chain_from_mjcf(path_or_model, *, tip: str | None = None, name: str | None = None) -> Chain:
    """Chain from an MJCF file (or its XML text) or a compiled ``mujoco.MjModel``.

    Args:
        path_or_model: path to an ``.xml`` MJCF file, the XML text, or an ``MjModel``.
        tip: name of a site or a body (sites are looked up first) that becomes the
            tool frame. Optional when the moving bodies form a single path (the tip
            is then its last body); required when they branch.
        name: chain name; default the model name.

    The chain reproduces MuJoCo's kinematics: for a body with position ``p_b`` and
    orientation ``quat_b`` relative to its parent, and hinge joints at anchor ``c``
    (body frame) with axis ``a`` and reference ``ref``, the body pose is
    ``T_parent · T(p_b, quat_b) · T(c) · Rot(a, q − ref) · T(−c)``, applied joint by
    joint in their order in the body; a slide joint contributes ``T(a (q − ref))``.
    Hinge and slide joints with ``limited`` ranges give ``qlim`` [rad or m]; MJCF has
    no joint velocity limit, so ``vmax`` is left unlimited.

    Raises:
        ImportModelError: malformed XML, DTD/entity declarations, MuJoCo compile errors,
            ball or free joints on the chain, joint equality constraints coupling a
            chain joint (mimic-like), a branch without a chosen tip, an unknown tip.
    """
    import mujoco

    if isinstance(path_or_model, mujoco.MjModel):
        model, label = path_or_model, "<MjModel>"
    else:
        model, label = _compile_mjcf(path_or_model)
    return _chain_from_model(model, tip=tip, name=name, label=label)


def _compile_mjcf(source):
    import mujoco

    data, label, directory = _read_source(source, "MJCF")
    root = parse_xml_safely(data, label=label)
    if root.tag != "mujoco":
        raise ImportModelError(f"{label}: the root element must be <mujoco>, got <{root.tag}>",
                               element=f"<{root.tag}>")
    _inline_includes(root, directory, label, depth=0)
    _strip_files(root)
    xml = ET.tostring(root, encoding="unicode")
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        msg = str(exc).strip()
        m = re.search(r"Element name '([^']*)', id (\d+)", msg)
        m2 = re.search(r"Element '([^']*)'", msg)
        element = (f"{m2.group(1) if m2 else 'element'} {m.group(1)!r}" if m and m.group(1)
                   else (f"<{m2.group(1)}>" if m2 else "mujoco"))
        raise ImportModelError(f"{label}: MuJoCo cannot compile the model: {msg}",
                               element=element) from None
    return model, label


def _inline_includes(root: ET.Element, directory: Path | None, label: str, *, depth: int) -> None:
    """Replace ``<include file=...>`` by the (safely parsed) children of the included file."""
    if depth > 8:
        raise ImportModelError(f"{label}: <include> nested more than 8 levels", element="include")
    for parent in list(root.iter()):
        for k, child in enumerate(list(parent)):
            if child.tag != "include":
                continue
            fname = child.get("file")
            what = f"include {fname!r}"
            if not fname or directory is None:
                raise ImportModelError(f"{label}: <include file={fname!r}> cannot be resolved "
                                       "(includes need a file path, not XML text)", element=what)
            if "://" in fname:
                raise ImportModelError(f"{label}: <include file={fname!r}>: only local files are read",
                                       element=what)
            fpath = directory / fname
            if not fpath.is_file():
                raise ImportModelError(f"{label}: <include file={fname!r}>: file not found",
                                       element=what)
            sub = parse_xml_safely(fpath.read_bytes(), label=str(fpath))
            _inline_includes(sub, fpath.parent, str(fpath), depth=depth + 1)
            parent.remove(child)
            for j, el in enumerate(list(sub)):
                parent.insert(k + j, el)


def _strip_files(root: ET.Element) -> None:
    """Drop assets read from files (meshes, heightfields, textures, skins) and turn geoms
    that used them into small spheres: kinematics does not depend on them, and ratectl
    never opens them."""
    for asset in root.iter("asset"):
        for el in list(asset):
            if el.tag in ("mesh", "hfield", "skin", "texture") or el.get("file"):
                asset.remove(el)
            elif el.tag == "material":
                el.attrib.pop("texture", None)
    for parent in list(root.iter()):
        for el in list(parent):
            if el.tag == "skin":
                parent.remove(el)
    for el in root.iter():
        if el.tag == "geom" and (el.get("mesh") is not None or el.get("hfield") is not None
                                 or el.get("type") in ("mesh", "hfield", "sdf")):
            el.attrib.pop("mesh", None)
            el.attrib.pop("hfield", None)
            el.set("type", "sphere")
            el.set("size", "0.01")
            el.attrib.pop("fromto", None)
    for d in root.iter("default"):
        for g in d.findall("geom"):
            if g.get("type") in ("mesh", "hfield", "sdf"):
                g.set("type", "sphere")
            g.attrib.pop("mesh", None)
            g.attrib.pop("hfield", None)
    for c in root.iter("compiler"):
        for a in ("meshdir", "texturedir", "assetdir"):
            c.attrib.pop(a, None)


def _mj_name(model, objtype, i: int, kind: str) -> str:
    import mujoco

    n = mujoco.mj_id2name(model, objtype, i)
    return f"{kind} {n!r}" if n else f"{kind} #{i}"


def _chain_from_model(model, *, tip, name, label) -> Chain:
    import mujoco

    OBJ = mujoco.mjtObj
    site = -1
    if tip is not None:
        site = mujoco.mj_name2id(model, OBJ.mjOBJ_SITE, tip)
        if site >= 0:
            tip_body = int(model.site_bodyid[site])
        else:
            tip_body = mujoco.mj_name2id(model, OBJ.mjOBJ_BODY, tip)
            if tip_body < 0:
                sites = [mujoco.mj_id2name(model, OBJ.mjOBJ_SITE, i) for i in range(model.nsite)]
                bodies = [mujoco.mj_id2name(model, OBJ.mjOBJ_BODY, i) for i in range(1, model.nbody)]
                raise ImportModelError(
                    f"{label}: tip {tip!r} is neither a site nor a body of the model; sites: "
                    f"{[s for s in sites if s]}, bodies: {[b for b in bodies if b]}",
                    element=f"tip {tip!r}")
            if tip_body == 0:
                raise ImportModelError(f"{label}: tip {tip!r} is the world body", element=f"body {tip!r}")
    else:
        tip_body = _default_tip_body(model, label)
    # path world -> tip_body
    path = []
    b = tip_body
    while b != 0:
        path.append(b)
        b = int(model.body_parentid[b])
    path.reverse()
    chain_joint_ids = {j for b in path for j in range(model.body_jntadr[b],
                                                      model.body_jntadr[b] + model.body_jntnum[b])}
    _check_equalities(model, chain_joint_ids, label)
    joints: list[Joint] = []
    A = np.eye(4)
    for b in path:
        A = A @ _transform(rotation_from_quat(model.body_quat[b]), model.body_pos[b])
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            jtype = int(model.jnt_type[j])
            what = _mj_name(model, OBJ.mjOBJ_JOINT, j, "joint")
            if jtype not in (2, 3):
                raise ImportModelError(
                    f"{label}: {what} is a {_MJ_JOINT_NAMES.get(jtype, jtype)} joint on the chain to "
                    f"{tip!r}; ratectl chains support hinge and slide joints only", element=what)
            axis = _unit_axis(np.array(model.jnt_axis[j], dtype=float), what)
            qpos0 = float(model.qpos0[model.jnt_qposadr[j]])
            qlim = None
            if model.jnt_limited[j]:
                lo, hi = (float(x) for x in model.jnt_range[j])
                # ±1e10 and beyond stand for an absent bound (one-sided ranges, see to_mjcf)
                qlim = (-math.inf if lo <= -1e10 else lo, math.inf if hi >= 1e10 else hi)
            jname = mujoco.mj_id2name(model, OBJ.mjOBJ_JOINT, j) or f"joint{j}"
            if jtype == 3:
                c = np.array(model.jnt_pos[j], dtype=float)
                joints.append(_movable_joint("revolute", A @ _transform(p=c), axis, name=jname,
                                             qlim=qlim, vmax=None, what=what,
                                             post_extra=_transform(p=-c), offset=qpos0))
            else:
                joints.append(_movable_joint("prismatic", A, axis, name=jname, qlim=qlim, vmax=None,
                                             what=what, offset=qpos0))
            A = np.eye(4)
    if site >= 0:
        A = A @ _transform(rotation_from_quat(model.site_quat[site]), model.site_pos[site])
    if not joints:
        raise ImportModelError(f"{label}: no hinge or slide joint between the world and {tip!r}",
                               element=_mj_name(model, OBJ.mjOBJ_BODY, tip_body, "body"))
    mname = name
    if mname is None:
        raw = bytes(model.names)
        mname = raw[:raw.find(b"\0")].decode("utf-8", "replace") or "mjcf"
    return Chain(joints, tool=A, name=mname)


def _default_tip_body(model, label: str) -> int:
    """The last body of the single path of moving bodies, or an error naming the branch."""
    import mujoco

    nb = model.nbody
    moving = np.zeros(nb, dtype=bool)
    for b in range(1, nb):
        p = int(model.body_parentid[b])
        moving[b] = moving[p] or model.body_jntnum[b] > 0
    relevant = moving.copy()   # moving, or an ancestor of a moving body
    for b in range(nb - 1, 0, -1):  # MuJoCo numbers parents before children
        if relevant[b]:
            relevant[int(model.body_parentid[b])] = True
    kids: dict[int, list[int]] = {}
    for b in range(1, nb):
        if relevant[b]:
            kids.setdefault(int(model.body_parentid[b]), []).append(b)
    if not moving.any():
        raise ImportModelError(f"{label}: the model has no body with a joint", element="worldbody")
    b = 0
    while kids.get(b):
        if len(kids[b]) > 1:
            names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, k) or f"#{k}" for k in kids[b]]
            what = _mj_name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body") if b else "worldbody"
            raise ImportModelError(
                f"{label}: the moving bodies branch at {what} into {names}; pass tip= the name of "
                "a site or body to choose the serial chain", element=what)
        b = kids[b][0]
    return b


def _check_equalities(model, chain_joint_ids: set[int], label: str) -> None:
    import mujoco

    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT):
            continue
        if bool(model.eq_active0[e]) is False:
            continue
        j1, j2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        if j1 in chain_joint_ids or j2 in chain_joint_ids:
            what = _mj_name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e, "equality")
            jn = _mj_name(model, mujoco.mjtObj.mjOBJ_JOINT, j1 if j1 in chain_joint_ids else j2, "joint")
            raise ImportModelError(
                f"{label}: {what} couples {jn} to another joint (a mimic-like joint equality); coupled "
                "joints are not supported on the chain; choose a tip that excludes it", element=what)


def mjcf_joint_addresses(model, chain) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos addresses, dof addresses)`` of the chain's joints in ``model``, matched by name.

    Raises:
        ImportModelError: a chain joint has no hinge/slide joint of that name in the model.
    """
    import mujoco

    qadr, dadr = [], []
    for jn in chain.joint_names:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jn)
        if j < 0 or int(model.jnt_type[j]) not in (2, 3):
            raise ImportModelError(f"the MuJoCo model has no hinge or slide joint named {jn!r} "
                                   "(chain joints are matched to model joints by name)",
                                   element=f"joint {jn!r}")
        qadr.append(int(model.jnt_qposadr[j]))
        dadr.append(int(model.jnt_dofadr[j]))
    return np.array(qadr, dtype=int), np.array(dadr, dtype=int)
