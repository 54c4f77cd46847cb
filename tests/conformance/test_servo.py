"""Servo conformance: the user's loop reaches step targets without overshoot, within every
limit, on built-in arms and on arms imported from URDF without acceleration limits.

The default run is a fixed subset (a few seconds); the full sweep — every arm, step targets
of 1–20 cm in random directions with turns up to 30°, smoothing off and on, dt 1 ms and
4 ms — is marked ``slow`` and runs with ``RATECTL_SLOW=1`` (``benchmarks/report_servo.py``
prints its worst overshoot and settling time per arm).
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

import ratectl as rc

from . import harness

ARMS = harness.all_arms()


def _check(chain, case, *, smoothing, dt, loop="q_next"):
    out = harness.run_case(chain, case, smoothing=smoothing, dt=dt, loop=loop)
    where = (f"{case.arm} smoothing={smoothing} dt={dt} step={case.step * 1e3:.1f} mm "
             f"turn={math.degrees(case.turn):.1f}°: {out}")
    assert out.settle <= 4.0, f"not settled within 0.1 mm / 0.01° in 4 s: {where}"
    assert out.overshoot <= 0.01 * case.step + 1e-4, f"overshoot: {where}"
    assert out.vratio <= 1.0 + 1e-9, f"|q̇| > vmax: {where}"
    assert not out.aratio > 1.0 + 1e-6, f"|q̈| > amax: {where}"
    assert out.beyond <= 1e-12, f"q outside its range: {where}"
    return out


# (arm, case index, smoothing, dt, loop): the default, fast subset
FAST = [
    ("builtin:ur5e", 0, False, 4e-3, "euler"),
    ("builtin:ur5e", 1, True, 4e-3, "q_next"),
    ("builtin:panda", 0, True, 1e-3, "q_next"),
    ("builtin:iiwa7", 2, False, 1e-3, "euler"),
    ("urdf:fr3_urdf", 0, False, 4e-3, "euler"),
    ("urdf:irb_like", 1, True, 4e-3, "q_next"),
    ("urdf:rail_ur_like", 0, False, 4e-3, "q_next"),
]


# (arm, case index with seed 0 as in benchmarks/report_servo.py, dt): smoothed runs that
# failed before the approach was planned in joint space with a reference the filter meets
# exactly — the rpr's curved least-squares path overshot 6.1 % (the filter lagged a
# proportional command by up to 78 periods), rail_ur_like crawled and did not settle (each
# reference stretched to 1.5–2 periods by the filter's synchronisation), iiwa7 rode a
# braking curve whose mapped limits shrank and passed a joint-limit brake
REGRESSION = [
    ("builtin:rpr", 2, 1e-3),
    ("urdf:rail_ur_like", 3, 1e-3),
    ("urdf:rail_ur_like", 0, 4e-3),
    ("builtin:iiwa7", 3, 1e-3),
    ("builtin:iiwa7", 1, 4e-3),
    # the filter, given a reference it could not meet within one period by a hair (a joint
    # 1.8 % or 0.9 % too slow), went the time-optimal way to that fixed (q̇, q̈), a detour of
    # 0.16–0.18 s, and fell behind the reference: 11.1 mm past a 149 mm step (planar2r),
    # 4.6 mm past a 179 mm step after two restarts of the line from the lagging arm (FR3)
    ("builtin:planar2r", 1, 4e-3),
    ("urdf:fr3_urdf", 2, 1e-3),
]


@pytest.mark.parametrize(("arm", "index", "dt"), REGRESSION,
                         ids=[f"{a}-{i}-{d * 1e3:g}ms" for a, i, d in REGRESSION])
def test_smoothed_regressions(arm, index, dt):
    if arm not in ARMS:
        pytest.skip(f"{arm} not available")
    chain = ARMS[arm]()
    case = harness.make_cases(arm, chain, index + 1, seed=0)[index]
    out = _check(harness.smoothing_limits(chain), case, smoothing=True, dt=dt)
    assert out.settle < 3.0


@pytest.mark.parametrize(("arm", "index", "smoothing", "dt", "loop"), FAST,
                         ids=[f"{a}-{i}-{'smooth' if s else 'plain'}-{d * 1e3:g}ms-{lp}"
                              for a, i, s, d, lp in FAST])
def test_step_target_reached_without_overshoot(arm, index, smoothing, dt, loop):
    if arm not in ARMS:
        pytest.skip(f"{arm} not available")
    chain = ARMS[arm]()
    case = harness.make_cases(arm, chain, index + 1, seed=3)[index]
    if smoothing:
        chain = harness.smoothing_limits(chain)
    _check(chain, case, smoothing=smoothing, dt=dt, loop=loop)


def test_a_urdf_arm_without_acceleration_limits_reaches_a_5cm_target():
    """The FR3 URDF shipped with franky-sim has no acceleration limits (amax = inf): the
    default controller moves it and reaches a 5 cm target, within vmax and its range."""
    if "urdf:fr3_urdf" not in ARMS:
        pytest.skip("franky-sim's FR3 URDF is not installed")
    arm = ARMS["urdf:fr3_urdf"]()
    assert np.all(np.isinf(arm.amax))
    q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    T = arm.fk(q0)
    T[:3, 3] += [0.0, 0.05, 0.0]
    case = harness.Case("urdf:fr3_urdf", q0, T, 0.05, 0.0)
    out = _check(arm, case, smoothing=False, dt=1e-3, loop="euler")
    assert out.settle < 2.0


def test_smoothing_on_a_urdf_arm_needs_with_limits():
    arm = ARMS["urdf:irb_like"]()
    with pytest.raises(rc.errors.InputError, match="with_limits"):
        rc.ResolvedRateController(arm, smoothing=True)
    rc.ResolvedRateController(arm.with_limits(amax=10.0, jmax=100.0), smoothing=True)


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("RATECTL_SLOW"), reason="full sweep: set RATECTL_SLOW=1")
@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_full_sweep(arm, smoothing):
    chain = ARMS[arm]()
    if smoothing:
        chain = harness.smoothing_limits(chain)
    for case in harness.make_cases(arm, ARMS[arm](), 6, seed=0):
        for dt in (1e-3, 4e-3):
            _check(chain, case, smoothing=smoothing, dt=dt)
