"""ProgressLimits.caps: the joint limits as bounds on progress along a direction."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import ratectl as rc
from ratectl.control.progress import ProgressLimits


def _limits(arm, smoothed):
    return ProgressLimits(arm, rc.Limits.of(arm, arm.dof), jmax=arm.jmax if smoothed else None,
                          accel_share=0.5, stop_sigma=0.05, watch_sigma=0.2)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 10_000), st.booleans(), st.floats(0.0, 0.05))
def test_an_arm_that_lags_its_command_has_the_room_of_its_command(seed, smoothed, lag):
    """With the last commanded position q_lead ahead of the measured q along w (an arm that
    lags its command), the room to a limit and the speed bound are those measured from
    q_lead: the arm will still get there. q_lead behind q changes nothing."""
    arm = rc.robots.ur5e().with_limits(qlim=np.column_stack([np.full(6, -1.0), np.full(6, 1.0)]))
    rng = np.random.default_rng(seed)
    q = rng.uniform(-0.9, 0.9, 6)
    w = rng.standard_normal(6)
    pl = _limits(arm, smoothed)
    ahead = q + lag * np.sign(w)
    behind = q - lag * np.sign(w)
    lead = pl.caps(q, w, dt=1e-3, q_lead=ahead)
    moved = pl.caps(np.clip(ahead, -1.0, 1.0), w, dt=1e-3)
    assert lead.room == moved.room or abs(lead.room - moved.room) <= 1e-12 * (1 + moved.room)
    assert lead.speed == moved.speed or abs(lead.speed - moved.speed) <= 1e-12 * (1 + moved.speed)
    plain = pl.caps(q, w, dt=1e-3)
    same = pl.caps(q, w, dt=1e-3, q_lead=behind)
    assert (same.room, same.speed) == (plain.room, plain.speed)
    assert lead.room <= plain.room and lead.speed <= plain.speed
