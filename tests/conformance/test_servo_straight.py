"""The servo goes straight to its target: the acceptance sweep of the straight approach.

On arms imported from the ``example-robot-data`` package (UR10, Panda, xArm7, Kinova Jaco2;
amax and jmax added with ``chain.with_limits``) and the built-ins with six or more joints,
5–25 cm steps with turns up to 45° and pure turns of 15–45°, from seeded regular starts,
with smoothing off and on, at dt 1 and 4 ms, the user's loop ``cmd = ctrl.step(q, target=T,
dt=dt); q = cmd.q_next`` must keep the tool within 1 mm + 0.5 % of the step from the
straight segment (and within 0.5° + 1 % of the turn from the geodesic rotation), overshoot
by at most 1 % + 0.1 mm along the step, reach the target within 4 s, and hold |q̇| ≤ vmax,
|q̈| ≤ amax and the range (see `servo_sweep` for every definition). Every case's straight
line is clear (a continuous, regular joint path inside the range exists), so nothing
excuses a miss. Targets whose line is blocked must be reached or reported (a terminal status
with a reason) within 4 s.

Default: 3 steps and 2 pure turns per arm; ``RATECTL_SLOW=1`` adds a sweep of 10 steps and
4 pure turns per arm on other seeds. ``python -m tests.conformance.servo_sweep`` prints the
table (arm × smoothing × dt).
"""

from __future__ import annotations

import functools
import os

import pytest

from . import servo_arms, servo_sweep

ARMS = servo_arms.sweep_arms()
GRID = [(arm, smoothing, dt) for arm in ARMS for smoothing in (False, True) for dt in (1e-3, 4e-3)]


@functools.cache
def _arm(name):
    return ARMS[name]()


@functools.cache
def _cases(name, steps, turns, seed):
    return servo_sweep.make_cases(name, _arm(name), steps=steps, turns=turns, seed=seed)


def _judge(arm, smoothing, dt, *, steps, turns, seed):
    cases = _cases(arm, steps, turns, seed)
    assert len(cases) == steps + turns, f"{arm}: only {len(cases)} clear cases were found"
    failures = []
    for case in cases:
        out = servo_sweep.run_case(_arm(arm), case, smoothing=smoothing, dt=dt)
        v = out.violations()
        if v:
            failures.append(f"{out.where}: " + "; ".join(v) + f"\n    [{out.summary()}]")
    assert not failures, (f"{len(failures)} of {len(cases)} runs break the straight-approach "
                          "criteria:\n" + "\n".join(failures))


def test_the_sweep_has_imported_arms():
    """The package's arms are there (the sweep would silently shrink without them)."""
    assert servo_arms.robots_dir() is not None, "example-robot-data is not installed"
    for name in ("erd:ur10", "erd:panda", "erd:xarm7", "erd:jaco2"):
        chain = ARMS[name]()
        assert chain.dof >= 6
        assert (chain.amax == servo_arms.AMAX).all() and (chain.jmax == servo_arms.JMAX).all()


@pytest.mark.parametrize(("arm", "smoothing", "dt"), GRID,
                         ids=[f"{a}-{'smooth' if s else 'plain'}-{d * 1e3:g}ms" for a, s, d in GRID])
def test_straight_to_the_target(arm, smoothing, dt):
    _judge(arm, smoothing, dt, seed=0, **servo_sweep.DEFAULT_SIZE)


BLOCKED = servo_sweep.blocked_cases()


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
@pytest.mark.parametrize("index", range(len(BLOCKED)), ids=[b[0] for b in BLOCKED])
def test_a_blocked_line_is_reached_or_reported(index, smoothing):
    name, chain, case = BLOCKED[index]
    out = servo_sweep.run_case(chain, case, smoothing=smoothing, dt=1e-3)
    v = out.violations(straight=False)
    assert not v, f"{name}, {out.where}: " + "; ".join(v) + f"\n    [{out.summary()}]"


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("RATECTL_SLOW"), reason="full sweep: set RATECTL_SLOW=1")
@pytest.mark.parametrize(("arm", "smoothing", "dt"), GRID,
                         ids=[f"{a}-{'smooth' if s else 'plain'}-{d * 1e3:g}ms" for a, s, d in GRID])
def test_straight_to_the_target_full_sweep(arm, smoothing, dt):
    _judge(arm, smoothing, dt, seed=1, **servo_sweep.SLOW_SIZE)


@pytest.mark.parametrize("smoothing", [False, True], ids=["plain", "smooth"])
def test_a_turn_blocked_by_a_boundary_singularity_goes_on_in_joint_space(smoothing):
    """example-robot-data's Panda, a 24° pure turn (case 11 of the full sweep) whose geodesic
    heads into a boundary singularity: the line stops before it and the arm goes on in joint
    space to the target. The cycle that takes the alternative is neither a halt nor
    ``target-unreachable`` (a loop that ends on those stopped there)."""
    name = "erd:panda"
    case = _cases(name, *servo_sweep.SLOW_SIZE.values(), seed=1)[11]
    assert case.kind == "turn"
    out = servo_sweep.run_case(_arm(name), case, smoothing=smoothing, dt=1e-3)
    v = out.violations()
    assert not v, f"{out.where}: " + "; ".join(v) + f"\n    [{out.summary()}]"
