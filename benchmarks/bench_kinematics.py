"""Kinematics speed: fk + Jacobian for one configuration, and batched Jacobians.

Run:  python benchmarks/bench_kinematics.py [--quick] [--clock cpu|wall] [--rounds R]
                                           [--markdown | --update-docs]

Prints, for each built-in arm, the median µs per call of ``fk_jacobian`` (one
combined call) and of ``fk`` + ``jacobian`` (two calls), and configurations per
second of batched ``jacobian`` at B = 10^4 and 10^5. When Pinocchio,
roboticstoolbox-python or MuJoCo are installed, the same work is measured with
them in the same run (same arm, results cross-checked) and ratios are printed:

* the UR5e: ``fk_jacobian`` of one configuration beside Pinocchio's
  ``computeFrameJacobian`` + ``updateFramePlacement`` (ratio of times), and batched
  ``fk_jacobian(Q)``, Q of shape (B, 6), beside a Python loop of the same Pinocchio calls
  (ratio of configurations per second), B = 10^4 and 10^5;
* cost growth with the number of joints: random standard-DH chains of 3, 6, 7, 12 and
  24 revolute joints (seeded), the same chain built in Pinocchio from its joint
  placements, single and batched (B = 10^4), as ratios.

The UR5e comparison runs ``--rounds`` times (default 5) and reports the best and the
median ratio. ``--markdown`` prints both tables as markdown; ``--update-docs`` also
writes them into docs/benchmarks.md, between the ``bench_kinematics.py --update-docs``
markers, with the date, the machine and the load.

Times are this thread's CPU time by default (``--clock cpu``): on a shared machine it
leaves out the time other processes hold the core. Pin to one core for the "one core"
figures: ``taskset -c 0 python ...``.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import machine, median_s, median_us, update_docs  # noqa: E402

import ratectl as rc  # noqa: E402


def pinocchio_model(chain):
    """The same chain as a Pinocchio model: joint placement = post_{i-1} · pre_i, tool frame."""
    import pinocchio as pin

    model = pin.Model()
    parent = 0
    carry = chain.base.copy()
    for k, joint in enumerate(chain.joints):
        M = carry @ joint.pre
        jm = pin.JointModelRZ() if joint.kind == "revolute" else pin.JointModelPZ()
        parent = model.addJoint(parent, jm, pin.SE3(M[:3, :3], M[:3, 3]), f"j{k}")
        model.appendBodyToJoint(parent, pin.Inertia.Random(), pin.SE3.Identity())
        carry = joint.post
    T = carry @ chain.tool
    fid = model.addFrame(pin.Frame("tool", parent, 0, pin.SE3(T[:3, :3], T[:3, 3]), pin.FrameType.OP_FRAME))
    return model, model.createData(), fid


def random_dh_chain(n: int, seed: int = 0):
    """A random standard-DH chain of n revolute joints: a, d uniform in ±0.4 m, twists
    from {0, ±π/2} or uniform, offsets uniform in ±1 rad."""
    rng = np.random.default_rng(seed + 1000 * n)
    rows = []
    for _ in range(n):
        alpha = rng.choice([0.0, np.pi / 2, -np.pi / 2, rng.uniform(-np.pi, np.pi)])
        rows.append(rc.DH(a=rng.uniform(-0.4, 0.4), alpha=float(alpha), d=rng.uniform(-0.4, 0.4),
                          theta=rng.uniform(-1, 1), qlim=(-np.pi, np.pi)))
    return rc.Chain.from_dh(rows, name=f"random DH {n}")


def pinocchio_pair(chain, clock: str, B: int, rng, number: int):
    """(ratectl µs, Pinocchio µs, ratectl batched /s, Pinocchio loop /s) for fk + J."""
    import pinocchio as pin

    model, data, fid = pinocchio_model(chain)
    ref = pin.LOCAL_WORLD_ALIGNED

    def one(qq):
        J = pin.computeFrameJacobian(model, data, qq, fid, ref)  # runs forward kinematics
        pin.updateFramePlacement(model, data, fid)
        return data.oMf[fid].homogeneous, J

    q = chain.random_q(rng=rng)
    T, J = one(q)
    T0, J0 = chain.fk_jacobian(q)
    assert np.allclose(T, T0, atol=1e-10) and np.allclose(J, J0, atol=1e-10), "pinocchio disagrees"
    qs = chain.random_q(B, rng=rng)
    Tb, Jb = chain.fk_jacobian(qs)
    for i in (0, B // 2, B - 1):
        T, J = one(qs[i])
        assert np.allclose(T, Tb[i], atol=1e-10) and np.allclose(J, Jb[i], atol=1e-10)

    def loop():
        for row in qs:
            pin.computeFrameJacobian(model, data, row, fid, ref)
            pin.updateFramePlacement(model, data, fid)

    pin_us = median_us(lambda: one(q), number=number, clock=clock)
    ours_us = median_us(lambda: chain.fk_jacobian(q), number=number, clock=clock)
    pin_us = 0.5 * (pin_us + median_us(lambda: one(q), number=number, clock=clock))
    loop_rate = B / median_s(loop, repeat=3, clock=clock)
    ours_rate = B / median_s(lambda: chain.fk_jacobian(qs), repeat=7, clock=clock)
    loop_rate = 0.5 * (loop_rate + B / median_s(loop, repeat=3, clock=clock))
    return ours_us, pin_us, ours_rate, loop_rate


def headline(clock: str, quick: bool, rng, rounds: int) -> dict:
    """UR5e: single and batched fk_jacobian beside Pinocchio, as ratios, ``rounds`` times.

    Returns {B: [(ratectl M/s, Pinocchio-loop M/s, batched ratio, single ratio), ...]}.
    """
    chain = rc.robots.ur5e()
    print("\nUR5e fk_jacobian beside Pinocchio (computeFrameJacobian + updateFramePlacement):")
    runs: dict = {}
    for k in range(rounds):
        for B in (10_000,) if quick else (10_000, 100_000):
            us, pus, rate, prate = pinocchio_pair(chain, clock, B, rng, 500 if quick else 3000)
            runs.setdefault(B, []).append((rate / 1e6, prate / 1e6, rate / prate, us / pus))
            print(f"  round {k + 1} B = {B:6d}: batched {rate / 1e6:6.2f} M configs/s, Pinocchio loop "
                  f"{prate / 1e6:5.3f} M/s -> {rate / prate:5.1f}x the loop | one configuration "
                  f"{us:5.2f} µs vs {pus:5.2f} µs -> {us / pus:4.2f}x Pinocchio's time")
    for B, rows in runs.items():
        r = np.array(rows)
        print(f"  B = {B:6d} over {len(rows)} rounds: batched/loop best {r[:, 2].max():.1f}x, median "
              f"{np.median(r[:, 2]):.1f}x; one configuration best {r[:, 3].min():.2f}x, median "
              f"{np.median(r[:, 3]):.2f}x Pinocchio's time")
    return runs


def growth(clock: str, quick: bool, rng) -> list:
    """Cost growth with the number of joints, ratectl beside Pinocchio (ratios)."""
    B = 10_000
    rows = []
    print(f"\ncost growth with the number of joints (random standard-DH chains, batched B = {B}):")
    print(f"{'joints':>6s} {'single: ratectl/pin time':>25s} {'batched: ratectl/pin-loop speed':>32s}"
          f" {'ratectl µs':>11s} {'pin µs':>7s} {'ratectl M/s':>12s} {'pin loop M/s':>13s}")
    for n in (3, 6, 7, 12, 24):
        chain = random_dh_chain(n)
        us, pus, rate, prate = pinocchio_pair(chain, clock, B, rng, 300 if quick else 2000)
        rows.append((n, us / pus, rate / prate, us, pus, rate, prate))
        print(f"{n:6d} {us / pus:25.2f} {rate / prate:32.1f} {us:11.2f} {pus:7.2f} "
              f"{rate / 1e6:12.2f} {prate / 1e6:13.3f}")
    return rows


def markdown(runs: dict, rows: list, clock: str) -> str:
    """The measured tables as the markdown block of docs/benchmarks.md."""
    import pinocchio

    where = machine()[:-1]  # "date (cpu, cores, load; Python x" without its closing parenthesis
    out = [f"Measured by `benchmarks/bench_kinematics.py` on {where}; numpy {np.__version__}, "
           f"pinocchio {pinocchio.__version__}; {clock} clock):", "",
           "| UR5e `fk_jacobian` | rounds | ratectl | Pinocchio | ratio: best | ratio: median |",
           "|---|---|---|---|---|---|"]
    for B, rs in runs.items():
        r = np.array(rs)
        out.append(f"| batched, B = {B:,} [M configurations/s] | {len(rs)} | {r[:, 0].min():.2f}–"
                   f"{r[:, 0].max():.2f} | {r[:, 1].min():.2f}–{r[:, 1].max():.2f} (loop) | "
                   f"{r[:, 2].max():.1f} × the loop | {np.median(r[:, 2]):.1f} × the loop |")
    r = np.array([x for rs in runs.values() for x in rs])
    out.append(f"| one configuration [time ratio] | {len(r)} | | | {r[:, 3].min():.2f} × "
               f"Pinocchio's time | {np.median(r[:, 3]):.2f} × Pinocchio's time |")
    out += ["", "Cost growth with the number of joints — random standard-DH chains with random "
            "twists and offsets (seeded), the same chain built in Pinocchio from its joint "
            "placements:", "",
            "| joints | one configuration: ratectl / Pinocchio time | batched (B = 10⁴): "
            "ratectl / Pinocchio-loop speed | ratectl batched [M/s] | Pinocchio loop [M/s] |",
            "|---|---|---|---|---|"]
    for n, r1, r2, _us, _pus, rate, prate in rows:
        out.append(f"| {n} | {r1:.2f}× | {r2:.1f}× | {rate / 1e6:.2f} | {prate / 1e6:.2f} |")
    return "\n".join(out) + "\n"


def profile(clock: str) -> None:
    """Where the batched UR5e fk_jacobian time goes, ns per configuration (B = 10^5), and
    throughput at B = 10^4, 10^5, 10^6 (chunking against cache sizes)."""
    from ratectl.kinematics import codegen, forward

    chain = rc.robots.ur5e()
    rng = np.random.default_rng(1)
    print("\nUR5e batched fk_jacobian throughput by batch size (best of 3 medians):")
    for B in (10_000, 100_000, 1_000_000):
        qs = chain.random_q(B, rng=rng)
        best = min(median_s(lambda: chain.fk_jacobian(qs), repeat=3 if B > 100_000 else 7, clock=clock)
                   for _ in range(3))
        print(f"  B = {B:9,d}: {B / best / 1e6:6.2f} M configurations/s, {best / B * 1e9:5.0f} ns each")
    B = 100_000
    qs = chain.random_q(B, rng=rng)
    kern = forward.build_kernel(chain, ("fkjac", True))
    m = forward._chunk(52, kern.__nwork__)
    W = np.empty((kern.__nwork__, m))
    kern.__prepare__(W)
    rows_of_W = tuple(W)
    qT, T, J, chunks = qs[:m].T, np.empty((B, 16)), np.empty((B, 36)), B // m

    def kernel_only():
        for _ in range(chunks):
            kern(qT, W, rows_of_W)

    def sincos_only():
        for _ in range(chunks):
            codegen.sincos(qT, None, W[52:], 6)

    def copies_only():
        for i in range(chunks):
            np.copyto(T[i * m:(i + 1) * m], W[:16].T)
            np.copyto(J[i * m:(i + 1) * m], W[16:52].T)

    rows = []
    for _ in range(5):
        total = median_s(lambda: chain.fk_jacobian(qs), clock=clock) / B
        kern_s, sc_s, cp_s = (median_s(f, clock=clock) / (chunks * m)
                              for f in (kernel_only, sincos_only, copies_only))
        rows.append((total, sc_s, kern_s - sc_s, cp_s, total - kern_s - cp_s))
    r = np.median(np.array(rows), axis=0) * 1e9
    lines = kern.__source__.split("def kernel")[1].count("\n") - 3
    print(f"where the time goes at B = {B:,} ({m}-column chunks, {kern.__nwork__} work rows, "
          f"{lines} kernel lines), ns per configuration, median of 5:")
    for name, v in zip(("total", "sin/cos (sincos)", "kernel arithmetic", "transposing copies into the "
                        "result", "rest (checks, allocation, chunk loop)"), r, strict=True):
        print(f"  {name:40s} {v:6.1f}")


def bench_pinocchio(chain, q, qs):
    import pinocchio as pin

    model, data, fid = pinocchio_model(chain)
    ref = pin.LOCAL_WORLD_ALIGNED

    def one(qq):
        J = pin.computeFrameJacobian(model, data, qq, fid, ref)  # runs forward kinematics
        pin.updateFramePlacement(model, data, fid)
        return data.oMf[fid].homogeneous, J

    T, J = one(q)
    T0, J0 = chain.fk_jacobian(q)
    assert np.allclose(T, T0, atol=1e-10) and np.allclose(J, J0, atol=1e-10), "pinocchio disagrees"
    us = median_us(lambda: one(q))

    def loop():
        for row in qs:
            pin.computeFrameJacobian(model, data, row, fid, ref)

    return us, len(qs) / median_s(loop, repeat=3)


def bench_rtb(chain, q):
    import roboticstoolbox as rtb

    if chain.table is None:
        return None
    links = []
    for r in chain.table:
        if r.convention == "standard":
            cls = rtb.RevoluteDH if r.joint == "revolute" else rtb.PrismaticDH
        else:
            cls = rtb.RevoluteMDH if r.joint == "revolute" else rtb.PrismaticMDH
        kw = dict(a=r.a, alpha=r.alpha)
        kw.update(offset=r.theta, d=r.d) if r.joint == "revolute" else kw.update(theta=r.theta, offset=r.d)
        links.append(cls(**kw))
    robot = rtb.DHRobot(links, tool=chain.tool)
    T = np.asarray(robot.fkine(q))
    J = robot.jacob0(q)
    T0, J0 = chain.fk_jacobian(q)
    assert np.allclose(T, T0, atol=1e-9) and np.allclose(J, J0, atol=1e-9), "rtb disagrees"
    dh_us = median_us(lambda: (robot.fkine(q), robot.jacob0(q)), number=200, repeat=5)
    ets = robot.ets()
    ets_us = median_us(lambda: (ets.fkine(q), ets.jacob0(q)), number=2000, repeat=7)
    return dh_us, ets_us


def bench_mujoco(chain, q):
    try:
        import mujoco

        from ratectl.interop.mujoco import to_mjcf
    except Exception:  # noqa: BLE001 - optional
        return None
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    data = mujoco.MjData(model)
    sid = model.nsite - 1
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))

    def one():
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)  # mj_jacSite reads the motion axes (cdof) it computes
        mujoco.mj_jacSite(model, data, jacp, jacr, sid)

    one()
    J0 = chain.jacobian(q)
    T0 = chain.fk(q)
    if not (np.allclose(jacp, J0[:3], atol=1e-9) and np.allclose(jacr, J0[3:], atol=1e-9)
            and np.allclose(data.site_xpos[sid], T0[:3, 3], atol=1e-9)):
        raise AssertionError("MuJoCo's site Jacobian disagrees with ratectl's")
    return median_us(one)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, B = 10^4 only")
    ap.add_argument("--arms", default=",".join(k for k in rc.robots.BUILTIN if k != "planar2r"))
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu",
                    help="cpu: this thread's CPU time (default, steadier on a shared machine)")
    ap.add_argument("--markdown", action="store_true", help="print the Pinocchio tables as markdown")
    ap.add_argument("--update-docs", action="store_true",
                    help="write the Pinocchio tables into docs/benchmarks.md (implies --markdown)")
    ap.add_argument("--rounds", type=int, default=5,
                    help="repetitions of the UR5e comparison (best and median ratios)")
    ap.add_argument("--profile", action="store_true",
                    help="only: where the batched UR5e time goes, and throughput at B = 1e4..1e6")
    args = ap.parse_args(argv)
    if args.profile:
        profile(args.clock)
        return
    rng = np.random.default_rng(0)
    print(f"ratectl {rc.__version__}, numpy {np.__version__}, clock {args.clock}")
    try:
        import pinocchio  # noqa: F401
        have_pin = True
    except ImportError:
        have_pin = False
        print("pinocchio not installed: no ratios")
    if have_pin:
        runs = headline(args.clock, args.quick, rng, max(1, args.rounds))
        rows = growth(args.clock, args.quick, rng)
        if args.markdown or args.update_docs:
            text = markdown(runs, rows, args.clock)
            print("\n" + text)
            if args.update_docs:
                update_docs("bench_kinematics.py", text)
    print(f"{'arm':14s} {'fk_jacobian µs':>15s} {'fk+jacobian µs':>15s} "
          f"{'batch 1e4 /s':>13s} {'batch 1e5 /s':>13s}")
    sizes = (10_000,) if args.quick else (10_000, 100_000)
    for name in args.arms.split(","):
        chain = rc.robots.BUILTIN[name]()
        q = chain.random_q(rng=rng)
        n = 500 if args.quick else 5000
        one = median_us(lambda: chain.fk_jacobian(q), number=n)
        two = median_us(lambda: (chain.fk(q), chain.jacobian(q)), number=n)
        rates = []
        for B in sizes:
            qs = chain.random_q(B, rng=rng)
            rates.append(B / median_s(lambda: chain.jacobian(qs), repeat=3 if args.quick else 7))
        rates += [float("nan")] * (2 - len(rates))
        print(f"{chain.name:14s} {one:15.2f} {two:15.2f} {rates[0]:13.3e} {rates[1]:13.3e}")

    print("\npeers on the UR5e (same work, results cross-checked):")
    chain = rc.robots.ur5e()
    q = chain.random_q(rng=rng)
    ours = median_us(lambda: chain.fk_jacobian(q))
    qs = chain.random_q(100_000, rng=rng)
    ours_rate = 1e5 / median_s(lambda: chain.jacobian(qs), repeat=3 if args.quick else 7)
    print(f"  ratectl fk_jacobian        {ours:8.2f} µs   batched {ours_rate:.3e} configs/s")
    try:
        us, rate = bench_pinocchio(chain, q, qs[:20_000])
        print(f"  pinocchio frame Jacobian   {us:8.2f} µs   loop    {rate:.3e} configs/s "
              f"(ratectl/pinocchio time {ours / us:.2f}x, batch speed-up {ours_rate / rate:.1f}x)")
    except ImportError:
        print("  pinocchio not installed")
    try:
        res = bench_rtb(chain, q)
        if res:
            print(f"  rtb DHRobot fkine+jacob0   {res[0]:8.2f} µs   (ratectl {res[0] / ours:.0f}x faster)")
            print(f"  rtb ETS fkine+jacob0 (C)   {res[1]:8.2f} µs   (ratectl {res[1] / ours:.1f}x faster)")
    except ImportError:
        print("  roboticstoolbox-python not installed")
    mj = bench_mujoco(chain, q)
    if mj is not None:
        print(f"  mujoco kinematics+comPos+jacSite {mj:6.2f} µs (ratectl/mujoco time {ours / mj:.2f}x)")
    else:
        print("  mujoco comparison unavailable (needs ratectl.interop.mujoco.to_mjcf and mujoco)")


if __name__ == "__main__":
    main()
