"""Threads evaluating batched kernels at once give exactly the serial answers."""

import threading

import numpy as np

import ratectl as rc


def _run_threads(jobs):
    results = [None] * len(jobs)
    errors = []
    start = threading.Barrier(len(jobs))

    def work(k, chain, q):
        try:
            start.wait()
            out = []
            for _ in range(3):
                T, J = chain.fk_jacobian(q)
                out.append((T, J, chain.jacobian(q), chain.fk(q)))
            results[k] = out
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(k, c, q)) for k, (c, q) in enumerate(jobs)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    return results


def _check(jobs, results):
    for (chain, q), out in zip(jobs, results, strict=True):
        T, J = chain.fk_jacobian(q)  # serial
        for Tt, Jt, Jj, Tf in out:
            assert np.array_equal(Tt, T) and np.array_equal(Jt, J)
            assert np.array_equal(Jj, J) and np.array_equal(Tf, T)


def test_threads_on_different_chains_match_serial():
    rng = np.random.default_rng(11)
    chains = [rc.robots.ur5e(), rc.robots.iiwa7(), rc.robots.planar2r(), rc.robots.ur5e()]
    jobs = [(c, c.random_q(int(B), rng=rng)) for c, B in zip(chains, (20000, 9001, 3, 12345), strict=True)]
    _check(jobs, _run_threads(jobs))


def test_threads_on_one_chain_match_serial():
    rng = np.random.default_rng(12)
    arm = rc.robots.ur5e()
    # different batch sizes force different work arrays and chunk tails in each thread
    jobs = [(arm, arm.random_q(B, rng=rng)) for B in (15000, 15000, 777, 1)]
    _check(jobs, _run_threads(jobs))
