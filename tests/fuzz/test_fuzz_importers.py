"""Fuzz: the URDF and MJCF importers on generated hostile files.

* Entity bombs and external entities, in UTF-8, UTF-16 and UTF-32, with and without a
  byte-order mark or an XML declaration: always refused.
* Include bombs, include path escapes (absolute, ``..``, symlinks, /proc), file
  attributes of every kind pointing outside: refused, or stripped so MuJoCo never opens
  them (the targets do not exist: an attempt to open one would fail the compile).
* Deep nesting and huge numbers: a chain or a ratectl error, never a RecursionError.

Every import finishes within 5 s and reads (through Python) no file outside the model's
directory (an audit hook records every ``open``).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import ImportModelError, RatectlError

_OPENED: list[str] | None = None


def _audit(event, args):
    if _OPENED is not None and event == "open" and args and isinstance(args[0], str | bytes | os.PathLike):
        _OPENED.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)


def _import(fuzz, what, f, allowed_dir: Path | None):
    """Run one import: (result or the ratectl error), checking time and opened files."""
    global _OPENED
    fuzz.count(what)
    _OPENED = []
    t0 = time.perf_counter()
    try:
        out = f()
    except RatectlError as exc:
        out = exc
    finally:
        opened, _OPENED = _OPENED, None
    assert time.perf_counter() - t0 < 5.0
    for p in opened:
        real = os.path.realpath(p)
        if allowed_dir is not None and real.startswith(str(allowed_dir.resolve())):
            continue
        # Python modules (a lazy import) and installed packages' metadata (entry points read
        # by the import system) are fine; nothing else may be read
        assert (real.endswith((".py", ".pyc", ".so")) or ".egg-info" in real or ".dist-info" in real
                or "python3" in real), real
    return out


ENCODINGS = ["utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-32-le", "utf-32-be"]


def _urdf_text(r, *, n: int, huge: bool) -> str:
    def num():
        v = r.uniform(-1, 1)
        if huge and r.random() < 0.3:
            v *= 10.0 ** r.uniform(0, 308)
        return repr(float(v))

    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = []
    for i in range(n):
        kind = r.choice(["revolute", "continuous", "prismatic", "fixed"])
        joints.append(
            f'<joint name="j{i}" type="{kind}"><parent link="l{i}"/><child link="l{i + 1}"/>'
            f'<origin xyz="{num()} {num()} {num()}" rpy="{num()} {num()} {num()}"/>'
            f'<axis xyz="{num()} {num()} {num()}"/>'
            f'<limit lower="-1" upper="1" velocity="{abs(float(num()))}" effort="1"/></joint>')
    return f'<robot name="fuzz">{links}{"".join(joints)}</robot>'


_DECLS = [
    '<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>',
    '<!DOCTYPE robot SYSTEM "file:///etc/passwd">',
    '<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>',
    '<!ENTITY a "b">',
    '<!DOCTYPE  robot>',
    '<!doctype robot>',
]


def test_urdf_entity_declarations_are_refused_in_every_encoding(fuzz):
    @fuzz.settings(25)
    @given(seed=st.integers(0, 2**32 - 1), enc=st.sampled_from(ENCODINGS),
           decl=st.sampled_from(_DECLS), with_xml_decl=st.booleans(), as_text=st.booleans())
    def prop(seed, enc, decl, with_xml_decl, as_text):
        r = np.random.default_rng(seed)
        body = _urdf_text(r, n=int(r.integers(1, 6)), huge=False)
        head = f'<?xml version="1.0" encoding="{enc.replace("-sig", "")}"?>\n' if with_xml_decl else ""
        doc = head + decl + "\n" + body.replace('name="fuzz"', 'name="&b;"' if "ENTITY b" in decl else
                                                'name="fuzz"')
        src = doc if as_text and not with_xml_decl else doc.encode(enc)
        out = _import(fuzz, "urdf", lambda: rc.Chain.from_urdf(src), None)
        assert isinstance(out, ImportModelError), out
        assert out.element in ("<!DOCTYPE>", "<!ENTITY>"), out

    prop()


def test_urdf_generated_files_import_or_raise_ratectl_errors(fuzz, tmp_path):
    @fuzz.settings(25)
    @given(seed=st.integers(0, 2**32 - 1), enc=st.sampled_from(ENCODINGS), huge=st.booleans(),
           as_file=st.booleans())
    def prop(seed, enc, huge, as_file):
        r = np.random.default_rng(seed)
        doc = _urdf_text(r, n=int(r.integers(1, 8)), huge=huge)
        data = doc.encode(enc)
        src: object = data
        if as_file:
            f = tmp_path / f"m{seed}.urdf"
            f.write_bytes(data)
            src = f
        out = _import(fuzz, "urdf", lambda: rc.Chain.from_urdf(src), tmp_path)
        if isinstance(out, RatectlError):
            assert str(out)
            return
        q = out.random_q(rng=seed) if out.dof else None
        T = out.fk(q)
        assert np.all(np.isfinite(T))
        if not huge:
            assert out.name == "fuzz"

    prop()


# ---------------------------------------------------------------------- MJCF
_ARM = ('<body name="b1"><joint name="j1" type="hinge" axis="0 0 1"/><geom size="0.05"/>'
        '<body name="b2" pos="0 0 0.3"><joint name="j2" type="hinge" axis="0 1 0"/><geom size="0.05"/>'
        '</body></body>')


def test_mjcf_include_bombs_are_stopped(fuzz, tmp_path):
    @fuzz.settings(6)
    @given(depth=st.integers(1, 12), fanout=st.integers(1, 12))
    def prop(depth, fanout):
        d = tmp_path / f"bomb_{depth}_{fanout}"
        d.mkdir(exist_ok=True)
        for i in range(depth):
            inc = "".join(f'<include file="f{i + 1}.xml"/>' for _ in range(fanout)) if i < depth - 1 \
                else '<body><geom size="0.01"/></body>'
            (d / f"f{i}.xml").write_text(f"<mujoco>{inc}</mujoco>")
        (d / "top.xml").write_text(f'<mujoco><worldbody><include file="f0.xml"/>{_ARM}</worldbody></mujoco>')
        out = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(d / "top.xml", tip="b2"), d)
        total = sum(fanout**k for k in range(depth))  # top includes f0 once, f0 includes f1 fanout×, ...
        if depth <= 8 and total <= 64:
            assert isinstance(out, rc.Chain), out
        else:
            assert isinstance(out, ImportModelError) and "include" in str(out), out

    prop()


_ESCAPES = ["/etc/passwd", "/proc/self/environ", "../outside.xml", "sub/../../outside.xml", "~/x.xml",
            "file:///etc/passwd", "link/passwd", "/dev/zero", "C:/x.xml", "sub/../inside.xml", "nul\0.xml"]


@pytest.mark.parametrize("target", _ESCAPES)
def test_mjcf_include_escapes_are_refused(fuzz, tmp_path, target):
    d = tmp_path / "model"
    (d / "sub").mkdir(parents=True)
    (tmp_path / "outside.xml").write_text("<mujoco><worldbody/></mujoco>")
    (d / "inside.xml").write_text("<mujoco></mujoco>")
    os.symlink("/etc", d / "link")
    top = d / "top.xml"
    top.write_text(f'<mujoco><worldbody><include file="{target}"/>{_ARM}</worldbody></mujoco>'
                   .replace("\0", "&#0;") if "\0" not in target else
                   f'<mujoco><worldbody><include file="nul.xml\x01"/>{_ARM}</worldbody></mujoco>')
    out = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(top, tip="b2"), d)
    if target == "sub/../inside.xml":  # '..' is refused even when it stays inside
        assert isinstance(out, ImportModelError)
    else:
        assert isinstance(out, ImportModelError), out


_FILE_REFS = [
    '<asset><mesh name="m" file="{p}.stl"/></asset>',
    '<asset><hfield name="h" file="{p}.png"/></asset>',
    '<asset><texture name="t" type="skybox" file="{p}.png"/></asset>',
    '<asset><texture name="t" type="cube" fileright="{p}.png" fileleft="{p}.png"/></asset>',
    '<asset><skin file="{p}.skn"/></asset>',
    '<asset><model name="sub" file="{p}.xml"/></asset>',
    '<compiler meshdir="{p}" texturedir="{p}" assetdir="{p}"/>',
    '<extension><plugin plugin="mujoco.elasticity.cable"/></extension>',
    '<worldbody><flexcomp name="f" type="mesh" file="{p}.obj" dim="2"/></worldbody>',
    '<worldbody><flexcomp name="g" type="gmsh" file="{p}.msh" dim="3"/></worldbody>',
    '<deformable><skin file="{p}.skn"/></deformable>',
    '<custom><text name="t" data="{p}"/></custom>',
]


def test_mjcf_file_references_are_never_opened(fuzz, tmp_path):
    @fuzz.settings(12)
    @given(picks=st.lists(st.sampled_from(_FILE_REFS), min_size=1, max_size=4, unique=True),
           mesh_geom=st.booleans())
    def prop(picks, mesh_geom):
        missing = "/nonexistent_ratectl_fuzz/x"
        extra = "".join(p.format(p=missing) for p in picks)
        geom = '<geom type="mesh" mesh="m"/>' if mesh_geom else ""
        doc = f'<mujoco>{extra}<worldbody><body name="b0">{geom}</body>{_ARM}</worldbody></mujoco>'
        f = tmp_path / "files.xml"
        f.write_text(doc)
        out = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(f, tip="b2"), tmp_path)
        # any opening attempt of the (missing) files would make MuJoCo's compile fail
        assert isinstance(out, rc.Chain), out
        assert out.dof == 2

    prop()


def test_mjcf_deep_nesting_is_a_chain_or_a_ratectl_error(fuzz):
    @fuzz.settings(5)
    @given(depth=st.sampled_from([10, 120, 399, 1000, 3000]))
    def prop(depth):
        body = "".join(f'<body name="b{i}" pos="0 0 0.01"><joint type="hinge"/><geom size="0.001"/>'
                       for i in range(depth)) + "</body>" * depth
        doc = f"<mujoco><worldbody>{body}</worldbody></mujoco>"
        out = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(doc), None)
        if depth < 300:
            assert isinstance(out, rc.Chain) and out.dof == depth, out
        else:
            assert isinstance(out, ImportModelError), out

    prop()


def test_urdf_deep_and_long_chains(fuzz):
    # URDF is flat: a 300-link chain imports and its first fk is fast (linear kernel)
    n = 300
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0 0 0.01"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/>'
                     "</joint>" for i in range(n))
    chain = _import(fuzz, "urdf", lambda: rc.Chain.from_urdf(f'<robot name="long">{links}{joints}</robot>'),
                    None)
    t0 = time.perf_counter()
    T = chain.fk(np.zeros(n))
    assert time.perf_counter() - t0 < 1.0
    assert np.isclose(T[2, 3], 0.01 * n)
    # nested XML far beyond the depth cap
    deep = "<robot>" + "<a>" * 5000 + "</a>" * 5000 + "</robot>"
    out = _import(fuzz, "urdf", lambda: rc.Chain.from_urdf(deep), None)
    assert isinstance(out, ImportModelError)


# ------------------------------------------------- directions at every scale
def _scaled(d, scale) -> str:
    return " ".join(repr(float(x) * scale) for x in d)


def test_joint_axes_at_every_scale_are_the_same_unit_vector_in_urdf_and_mjcf(fuzz):
    """A joint axis means its direction: any positive multiple (1e-10 … 1e300) of it gives
    the same joint in both readers, or (zero, tiny, infinite) the same refusal."""
    @fuzz.settings(40)
    @given(seed=st.integers(0, 2**32 - 1),
           exponent=st.sampled_from([-300, -13, -10, 0, 10, 100, 200, 300, 307, 400]),
           zeros=st.integers(0, 2))
    def prop(seed, exponent, zeros):
        r = np.random.default_rng(seed)
        d = r.uniform(0.1, 1.0, 3) * r.choice([-1.0, 1.0], 3)
        d[r.permutation(3)[:zeros]] = 0.0
        scale = 10.0 ** exponent if exponent < 400 else math.inf
        ax = _scaled(d, scale)
        urdf = ('<robot name="r"><link name="a"/><link name="b"/><joint name="j1" type="continuous">'
                f'<parent link="a"/><child link="b"/><axis xyz="{ax}"/></joint></robot>')
        mjcf = (f'<mujoco><worldbody><body name="b"><joint name="j1" type="hinge" axis="{ax}"/>'
                '<geom size="0.05"/></body></worldbody></mujoco>')
        outs = [_import(fuzz, kind, lambda f=f, doc=doc: f(doc), None)
                for kind, f, doc in (("urdf", rc.Chain.from_urdf, urdf), ("mjcf", rc.Chain.from_mjcf, mjcf))]
        if exponent <= -13 or exponent >= 400:
            for out in outs:
                assert isinstance(out, ImportModelError) and out.element.startswith("joint 'j1'"), out
                assert any(w in str(out) for w in ("zero length", "not finite", "finite numbers")), out
            return
        unit = d / np.linalg.norm(d)
        for out in outs:
            assert isinstance(out, rc.Chain), out
            z = out.joint_axes(np.zeros(1))[0][0]
            np.testing.assert_allclose(z, unit, atol=1e-12)

    prop()


_ORIENTATIONS = [("axisangle", [1.0, 1.0, 0.0], ["1"]), ("zaxis", [1.0, -2.0, 0.5], []),
                 ("quat", [0.0, 1.0, 0.0, 0.0], []), ("quat", [0.5, 0.5, -0.5, 0.5], []),
                 ("xyaxes", [1.0, 0.0, 0.0], ["0", "1", "0.2"])]


@pytest.mark.parametrize("attr, vec, rest", _ORIENTATIONS)
@pytest.mark.parametrize("exponent", [-10, 100, 300, 307])
def test_mjcf_orientations_mean_the_same_at_every_scale(fuzz, attr, vec, rest, exponent):
    """A body's ``axisangle``, ``zaxis``, ``quat`` or ``xyaxes`` scaled by a positive
    factor is the same orientation (MuJoCo alone turns a huge one into the identity)."""
    def arm(values: str | None) -> str:
        orientation = "" if values is None else f'{attr}="{values}"'
        return (f'<mujoco><worldbody><body name="b1" {orientation}>'
                '<joint name="j1" type="hinge" axis="0 0 1"/><geom size="0.05"/>'
                '<body name="b2" pos="0 0 0.3"><joint name="j2" type="hinge" axis="0 1 0"/>'
                '<geom size="0.05"/></body></body></worldbody></mujoco>')

    plain = " ".join([_scaled(vec, 1.0), *rest])
    big = " ".join([_scaled(vec, 10.0 ** exponent), *rest])
    ref = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(arm(plain)), None)
    out = _import(fuzz, "mjcf", lambda: rc.Chain.from_mjcf(arm(big)), None)
    q = np.array([0.3, -0.7])
    np.testing.assert_allclose(out.fk(q), ref.fk(q), atol=1e-12)
    assert not np.allclose(rc.Chain.from_mjcf(arm(None)).fk(q), ref.fk(q))  # not the identity
