"""Read a serial arm from MJCF (`parse_mjcf`) and match chain joints to a MuJoCo model.

MJCF is checked with the same guard as URDF (`parse_xml_safely`),
mesh/heightfield/texture file references are replaced by placeholders, and the result
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

import numpy as np

from ..errors import ImportModelError
from ..spatial import rotation_from_quat, transform
from .description import JointDescription, ModelDescription, movable_joint, unit_axis
from .xml import parse_xml_safely, read_source

__all__ = ["parse_mjcf", "compile_mjcf", "mjcf_joint_addresses"]

_MJ_JOINT_NAMES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def parse_mjcf(path_or_model, *, tip: str | None = None, name: str | None = None) -> ModelDescription:
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


def compile_mjcf(model_or_source):
    """An ``MjModel`` from an ``MjModel`` (returned as is), MJCF text, bytes or a file path.

    Text and files go through the safety checks of `parse_mjcf` (no DTD/entities,
    mesh files never opened, includes confined as documented there).
    """
    import mujoco

    if isinstance(model_or_source, mujoco.MjModel):
        return model_or_source
    return _compile(model_or_source)[0]


def _compile(source):
    import mujoco

    data, label, directory = read_source(source, "MJCF")
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
    if site >= 0:
        A = A @ transform(rotation_from_quat(model.site_quat[site]), model.site_pos[site])
    if not joints:
        raise ImportModelError(f"{label}: no hinge or slide joint between the world and {tip!r}",
                               element=_mj_name(model, OBJ.mjOBJ_BODY, tip_body, "body"))
    mname = name
    if mname is None:
        raw = bytes(model.names)
        mname = raw[:raw.find(b"\0")].decode("utf-8", "replace") or "mjcf"
    return ModelDescription(joints=tuple(joints), tool=A, name=mname, label=label)


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
