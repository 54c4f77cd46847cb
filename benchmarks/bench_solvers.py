"""Inverse-velocity speed: fk + Jacobian + solver for one UR5e configuration.

Run:  python benchmarks/bench_solvers.py [--quick]

Prints the median µs per control step (``chain.fk_jacobian(q)`` followed by
``solver.solve(J, xi, ...)``) for every solver; the QP with velocity and position
limits when no limit binds (the unconstrained shortcut answers) and when the velocity
limit binds (the default certified active-set step, warm OSQP with the shortcut off,
daqp through qpsolvers); and, for scale, Pinocchio's Jacobian plus a plain numpy DLS
and mink's ``solve_ik`` when those are installed. Results of the solvers are
cross-checked against numpy, OSQP and daqp before timing. Pin to one core for the
"one core" figures: ``taskset -c 0 python benchmarks/bench_solvers.py``.

Targets (issue #4): fk + J + fixed-λ DLS ≤ 12 µs; + adaptive DLS ≤ 25 µs;
+ QP with velocity and position limits on the default backend ≤ 30 µs.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import median_us  # noqa: E402

import ratectl as rc  # noqa: E402
from ratectl import solvers as S  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    args = parser.parse_args(argv)
    number, repeat = (200, 3) if args.quick else (2000, 15)

    ur = rc.robots.ur5e()
    q = np.array([0.3, -1.2, 1.5, -1.9, -1.4, 0.6])  # a regular configuration (σ_min ≈ 0.1)
    xi = np.array([0.05, -0.02, 0.03, 0.1, -0.05, 0.2])  # a modest twist: no limit binds
    xi_fast = 20.0 * xi  # needs more than vmax: the velocity limit binds
    T, J = ur.fk_jacobian(q)
    exact = np.linalg.solve(J, xi)
    lam = 0.05
    dls_ref = J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(6), xi)

    rows = []

    def row(name, fn, check=None):
        if check is not None:
            check()
        rows.append((name, median_us(fn, number=number, repeat=repeat)))

    fkj = ur.fk_jacobian
    row("fk_jacobian alone", lambda: fkj(q))

    def step(solver, twist, **kw):
        return lambda: solver.solve(fkj(q)[1], twist, **kw)

    dls = S.DLS(damping=lam)
    row("fk + J + DLS (fixed λ)", step(dls, xi),
        lambda: _close(dls.solve(J, xi).qd, dls_ref, 1e-12, "DLS"))
    ad = S.AdaptiveDLS(epsilon=0.05, max_damping=0.05)
    row("fk + J + AdaptiveDLS (σ schedule)", step(ad, xi),
        lambda: _close(ad.solve(J, xi).qd, exact, 1e-9, "AdaptiveDLS"))
    fd = S.AdaptiveDLS(epsilon=0.05, max_damping=0.05, mode="filtered")
    row("fk + J + AdaptiveDLS (filtered)", step(fd, xi),
        lambda: _close(fd.solve(J, xi).qd, exact, 1e-9, "filtered"))
    md = S.AdaptiveDLS(max_damping=0.05, mode="manipulability", manipulability_threshold=1e-4)
    row("fk + J + AdaptiveDLS (manipulability)", step(md, xi))
    row("fk + J + Inverse", step(S.Inverse(), xi))
    row("fk + J + PseudoInverse", step(S.PseudoInverse(), xi))
    row("fk + J + SDLS", step(S.SDLS(characteristic_length=ur.characteristic_length), xi))
    row("fk + J + DLS + velocity policy (limits=chain)", step(dls, xi, limits=ur))

    qp = S.QP(damping=lam)
    kw = dict(limits=ur, q=q, dt=0.002)

    def qp_check():
        r = qp.solve(J, xi, **kw)
        assert r.info["status"] == "unconstrained" and r.limits_active == ()
        _close(r.qd, dls_ref, 1e-12, "QP")

    row("fk + J + QP vel+pos limits, none binding (osqp)", step(qp, xi, **kw), qp_check)

    qp_osqp = S.QP(damping=lam, shortcut=False)

    def qp_active_check():
        r = qp.solve(J, xi_fast, **kw)
        assert r.info["status"] == "active-set" and "velocity" in r.limits_active, r.info
        o = qp_osqp.solve(J, xi_fast, **kw)
        assert o.info["status"] == "solved", o.info
        _close(r.qd, o.qd, 1e-9, "QP active-set vs warm OSQP")
        if "daqp" in __import__("qpsolvers").available_solvers:
            d = S.QP(damping=lam, backend="daqp").solve(J, xi_fast, **kw)
            _close(r.qd, d.qd, 1e-9, "QP active-set vs daqp")

    row("fk + J + QP vel+pos limits, velocity binding (default: active set)",
        step(qp, xi_fast, **kw), qp_active_check)
    row("fk + J + QP vel+pos limits, velocity binding (warm osqp, shortcut=False)",
        step(qp_osqp, xi_fast, **kw))
    kw_acc = dict(kw, qd_prev=qp.solve(J, xi, **kw).qd)
    row("fk + J + QP vel+pos+acc limits, none binding (osqp)", step(qp, xi, **kw_acc))
    import qpsolvers

    if "daqp" in qpsolvers.available_solvers:
        qd_ = S.QP(damping=lam, backend="daqp")
        row("fk + J + QP vel+pos limits, velocity binding (daqp via qpsolvers)",
            step(qd_, xi_fast, **kw))

    try:
        import pinocchio as pin
        from bench_kinematics import pinocchio_model
    except ImportError:
        pin = None
    if pin is not None:
        model, data, fid = pinocchio_model(ur)
        ref = pin.LOCAL_WORLD_ALIGNED
        I6 = lam**2 * np.eye(6)

        def pin_dls():
            Jp = pin.computeFrameJacobian(model, data, q, fid, ref)
            pin.updateFramePlacement(model, data, fid)
            return Jp.T @ np.linalg.solve(Jp @ Jp.T + I6, xi)

        _close(pin_dls(), dls_ref, 1e-10, "pinocchio DLS")
        row("peer: Pinocchio J + numpy DLS (no result object)", pin_dls)

    for name, fn in _mink_rows(ur, q, xi_fast):
        rows.append((name, median_us(fn, number=max(number // 10, 20), repeat=repeat)))

    width = max(len(n) for n, _ in rows)
    print(f"UR5e, one configuration; median of {repeat} rounds × {number} calls")
    for name, us in rows:
        print(f"  {name:<{width}}  {us:8.2f} µs")
    return 0


def _mink_rows(ur, q, xi):
    """mink's ``solve_ik`` on the same arm (exported with ``to_mjcf``), a frame task at the
    tool site with velocity and configuration limits, for scale: one call per step, as a
    mink user's loop makes it. Skipped when mink or mujoco is missing."""
    try:
        import mink
        import mujoco
        import qpsolvers

        from ratectl.interop.mujoco import to_mjcf
    except ImportError:
        return []
    model = mujoco.MjModel.from_xml_string(to_mjcf(ur))
    conf = mink.Configuration(model)
    conf.update(q)
    task = mink.FrameTask("tool", "site", position_cost=1.0, orientation_cost=1.0)
    T = ur.fk(q)
    # a target one step of the twist ahead: mink resolves the same motion
    target = T.copy()
    target[:3, 3] += xi[:3] * 0.002
    task.set_target(mink.SE3.from_matrix(target))
    names = [model.joint(i).name for i in range(model.njnt)]
    limits = [mink.ConfigurationLimit(model),
              mink.VelocityLimit(model, {nm: float(v) for nm, v in zip(names, ur.vmax, strict=True)})]
    out = []
    for backend in ("daqp", "osqp"):
        if backend not in qpsolvers.available_solvers:
            continue
        mink.solve_ik(conf, [task], 0.002, backend, damping=1e-3, limits=limits)
        out.append((f"peer: mink solve_ik ({backend}, vel+pos limits)",
                    lambda b=backend: mink.solve_ik(conf, [task], 0.002, b, damping=1e-3,
                                                    limits=limits)))
    return out


def _close(a, b, tol, what):
    err = float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
    if err > tol:
        raise AssertionError(f"{what}: result differs from the reference by {err:.3g}")


if __name__ == "__main__":
    raise SystemExit(main())
