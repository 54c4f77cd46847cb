"""Batched kinematics: equal to the looped single-configuration results, for odd batch
shapes, chunk boundaries, random DH chains (revolute and prismatic), the reference mode."""

import inspect
import os
import subprocess
import sys

import numpy as np
import pytest

import ratectl as rc
from ratectl.kinematics import forward, reference_fk_jacobian
from ratectl.kinematics.codegen import sincos

TOL = 1e-15  # absolute for entries of size ≤ 1 (metres, unit vectors); relative beyond


def random_chain(rng, n, *, modified=False, prismatic=0.25):
    """A random DH chain: twists from {0, ±π/2, π, random}, random offsets, some prismatic
    joints, random base and tool."""
    rows = []
    cls = rc.MDH if modified else rc.DH
    for _ in range(n):
        alpha = rng.choice([0.0, np.pi / 2, -np.pi / 2, np.pi, rng.uniform(-3, 3)])
        rows.append(cls(a=rng.choice([0.0, rng.uniform(-0.5, 0.5)]), alpha=float(alpha),
                        d=rng.choice([0.0, rng.uniform(-0.5, 0.5)]), theta=rng.uniform(-1, 1),
                        joint="prismatic" if rng.random() < prismatic else "revolute",
                        qlim=(-3.0, 3.0)))

    def pose():
        A = rng.normal(size=(3, 3))
        Qm, R = np.linalg.qr(A)
        Qm = Qm * np.sign(np.diag(R))
        if np.linalg.det(Qm) < 0:
            Qm[:, 0] = -Qm[:, 0]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Qm, rng.uniform(-0.3, 0.3, 3)
        return T

    make = rc.Chain.from_mdh if modified else rc.Chain.from_dh
    return make(rows, base=pose(), tool=pose(), name=f"random{n}")


def assert_matches_loop(chain, q):
    T, J = chain.fk_jacobian(q)
    Tf, Jj = chain.fk(q), chain.jacobian(q)
    shape = q.shape[:-1]
    assert T.shape == shape + (4, 4) and J.shape == shape + (6, chain.dof)
    for A in (T, J, Tf, Jj):
        assert A.flags.c_contiguous and A.flags.writeable and A.dtype == np.float64
    for idx in np.ndindex(*shape):
        t, j = chain.fk_jacobian(q[idx])
        scale = max(1.0, np.max(np.abs(t)), np.max(np.abs(j), initial=0.0))
        assert np.max(np.abs(T[idx] - t), initial=0.0) <= TOL * scale
        assert np.max(np.abs(J[idx] - j), initial=0.0) <= TOL * scale
        assert np.array_equal(Tf[idx], T[idx]) and np.array_equal(Jj[idx], J[idx])


@pytest.mark.parametrize("shape", [(0,), (1,), (1, 1), (2, 1, 3), (5,), (4, 0)])
@pytest.mark.parametrize("arm_name", ["ur5e", "iiwa7", "planar2r"])
def test_odd_batch_shapes(arm_name, shape, rng):
    arm = rc.robots.BUILTIN[arm_name]()
    assert_matches_loop(arm, arm.random_q(shape, rng=rng) if 0 not in shape
                        else np.zeros(shape + (arm.dof,)))


@pytest.mark.parametrize("m", [1, 3, 7, 64])
def test_every_chunk_boundary_with_tiny_chunks(m, rng, monkeypatch):
    monkeypatch.setattr(forward, "_chunk", lambda width, nwork: m)
    arm = rc.robots.ur5e()
    for B in (m - 1, m, m + 1, 3 * m + 2):
        if B > 0:
            assert_matches_loop(arm, arm.random_q(B, rng=rng))


def test_rows_at_the_real_chunk_boundaries(rng):
    arm = rc.robots.iiwa7()
    kern = arm.kernel_source("fkjac", batched=True)
    nwork = int(kern.split("NWORK = ")[1].split()[0])
    m = forward._chunk(16 + 6 * arm.dof, nwork)
    q = arm.random_q(2 * m + 5, rng=rng)
    T, J = arm.fk_jacobian(q)
    Jj = arm.jacobian(q)
    for i in (0, m - 1, m, m + 1, 2 * m - 1, 2 * m, 2 * m + 4):
        t, j = arm.fk_jacobian(q[i])
        assert np.max(np.abs(T[i] - t)) <= TOL and np.max(np.abs(J[i] - j)) <= TOL
        assert np.array_equal(Jj[i], J[i])


@pytest.mark.parametrize("seed", range(6))
def test_random_dh_chains_batched_equals_looped_and_reference(seed):
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 13))
    chain = random_chain(rng, n, modified=bool(seed % 2))
    q = rng.uniform(-3, 3, size=(37, n))
    assert_matches_loop(chain, q)
    T, J = chain.fk_jacobian(q)
    Tr, Jr = reference_fk_jacobian(chain, q)
    assert np.max(np.abs(T - Tr)) < 1e-12 and np.max(np.abs(J - Jr)) < 1e-12


