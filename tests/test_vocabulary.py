"""One vocabulary across the public API.

Rules checked here:

* **Exports**: the namespace of ``ratectl`` and of each subpackage holds only its
  ``__all__``, its own submodules and private names — no ``annotations``, ``importlib``,
  ``np`` or typing names leak into a user's tab completion.
* **Scaled and unscaled measures**: a name without suffix is the measure of J as given,
  the suffix ``_scaled`` the same measure of J_L = diag(I/L, I)·J; every result class that
  has both names agrees with the measure functions, and ``inverse_condition`` is
  1/``condition`` in both versions. A measure name means the same number in every
  result (`analyze`, `scan`, `path_distance`).
* **Labels**: a result for one configuration carries ``kind``; a result over many
  carries ``kinds`` (an array of the same strings) and ``kind_code``.
* **Measures take J or (chain, q)**: ``singular_values``, ``manipulability`` and
  ``condition_number`` accept a Jacobian or a chain with q, and say which when given
  neither.
* **Joints**: arguments are 0-based indices (or joint names); human-facing text names
  joints by the chain's ``joint_names`` (no "joint 4", no "q5").
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import types

import numpy as np
import pytest

import ratectl as rc
from ratectl.errors import InputError
from ratectl.singularity import condition_number, path_distance, scan, workspace_map

PACKAGES = ["ratectl", *(f"ratectl.{m}" for m in rc._LAZY_MODULES), "ratectl.solvers.qp", "ratectl.model",
            "ratectl.kinematics", "ratectl.interop.mujoco"]


@pytest.mark.parametrize("name", PACKAGES)
def test_packages_export_only_their_names_and_submodules(name):
    try:
        mod = importlib.import_module(name)
    except ImportError:  # pragma: no cover - an optional extra
        pytest.skip(f"{name} needs an optional extra")
    public = set(getattr(mod, "__all__", ()))
    stray = []
    for key, value in vars(mod).items():
        if key.startswith("_") or key in public:
            continue
        if isinstance(value, types.ModuleType) and value.__name__.startswith(name + "."):
            continue  # its own submodule
        stray.append(key)
    assert not stray, f"{name} exports names outside __all__: {stray}"
    for key in public:
        assert hasattr(mod, key), f"{name}.__all__ lists {key!r}, which does not exist"


ARM = rc.robots.ur5e()
QS = ARM.random_q(6, rng=3)


def _measure_fields(cls):
    return {f.name for f in dataclasses.fields(cls)}


def test_scaled_and_unscaled_names_agree_with_the_measure_functions():
    L = ARM.characteristic_length
    for q in QS:
        r = rc.analyze(ARM, q)
        J = ARM.jacobian(q)
        s, s_L = rc.singular_values(J), rc.singular_values(J, length=L)
        assert np.allclose(r.sigma, s) and np.allclose(r.sigma_scaled, s_L)
        assert r.sigma_min == pytest.approx(s[-1]) and r.sigma_min_scaled == pytest.approx(s_L[-1])
        assert r.manipulability == pytest.approx(float(rc.manipulability(J)))
        assert r.manipulability_scaled == pytest.approx(float(rc.manipulability(J, length=L)))
        assert r.condition == pytest.approx(float(condition_number(J)))
        assert r.condition_scaled == pytest.approx(float(condition_number(J, length=L)))
        assert r.inverse_condition == pytest.approx(1.0 / r.condition)
        assert r.inverse_condition_scaled == pytest.approx(1.0 / r.condition_scaled)
    # every result class that has an X_scaled and an X: X is of J, X_scaled of J_L
    for cls in (rc.SingularityReport, rc.singularity.ScanResult, rc.singularity.PathDistance):
        names = _measure_fields(cls)
        for n in names:
            if n.endswith("_scaled"):
                assert not n.startswith("scaled_")
        assert "inverse_condition" not in names or "inverse_condition_scaled" in names


def test_one_measure_name_means_one_number_in_every_result():
    rs = [rc.analyze(ARM, q) for q in QS]
    sc = scan(ARM, QS, raw=True)
    pd = path_distance(ARM, QS)
    shared = _measure_fields(rc.SingularityReport) & _measure_fields(rc.singularity.ScanResult)
    shared -= {"q", "length"}
    assert {"sigma_min_scaled", "inverse_condition_scaled", "manipulability", "condition"} <= shared
    for name in sorted(shared):
        col = getattr(sc, name)
        if col is None or np.asarray(getattr(rs[0], name)).dtype.kind not in "fiub":
            continue
        for k, r in enumerate(rs):
            assert np.allclose(np.asarray(col[k], dtype=float), np.asarray(getattr(r, name), dtype=float),
                               rtol=1e-9, atol=1e-12), name
    for name in _measure_fields(rc.singularity.PathDistance) & _measure_fields(rc.singularity.ScanResult):
        if name in ("q", "length", "kind_code"):
            continue
        assert np.allclose(getattr(pd, name), getattr(sc, name), rtol=1e-9), name


def test_one_result_has_kind_and_many_have_kinds_with_the_same_words():
    sc = scan(ARM, QS)
    assert [rc.analyze(ARM, q).kind for q in QS] == list(sc.kinds)
    assert list(path_distance(ARM, QS).kinds) == list(sc.kinds)
    assert not hasattr(rc.analyze(ARM, QS[0]), "kinds") and not hasattr(sc, "kind")


def test_measures_take_a_jacobian_or_a_chain_and_q():
    q = QS[0]
    J = ARM.jacobian(q)
    assert np.allclose(rc.singular_values(ARM, q), rc.singular_values(J))
    assert rc.manipulability(ARM, q) == pytest.approx(float(rc.manipulability(J)))
    assert condition_number(ARM, q, length=0.5) == pytest.approx(float(condition_number(J, length=0.5)))
    assert np.allclose(rc.singular_values(ARM, QS), rc.singular_values(ARM.jacobian(QS)))
    with pytest.raises(InputError, match="joint positions"):
        rc.singular_values(ARM)
    with pytest.raises(InputError, match="either a Jacobian"):
        rc.manipulability(J, q)


_NUMBERED = re.compile(r"\bjoints? \d|\bq\d\b|\baxis \d")


def _near_configs(arm, kinds):
    qs = arm.random_q(4000, rng=0)
    sc = scan(arm, qs)
    out = []
    for kind in kinds:
        k = np.flatnonzero(sc.kinds == kind)
        if k.size:
            out.append(qs[k[0]])
    return out


@pytest.mark.parametrize("arm", [rc.robots.ur5e(), rc.robots.puma560(), rc.robots.stanford(),
                                 rc.robots.panda(), rc.robots.iiwa7()], ids=lambda a: a.name)
def test_reports_name_joints_by_their_names(arm):
    qs = _near_configs(arm, ("wrist", "elbow", "shoulder", "boundary", "rank-deficient"))
    q5 = np.clip(np.zeros(arm.dof), arm.lower, arm.upper)
    for q in [*qs, q5]:
        r = rc.analyze(arm, q)
        text = str(r)
        assert not _NUMBERED.search(text), text
        if r.kind != "regular":
            assert any(repr(n) in text for n in arm.joint_names), text
        assert f"σ_min(J) = {r.sigma_min:.3g}" in text and f"σ_min(J_L) = {r.sigma_min_scaled:.3g}" in text
        assert "estimated" in text  # the joint distance is a first-order estimate, said so
        if not r.singular:  # full rank: never "rank-deficient (rank 6/6", but "near rank-deficient"
            assert not re.search(r"(?<!near )rank-deficient \(rank (\d)/\1", text), text


def test_workspace_map_joints_are_0_based_or_names_and_labelled_by_name():
    arm = rc.robots.ur5e()
    a = workspace_map(arm, joints=(2, 4), resolution=5)
    b = workspace_map(arm, joints=("elbow", "wrist_2"), resolution=5)
    assert np.array_equal(a.values, b.values)
    assert "wrist_2" in a.ylabel and "elbow" in a.xlabel and not _NUMBERED.search(a.title)
    for bad in ((1, 1), (0, 6), ("elbow", "nope"), (0.5, 1), "ab"):
        with pytest.raises(InputError):
            workspace_map(arm, joints=bad, resolution=5)


def test_workspace_map_covers_the_whole_joint_range():
    jaco = rc.Chain.from_dh([rc.DH(a=0.0, alpha=np.pi / 2, d=0.2, theta=0.0, qlim=(0.52, 5.76)),
                            rc.DH(a=0.4, alpha=0.0, d=0.0, theta=0.0, qlim=(-2.0, 2.0)),
                            rc.DH(a=0.0, alpha=np.pi / 2, d=0.0, theta=0.0, qlim=(-7.0, 7.0))], name="wide")
    m = workspace_map(jaco, joints=(0, 2), resolution=5)
    assert m.x[0] == pytest.approx(0.52) and m.x[-1] == pytest.approx(5.76)
    assert m.y[0] == pytest.approx(-7.0) and m.y[-1] == pytest.approx(7.0)


def test_fewer_joint_text_is_grammatical():
    arm = rc.Chain.from_dh(list(rc.robots.ur5e().table[:5]), name="ur5e without its last joint")
    text = rc.analyze(arm, np.array([0.1, -1.2, 1.3, -1.6, 1.0])).reason
    assert "(1 is unreachable" in text or "are unreachable" in text
    assert "(1 are" not in text
