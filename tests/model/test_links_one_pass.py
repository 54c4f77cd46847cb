"""`Chain.fk_jacobian_links`: several links' poses and Jacobians in one pass of the chain,
equal bit for bit to one `fk_jacobian(q, link=...)` call per link; `Chain.fk_rows_jacobian`:
the tool pose's first three rows as floats and the Jacobian, the numbers of ``fk`` and
``jacobian`` bit for bit."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import InputError

ROBOTS = {"panda": rc.robots.panda, "ur5e": rc.robots.ur5e, "stanford": rc.robots.stanford,
          "puma560": rc.robots.puma560}


@settings(max_examples=40, deadline=None)
@given(robot=st.sampled_from(sorted(ROBOTS)), seed=st.integers(0, 10_000), data=st.data())
def test_links_in_one_pass_equal_the_calls_one_link_at_a_time(robot, seed, data):
    chain = ROBOTS[robot]()
    names = [None, *chain.link_names]
    links = data.draw(st.lists(st.sampled_from(names), min_size=1, max_size=6))
    q = chain.random_q(rng=seed)
    got = chain.fk_jacobian_links(q, links)
    assert len(got) == len(links)
    for lk, (T, J) in zip(links, got, strict=True):
        T1, J1 = chain.fk_jacobian(q) if lk is None else chain.fk_jacobian(q, link=lk)
        assert T.shape == (4, 4) and J.shape == (6, chain.dof)
        assert np.array_equal(T, T1) and np.array_equal(J, J1), (robot, lk)


def test_a_link_on_the_base_is_computed_link_by_link():
    panda = rc.robots.panda()
    T4 = np.eye(4)
    T4[:3, 3] = [0.0, 0.1, 0.0]
    chain = rc.Chain(panda.joints, base=panda.base, tool=panda.tool, name="panda",
                     links=[("fixed", 0, np.eye(4)), ("elbow", 4, T4)])
    q = chain.random_q(rng=1)
    (T0, J0), (Te, Je), (Tt, Jt) = chain.fk_jacobian_links(q, ["fixed", "elbow", None])
    assert np.array_equal(T0, chain.fk(q, link="fixed")) and not J0.any()
    assert np.array_equal(Te, chain.fk(q, link="elbow"))
    assert np.array_equal(Je, chain.jacobian(q, link="elbow"))
    assert np.array_equal(Tt, chain.fk(q)) and np.array_equal(Jt, chain.jacobian(q))


def test_a_batch_and_a_list_fall_back_to_the_calls():
    chain = rc.robots.ur5e()
    qs = chain.random_q(3, rng=2)
    (T, J), = chain.fk_jacobian_links(qs, ["link3"])
    assert T.shape == (3, 4, 4) and J.shape == (3, 6, 6)
    assert np.array_equal(J, chain.jacobian(qs, link="link3"))
    (T1, J1), = chain.fk_jacobian_links(qs[0].tolist(), [None])
    assert np.array_equal(T1, chain.fk(qs[0]))


def test_an_unknown_link_names_the_links():
    chain = rc.robots.ur5e()
    with pytest.raises(rc.errors.InputError, match="link1"):
        chain.fk_jacobian_links(np.zeros(6), ["nope"])


@settings(max_examples=40, deadline=None)
@given(robot=st.sampled_from(sorted(ROBOTS)), seed=st.integers(0, 10_000), as_list=st.booleans())
def test_rows_and_jacobian_are_fk_and_jacobian(robot, seed, as_list):
    chain = ROBOTS[robot]()
    q = chain.random_q(rng=seed)
    rows, J = chain.fk_rows_jacobian(q.tolist() if as_list else q)
    T = chain.fk(q)
    assert len(rows) == 3
    assert [list(r) for r in rows] == T[:3].tolist()
    assert J.shape == (6, chain.dof) and np.array_equal(J, chain.jacobian(q))


def test_a_batch_is_refused():
    chain = rc.robots.panda()
    with pytest.raises(InputError, match="one configuration"):
        chain.fk_rows_jacobian(np.zeros((2, 7)))