def test_batched_sine_and_cosine_are_within_one_ulp_of_libm():
    rng = np.random.default_rng(3)
    q = np.concatenate([rng.uniform(-7, 7, 4000), rng.uniform(-2e4, 2e4, 1000),
                        np.arange(-16, 17) * np.pi / 8, [0.0, -0.0, 1e-300, 5e-324, 2e4, -2e4]])
    q = q[: q.size // 3 * 3].reshape(3, -1)
    for big in (False, True):  # beyond ±2e4 rad: numpy's own cos and sin
        x = q * 1e3 if big else q
        W = np.empty((21, x.shape[1]))
        sincos(x, None, W, 3)
        c, s = np.cos(x), np.sin(x)
        ulp = np.spacing(np.maximum(np.abs(c), np.abs(s)))
        assert np.all(np.abs(W[:3] - c) <= ulp) and np.all(np.abs(W[3:6] - s) <= ulp)
        if big:
            assert np.array_equal(W[:3], c) and np.array_equal(W[3:6], s)
        else:  # mostly the same bits as libm
            assert np.mean(W[:3] == c) > 0.9 and np.mean(W[3:6] == s) > 0.9


def test_non_contiguous_and_integer_inputs(rng):
    arm = rc.robots.ur5e()
    q = arm.random_q((9, 4), rng=rng)
    view = q.T[:, ::2].T  # strided rows
    assert_matches_loop(arm, view)
    Tq, Jq = arm.fk_jacobian(np.arange(12).reshape(2, 6) % 3)
    assert np.allclose(Jq[1], arm.jacobian(np.array([0.0, 1, 2, 0, 1, 2])), atol=TOL, rtol=0)


@pytest.mark.skipif(forward.KERNEL_MODE == "reference", reason="reference kernels are not generated")
def test_batched_kernel_source_is_registered_with_linecache():
    arm = rc.robots.ur5e()
    arm.fk_jacobian(arm.random_q(3))
    kern = forward.build_kernel(arm, ("fkjac", True))
    assert inspect.getsource(kern) in kern.__source__
    assert "multiply(" in arm.kernel_source("jac", batched=True)


def test_reference_mode_gives_the_same_batched_results(tmp_path):
    code = (
        "import numpy as np, ratectl as rc\n"
        "from ratectl.kinematics import KERNEL_MODE\n"
        "assert KERNEL_MODE == 'reference'\n"
        "arm = rc.robots.ur5e()\n"
        "q = arm.random_q((3, 5), rng=np.random.default_rng(7))\n"
        "T, J = arm.fk_jacobian(q)\n"
        "np.save(r'%s', np.concatenate([T.reshape(15, -1), J.reshape(15, -1), arm.jacobian(q)"
        ".reshape(15, -1), arm.fk(q).reshape(15, -1)], axis=1))\n" % (tmp_path / "ref.npy"))
    env = dict(os.environ, RATECTL_KERNELS="reference")
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=60)
    got = np.load(tmp_path / "ref.npy")
    arm = rc.robots.ur5e()
    q = arm.random_q((3, 5), rng=np.random.default_rng(7))
    T, J = arm.fk_jacobian(q)
    want = np.concatenate([T.reshape(15, -1), J.reshape(15, -1), J.reshape(15, -1),
                           T.reshape(15, -1)], axis=1)
    assert np.max(np.abs(got - want)) < 1e-12


def test_sign_rewrites_of_the_batched_kernels_are_exact():
    """`_signed` rewrites an expression to compute ±its value from operands stored with either
    sign; every rewrite must give the same bits (up to the sign of zero) as negating the
    value, for random expressions of the generated kinds and random operand values."""
    import ast

    from ratectl.kinematics.codegen import _signed

    rng = np.random.default_rng(21)
    names = ["a", "b", "c", "d"]
    forms = ["a*b + c*d", "a*b - c*d", "a - b*0.425", "0.1625 + a*-0.3922", "a*b*0.5 - c",
             "a - b", "a + b", "a*b", "a*0.0997", "a*b + c*d*-0.25 - d"]
    for text in forms:
        tree = ast.parse(text, mode="eval").body
        for _ in range(40):
            stored = {n: int(rng.choice([-1, 1])) for n in names}
            values = {n: float(rng.normal() * 10.0 ** rng.integers(-3, 3)) for n in names}
            want_value = eval(text, {}, values)  # noqa: S307 - test-only, fixed strings
            for want in (1, -1):
                rewritten = _signed(tree, want, stored)
                if rewritten is None:
                    continue
                env = {n: stored[n] * v for n, v in values.items()}
                got = eval(compile(ast.Expression(ast.fix_missing_locations(rewritten)), "<t>", "eval"),
                           {}, env)
                assert got == want * want_value, (text, want, stored, ast.unparse(rewritten))
            assert _signed(tree, 1, stored) is not None or _signed(tree, -1, stored) is not None


@pytest.mark.parametrize("nwork", [10, 55, 94, 172, 328, 2000])
def test_chunks_keep_work_rows_an_odd_number_of_cache_lines_apart(nwork):
    m = forward._chunk(52, nwork)
    assert m % 16 == 8 and m * 8 * nwork <= max(forward._CHUNK_BYTES, 8 * nwork * (forward._CHUNK_MIN + 8))
