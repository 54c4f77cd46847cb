"""The reproducers of the reliability report (solvers, kinematics, importers, paths), one
test each: finite output or a ratectl error, limits held, hostile files refused, clear
messages."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

import ratectl as rc
from ratectl.errors import ImportModelError, InputError, ModelError, RatectlError, SolverError
from ratectl.model.limits import Limits
from ratectl.solvers import QP, joint_velocity_bounds

INF = math.inf


def _in_box(qd, lo, hi, rel=1e-6):
    tol = rel * (1.0 + np.abs(qd))
    return bool(np.all(qd >= lo - tol) and np.all(qd <= hi + tol))


# 1. the active-set step answered outside its own box
def test_qp_active_set_answer_stays_in_its_box():
    lim = Limits(lower=[-.4099, -1.4093, -.1346], upper=[-.1266, .0776, -.1143], vmax=[2, .5, .05],
                 amax=[INF, 1, 10])
    J = [[.1923, .3356, 1.58], [.5752, -1.3006, -1.2014]]
    q = [-.1433, -1.4093, -.1309]
    r = QP(damping=1e-3).solve(J=J, xi=[.068, .0677], limits=lim, q=q, dt=.1)
    assert _in_box(r.qd, r.info["lower"], r.info["upper"])
    assert r.qd[1] >= -1e-12  # its box is [0, 0.5]
    ref = QP(damping=1e-3, backend="daqp").solve(J=J, xi=[.068, .0677], limits=lim, q=q, dt=.1)
    assert np.allclose(r.qd, ref.qd, atol=1e-7)


# 5. with a joint feed-forward the QP bounds the total
def test_qp_feed_forward_total_respects_every_limit():
    lim = Limits(lower=[-1.0, -1.0], upper=[0.5, 1.0], vmax=[1.0, 1.0], amax=[2.0, 2.0])
    q, qd_prev, dt = np.array([0.45, 0.0]), np.array([0.3, 0.0]), 0.01
    qd_ff = np.array([0.9, 0.0])  # drives joint 0 into its upper limit
    r = QP(damping=0.05).solve(np.eye(2), np.zeros(2), limits=lim, q=q, qd_prev=qd_prev, dt=dt,
                               qd_ff=qd_ff)
    total = r.qd + qd_ff
    vb = joint_velocity_bounds(lim, q=q, qd_prev=qd_prev, dt=dt)
    assert not vb.conflicts
    assert _in_box(total, vb.lower, vb.upper)
    assert abs(total[0] - qd_prev[0]) <= 2.0 * dt * (1 + 1e-6)
    assert q[0] + total[0] * dt <= 0.5 + 1e-9


# 7. Limits are validated; a NaN q never drops the position bounds
@pytest.mark.parametrize("kw", [dict(vmax=[np.nan]), dict(vmax=[-1.0]), dict(amax=[0.0]),
                                dict(lower=[2.0], upper=[1.0]), dict(lower=[np.nan]),
                                dict(lower=[INF]), dict(upper=[-INF]), dict(vmax=[1j])])
def test_limits_are_validated(kw):
    base = dict(lower=[0.0], upper=[1.0], vmax=[1.0], amax=[1.0])
    base.update(kw)
    with pytest.raises(InputError):
        Limits(**base)


def test_qp_refuses_a_nan_q():
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1, 1])
    with pytest.raises(InputError, match="q"):
        QP().solve(np.eye(2), np.ones(2), limits=lim, q=np.array([np.nan, 0.0]), dt=0.01)


# 8. ill-conditioned task weights: the default backend's answer is certified optimal
def test_qp_ill_conditioned_weights_equal_the_exact_answer(rng):
    arm = rc.robots.ur5e()
    lim = arm
    for _ in range(30):
        q = arm.random_q(rng=rng)
        J = arm.jacobian(q)
        xi = rng.standard_normal(6)
        kw = dict(limits=lim, q=q, qd_prev=rng.uniform(-1, 1, 6), dt=0.01)
        a = QP(task_weights=[1e6, 1, 1, 1, 1, 1]).solve(J, xi, **kw)
        b = QP(task_weights=[1e6, 1, 1, 1, 1, 1], backend="daqp").solve(J, xi, **kw)
        w = np.array([1e6, 1, 1, 1, 1, 1])
        P = J.T @ (w[:, None] * J) + 0.05**2 * np.eye(6)
        bb = J.T @ (w * xi)
        fa, fb = (0.5 * x @ P @ x - bb @ x for x in (a.qd, b.qd))
        assert fa <= fb + 1e-9 * (1 + abs(fb))


# 9. an axis with huge components is normalised after scaling
def test_urdf_huge_axis_is_scaled_before_normalising():
    doc = ('<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
           '<parent link="a"/><child link="b"/><axis xyz="1e300 1e300 0"/></joint></robot>')
    chain = rc.Chain.from_urdf(doc)
    z = chain.joint_axes(np.zeros(1))[0][0]
    assert np.allclose(z, [math.sqrt(0.5), math.sqrt(0.5), 0.0])


# 10. non-finite output without an error
def test_non_finite_outputs_are_errors(capfd):
    with pytest.raises(InputError):
        rc.solvers.DLS().solve(np.eye(6) * 1e154, np.ones(6))
    with pytest.raises(InputError, match="prismatic"):
        rc.robots.stanford().fk(np.full(6, 1e308))
    with pytest.raises(InputError, match="finite"):
        rc.manipulability(np.full((6, 6), np.nan))
    with pytest.raises(InputError):
        rc.singular_values(np.full((6, 6), np.nan))
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # LAPACK never sees the NaN, so it prints nothing


# 11. garbage accepted (the solver and model parts)
def test_random_q_margin_beyond_half_the_range_is_refused():
    with pytest.raises(InputError, match="half the range"):
        rc.robots.ur5e().random_q(margin=100.0)


def test_complex_q_is_refused():
    arm = rc.robots.ur5e()
    for q in (np.zeros(6) + 1j, [0j] * 6, list(np.zeros(6, dtype=complex))):
        with pytest.raises(InputError):
            arm.fk(q)


def test_sdls_with_joint_weights_stays_below_gamma_max():
    s = rc.solvers.SDLS(gamma_max=0.1, joint_weights=[1e-4] * 6)
    r = s.solve(np.eye(6) * 1e-3, np.ones(6))
    assert np.max(np.abs(r.qd)) <= 0.1 * (1 + 1e-12)


# 13. MJCF include bomb: refused quickly
def test_mjcf_include_bomb_is_refused_quickly(tmp_path):
    for i in range(9):
        inc = "".join(f'<include file="f{i + 1}.xml"/>' for _ in range(10)) if i < 8 else "<body/>"
        (tmp_path / f"f{i}.xml").write_text(f"<mujoco>{inc}</mujoco>")
    t0 = time.perf_counter()
    with pytest.raises(ImportModelError, match="include"):
        rc.Chain.from_mjcf(tmp_path / "f0.xml")
    assert time.perf_counter() - t0 < 5.0


# 14. the work of a loop over a path is bounded up front
def test_path_work_is_bounded_up_front():
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.5, 1.5, -1.5, -1.5, 0.0])
    T0 = arm.fk(q0)
    T1 = T0.copy()
    T1[0, 3] += 0.1
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="steps"):
        rc.follow(arm, rc.paths.Line(T0, T1, speed=1e-6, acceleration=1.0), q0, dt=0.01)
    with pytest.raises(InputError, match="steps"):
        rc.follow(arm, rc.paths.Line(T0, T1, speed=0.1, acceleration=1.0), q0, dt=1e-9)
    with pytest.raises(InputError, match="steps"):
        rc.paths.Line(T0, T1, speed=0.1, acceleration=1.0).sample(1e-12)
    assert time.perf_counter() - t0 < 2.0


def test_long_chain_first_fk_is_fast():
    chain = rc.Chain.from_dh([rc.DH(a=0.01, alpha=0.1) for _ in range(500)])
    t0 = time.perf_counter()
    T = chain.fk(np.zeros(500))
    J = chain.jacobian(np.zeros(500))
    assert time.perf_counter() - t0 < 0.5  # generated code would take ~0.4 s per kernel
    assert np.all(np.isfinite(T)) and J.shape == (6, 500)


# 15. a UTF-16 DOCTYPE/ENTITY document is refused
@pytest.mark.parametrize("enc", ["utf-16", "utf-16-le", "utf-16-be", "utf-32", "utf-8-sig"])
def test_encoded_doctype_is_refused(enc):
    doc = ('<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE r [<!ENTITY a "aaaa">]>\n'
           '<robot name="&a;"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
           '<parent link="a"/><child link="b"/></joint></robot>')
    with pytest.raises(ImportModelError, match="DOCTYPE"):
        rc.Chain.from_urdf(doc.encode(enc))


# 16. file attributes are never handed to MuJoCo
def test_mjcf_flexcomp_file_is_not_opened(tmp_path):
    doc = ('<mujoco><worldbody><flexcomp name="f" type="mesh" file="/outside/x.obj" dim="2"/>'
           '<body name="b"><joint type="hinge"/><geom size=".1"/></body></worldbody></mujoco>')
    (tmp_path / "m.xml").write_text(doc)
    assert rc.Chain.from_mjcf(tmp_path / "m.xml").dof == 1


# 17. OSQP's own exception never escapes
@pytest.mark.parametrize("case", ["max_iter0", "h_minus_inf", "negative_vmax", "huge_J"])
def test_osqp_exceptions_become_ratectl_errors(case):
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1, 1])
    kw = dict(limits=lim, q=np.zeros(2), dt=0.01)
    J = np.eye(2)
    solver = QP(shortcut=False)
    if case == "max_iter0":
        solver = QP(shortcut=False, settings={"max_iter": 0})
        kw["extra_inequalities"] = (np.ones((1, 2)), [0.5])
    elif case == "h_minus_inf":
        kw["extra_inequalities"] = (np.ones((1, 2)), [-INF])
    elif case == "negative_vmax":
        with pytest.raises(InputError):
            Limits(lower=[-1, -1], upper=[1, 1], vmax=[-1, 1], amax=[1, 1])
        return
    else:
        J = np.eye(2) * 1e150
    with pytest.raises(RatectlError):
        solver.solve(J, np.ones(2), **kw)


# 18. J = 1e300 with a tiny amax
def test_qp_huge_J_tiny_amax_is_a_ratectl_error():
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1e-300, 1e-300])
    for J in (np.eye(2) * 1e300, np.eye(2)):
        with pytest.raises(InputError):
            QP().solve(J, np.ones(2), limits=lim, q=np.zeros(2), qd_prev=np.zeros(2), dt=1e-9)
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1e-280, 1e-280])
    r = QP().solve(np.eye(2), np.ones(2), limits=lim, q=np.zeros(2), qd_prev=np.zeros(2), dt=0.01)
    assert np.all(np.isfinite(r.qd)) and np.all(np.abs(r.qd) <= 1e-282 * (1 + 1e-6))


# 19. deeply nested MJCF bodies
def test_mjcf_deep_nesting_is_an_import_error():
    body = "".join(f'<body name="b{i}"><joint type="hinge"/><geom size="0.01"/>' for i in range(1000))
    doc = f"<mujoco><worldbody>{body}{'</body>' * 1000}</worldbody></mujoco>"
    with pytest.raises(ImportModelError, match="nested"):
        rc.Chain.from_mjcf(doc)


# 20. analyze for absurd reach or q
def test_analyze_absurd_reach_and_q():
    with pytest.raises(ModelError, match="metres"):
        rc.Chain.from_dh([rc.DH(a=1e154)] * 6)
    big = rc.Chain.from_dh([rc.DH(a=1e9, alpha=1.0, d=1e9) for _ in range(6)])
    assert rc.analyze(big, np.full(6, 1e300)).kind in rc.singularity.KINDS
    stan = rc.robots.stanford()
    with pytest.raises(InputError):
        rc.analyze(stan, np.full(6, 1e300))


# 21. raw ValueError/TypeError/IndexError/MemoryError
@pytest.mark.parametrize("call", [
    lambda: rc.solvers.DLS().solve(np.zeros((0, 0)), np.zeros(0)),
    lambda: rc.solvers.QP().solve(np.zeros((6, 0)), np.zeros(6)),
    lambda: rc.solvers.DLS().solve("abc", [1]),
    lambda: rc.solvers.DLS(damping="0.1"),
    lambda: rc.robots.ur5e().fk("abc"),
    lambda: rc.paths.Line(np.eye(4), np.eye(4), speed="fast", acceleration=1.0),
    lambda: rc.manipulability("abc"),
])
def test_malformed_arguments_are_input_errors(call):
    with pytest.raises(InputError):
        call()


# 23-24. messages
def test_zero_length_path_message_names_the_path():
    arm = rc.robots.ur5e()
    q0 = np.array([0.0, -1.5, 1.5, -1.5, -1.5, 0.0])
    T0 = arm.fk(q0)
    with pytest.raises(InputError, match="zero length"):
        rc.follow(arm, rc.paths.Line(T0, T0, speed=0.1, acceleration=1.0), q0, dt=0.01)


def test_huge_lengths_message_names_the_length_not_a_derived_quantity():
    with pytest.raises(ModelError) as info:
        rc.Chain.from_dh([rc.DH(d=1e154)])
    assert "1e+154" in str(info.value) and "characteristic_length" not in str(info.value)


def test_urdf_without_links_is_not_called_a_cycle():
    with pytest.raises(ImportModelError, match="no <link>"):
        rc.Chain.from_urdf('<robot name="x"></robot>')


def test_xml_text_with_a_bom_is_parsed_not_looked_up_as_a_file():
    doc = ('\ufeff<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
           '<parent link="a"/><child link="b"/></joint></robot>')
    assert rc.Chain.from_urdf(doc).dof == 1


def test_solver_errors_carry_the_problem():
    s = QP(shortcut=False, settings={"max_iter": 1, "polishing": False})
    lim = Limits(lower=[-1, -1], upper=[1, 1], vmax=[1, 1], amax=[1, 1])
    with pytest.raises(SolverError) as info:
        s.solve(np.array([[1.0, 2.0]]), np.ones(1), limits=lim, q=np.zeros(2), dt=0.01,
                extra_inequalities=(np.array([[1.0, 1.0]]), [-0.5]))
    assert info.value.problem is not None
