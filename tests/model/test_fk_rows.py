"""`Chain.fk_rows_jacobian`: the tool pose's first three rows as floats and the Jacobian,
the numbers of ``fk`` and ``jacobian`` bit for bit."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.errors import InputError

ROBOTS = {"panda": rc.robots.panda, "ur5e": rc.robots.ur5e, "stanford": rc.robots.stanford,
          "puma560": rc.robots.puma560}


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
