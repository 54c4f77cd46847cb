"""Read a serial arm from MJCF (`parse_mjcf`) and match chain joints to a MuJoCo model.

MJCF is checked with the same guard as URDF (`parse_xml_safely`),
``<include>`` files are inlined under caps and confined to the model's directory, every
element or attribute that would make MuJoCo open a file (mesh, heightfield, texture,
skin, flexcomp, sub-model, plugin, ``*dir``) is removed, and the result
is compiled by MuJoCo, the authority on MJCF semantics (defaults, angle units,
``euler`` sequences, ``ref`` positions); the chain is read from the compiled ``MjModel``.
Joint-less bodies are folded into the next joint's ``pre`` or into the tool transform;
the base is MuJoCo's world body.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ImportModelError
from ..spatial import rotation_from_quat, transform
from .description import JointDescription, ModelDescription, movable_joint, unit_axis
from .xml import MAX_BYTES, MAX_DEPTH, parse_xml_safely, read_file_capped, read_source

if TYPE_CHECKING:
    import mujoco

    from ..model.chain import Chain

__all__ = ["parse_mjcf", "compile_mjcf", "mjcf_joint_addresses"]

_MJ_JOINT_NAMES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def parse_mjcf(path_or_model: Any, *, tip: str | None = None, name: str | None = None) -> ModelDescription:
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
        model, label = _compile(path_or_model)
    return _describe_model(model, tip=tip, name=name, label=label)


def compile_mjcf(model_or_source: Any):
    """An ``MjModel`` from an ``MjModel`` (returned as is), MJCF text, bytes or a file path.

    Text and files go through the safety checks of `parse_mjcf` (no DTD/entities,
    mesh files never opened, includes confined as documented there).
    """
    import mujoco

    if isinstance(model_or_source, mujoco.MjModel):
        return model_or_source
    return _compile(model_or_source)[0]


#: Caps on ``<include>``: files read in total (each inclusion counts), and nesting depth.
MAX_INCLUDES = 64
MAX_INCLUDE_DEPTH = 8


def _compile(source):
    import mujoco

    data, label, directory = read_source(source, "MJCF")
    root = parse_xml_safely(data, label=label)
    if root.tag != "mujoco":
        raise ImportModelError(f"{label}: the root element must be <mujoco>, got <{root.tag}>",
                               element=f"<{root.tag}>")
    size = len(data) if isinstance(data, bytes) else len(data.encode("utf-8", "surrogatepass"))
    budget = _IncludeBudget(directory, size)
    _inline_includes(root, directory, label, depth=0, budget=budget)
    _check_depth_after_includes(root, label)
    _strip_files(root)
    _normalise_directions(root, label)
    try:
        xml = ET.tostring(root, encoding="unicode")
    except RecursionError:  # guarded by the depth check; kept as a last line of defence
        raise ImportModelError(f"{label}: elements are nested too deeply", element="mujoco") from None
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except Exception as exc:  # ValueError for compile errors; MuJoCo's other types too
        msg = str(exc).strip()
        m = re.search(r"Element name '([^']*)', id (\d+)", msg)
        m2 = re.search(r"Element '([^']*)'", msg)
        element = (f"{m2.group(1) if m2 else 'element'} {m.group(1)!r}" if m and m.group(1)
                   else (f"<{m2.group(1)}>" if m2 else "mujoco"))
        raise ImportModelError(f"{label}: MuJoCo cannot compile the model: {msg}",
                               element=element) from None
    return model, label


class _IncludeBudget:
    """What the includes of one model may still read: files (each inclusion counts, so an
    include bomb is stopped after `MAX_INCLUDES`) and bytes (the model and every
    included file together stay under `MAX_BYTES`); and the one
    directory they must stay inside (the top model's, symlinks resolved)."""

    def __init__(self, directory: Path | None, used: int) -> None:
        self.root = None if directory is None else directory.resolve()
        self.files = 0
        self.bytes = used


def _check_depth_after_includes(root: ET.Element, label: str) -> None:
    stack = [(root, 1)]
    while stack:
        el, d = stack.pop()
        if d > MAX_DEPTH:
            raise ImportModelError(f"{label}: with its includes, elements are nested more than "
                                   f"{MAX_DEPTH} levels deep (at <{el.tag}>); refused",
                                   element=f"<{el.tag}>")
        stack.extend((c, d + 1) for c in el)


def _resolve_include(fname: str, directory: Path, budget: _IncludeBudget, label: str) -> Path:
    """The file an ``<include file=...>`` names, confined to the model's directory."""
    what = f"include {fname!r}"
    if "\0" in fname or "://" in fname or fname.startswith(("/", "\\", "~")) or \
            re.match(r"^[A-Za-z]:", fname) or Path(fname).is_absolute():
        raise ImportModelError(f"{label}: <include file={fname!r}>: only relative paths inside the "
                               "model's directory are read (no absolute paths, URLs or ~)", element=what)
    if ".." in re.split(r"[\\/]", fname):
        raise ImportModelError(f"{label}: <include file={fname!r}>: '..' is not allowed; includes "
                               "must stay inside the model's directory", element=what)
    fpath = directory / fname
    try:
        real = fpath.resolve(strict=True)
    except (OSError, RuntimeError):
        raise ImportModelError(f"{label}: <include file={fname!r}>: file not found", element=what) \
            from None
    if budget.root is None or not real.is_relative_to(budget.root):
        raise ImportModelError(f"{label}: <include file={fname!r}> resolves to {str(real)!r}, outside "
                               f"the model's directory {str(budget.root)!r}; refused", element=what)
    return real


def _inline_includes(root: ET.Element, directory: Path | None, label: str, *, depth: int,
                     budget: _IncludeBudget) -> None:
    """Replace ``<include file=...>`` by the (safely parsed) children of the included file.

    Includes are confined (relative paths inside the top model's directory, no ``..``,
    symlinks resolved), nested at most `MAX_INCLUDE_DEPTH` deep, at most
    `MAX_INCLUDES` inclusions in total, and the bytes of the model and all its
    inclusions together at most `MAX_BYTES`.
    """
    for parent in list(root.iter()):
        for k, child in enumerate(list(parent)):
            if child.tag != "include":
                continue
            fname = child.get("file")
            what = f"include {fname!r}"
            if not fname or directory is None:
                raise ImportModelError(f"{label}: <include file={fname!r}> cannot be resolved "
                                       "(includes need a model read from a file, not XML text)",
                                       element=what)
            if depth + 1 > MAX_INCLUDE_DEPTH:
                raise ImportModelError(f"{label}: <include> nested more than {MAX_INCLUDE_DEPTH} "
                                       "levels", element="include")
            real = _resolve_include(fname, directory, budget, label)
            budget.files += 1
            if budget.files > MAX_INCLUDES:
                raise ImportModelError(f"{label}: more than {MAX_INCLUDES} <include> inclusions in "
                                       "total (an include bomb?); refused", element=what)
            data = read_file_capped(real, "MJCF include", MAX_BYTES - budget.bytes)
            budget.bytes += len(data)
            sub = parse_xml_safely(data, label=str(real))
            _inline_includes(sub, real.parent, str(real), depth=depth + 1, budget=budget)
            parent.remove(child)
            for j, el in enumerate(list(sub)):
                parent.insert(k + j, el)


# Elements whose only purpose is data read from files (or plugin code), removed whole.
_FILE_ELEMENTS = frozenset({"mesh", "hfield", "skin", "texture", "model", "plugin", "extension",
                            "flexcomp", "flex"})
# Attributes naming files or directories of files, removed wherever they appear.
_FILE_ATTRS = re.compile(r"^(file.*|meshdir|texturedir|assetdir|content_type|plugin|instance)$")


def _strip_files(root: ET.Element) -> None:
    """Remove everything that makes MuJoCo open a file or load plugin code: the elements
    of `_FILE_ELEMENTS` (meshes, heightfields, skins, textures, sub-models,
    flexcomps, plugins), every ``file*`` attribute on any element (texture ``fileright``,
    ...) and the compiler's ``meshdir``/``texturedir``/``assetdir``, and turn geoms that
    used a mesh or heightfield into small spheres. Kinematics does not depend on them, and
    MuJoCo is never given a file name (checked after stripping)."""
    for parent in list(root.iter()):
        for el in list(parent):
            if el.tag in _FILE_ELEMENTS:
                parent.remove(el)
    for el in root.iter():
        for a in [a for a in el.attrib if _FILE_ATTRS.match(a)]:
            del el.attrib[a]
        if el.tag == "material":
            el.attrib.pop("texture", None)
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
    for el in root.iter():  # the guarantee the docstring gives
        if el.tag in _FILE_ELEMENTS or any(_FILE_ATTRS.match(a) for a in el.attrib):
            raise ImportModelError(f"<{el.tag}> still names a file after stripping (internal error)",
                                   element=f"<{el.tag}>")


#: Attributes that hold directions (or a quaternion) MuJoCo normalises when it compiles:
#: the attribute, the number of values it holds, and where its vectors start and end.
_DIRECTIONS = {
    "axis": (3, ((0, 3),)),             # a joint axis
    "zaxis": (3, ((0, 3),)),            # an orientation by its z axis
    "axisangle": (4, ((0, 3),)),        # the axis of an axis-angle orientation
    "xyaxes": (6, ((0, 3), (3, 6))),    # an orientation by its x and y axes
    "quat": (4, ((0, 4),)),             # a quaternion
}


def _normalise_directions(root: ET.Element, label: str) -> None:
    """Replace every direction and quaternion in the file by the unit vector `unit_axis`
    makes of it, before MuJoCo sees it.

    MuJoCo's own normalisation ``v / ‖v‖`` overflows for large components (a joint axis
    ``1e300 1e300 0`` compiles to ``0 0 0``, a quaternion ``0 1e300 0 0`` to the identity);
    `unit_axis` scales by the largest component first, so the URDF and MJCF readers give
    one answer: (1, 1, 0)/√2. A positive factor changes no axis, orientation or rotation, so
    the compiled model is MuJoCo's for every file it reads correctly. Values that are not
    the right count of numbers are left for MuJoCo to report.

    Raises:
        ImportModelError: a direction or quaternion that is zero, shorter than 1e-12, or
            not finite (the wording of the URDF reader).
    """
    for el in root.iter():
        for attr, (count, spans) in _DIRECTIONS.items():
            text = el.get(attr)
            if text is None:
                continue
            try:
                vals = [float(t) for t in text.split()]
            except ValueError:
                continue
            if len(vals) != count:
                continue
            name = el.get("name")
            what = f"{el.tag} {name!r}" if name else f"<{el.tag}>"
            noun = "joint axis" if el.tag == "joint" and attr == "axis" else f"{attr!r} vector"
            for a, b in spans:
                vals[a:b] = unit_axis(vals[a:b], what, label=label, noun=noun).tolist()
            el.set(attr, " ".join(repr(v) for v in vals))


def _mj_name(model, objtype, i: int, kind: str) -> str:
    import mujoco

    n = mujoco.mj_id2name(model, objtype, i)
    return f"{kind} {n!r}" if n else f"{kind} #{i}"


def _describe_model(model, *, tip, name, label) -> ModelDescription:
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
    joints: list[JointDescription] = []
    links: list[tuple[str, int, np.ndarray]] = []
    A = np.eye(4)
    for b in path:
        A = A @ transform(rotation_from_quat(model.body_quat[b]), model.body_pos[b])
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            jtype = int(model.jnt_type[j])
            what = _mj_name(model, OBJ.mjOBJ_JOINT, j, "joint")
            if jtype not in (2, 3):
                raise ImportModelError(
                    f"{label}: {what} is a {_MJ_JOINT_NAMES.get(jtype, jtype)} joint on the chain to "
                    f"{tip!r}; ratectl chains support hinge and slide joints only", element=what)
            axis = unit_axis(np.array(model.jnt_axis[j], dtype=float), what)
            qpos0 = float(model.qpos0[model.jnt_qposadr[j]])
            qlim = None
            if model.jnt_limited[j]:
                lo, hi = (float(x) for x in model.jnt_range[j])
                # ±1e10 and beyond stand for an absent bound (one-sided ranges, see to_mjcf)
                qlim = (-math.inf if lo <= -1e10 else lo, math.inf if hi >= 1e10 else hi)
            jname = mujoco.mj_id2name(model, OBJ.mjOBJ_JOINT, j) or f"joint{j}"
            if jtype == 3:
                c = np.array(model.jnt_pos[j], dtype=float)
                joints.append(movable_joint("revolute", A @ transform(p=c), axis, name=jname,
                                             qlim=qlim, vmax=None, what=what,
                                             post_extra=transform(p=-c), offset=qpos0))
            else:
                joints.append(movable_joint("prismatic", A, axis, name=jname, qlim=qlim, vmax=None,
                                             what=what, offset=qpos0))
            A = np.eye(4)
        links.append((mujoco.mj_id2name(model, OBJ.mjOBJ_BODY, b) or f"body{b}", len(joints), A))
    if site >= 0:
        A = A @ transform(rotation_from_quat(model.site_quat[site]), model.site_pos[site])
    if not joints:
        raise ImportModelError(f"{label}: no hinge or slide joint between the world and {tip!r}",
                               element=_mj_name(model, OBJ.mjOBJ_BODY, tip_body, "body"))
    mname = name
    if mname is None:
        raw = bytes(model.names)
        mname = raw[:raw.find(b"\0")].decode("utf-8", "replace") or "mjcf"
    return ModelDescription(joints=tuple(joints), tool=A, name=mname, label=label, links=tuple(links))


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


def mjcf_joint_addresses(model: mujoco.MjModel, chain: Chain) -> tuple[np.ndarray, np.ndarray]:
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
