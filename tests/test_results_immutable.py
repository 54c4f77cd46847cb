"""Every result the library returns is immutable: frozen, read-only arrays, no mutable dicts.

A result handed to a user must not be a window into the state of the object that made it:
writing into ``report.singular_values`` or ``plan.s`` must raise, never change what the next
call computes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
import pytest

import ratectl as rc


def _check(obj, where: str) -> list[str]:
    problems = []
    if dataclasses.is_dataclass(obj):
        params = type(obj).__dataclass_params__
        if not params.frozen:
            problems.append(f"{where}: {type(obj).__name__} is not frozen")
        values = {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}
    else:
        values = {k: getattr(obj, k) for k in getattr(obj, "__slots__", ())}
    for name, v in values.items():
        here = f"{where}.{name}"
        if isinstance(v, np.ndarray):
            if v.flags.writeable:
                problems.append(f"{here} is a writeable array")
        elif isinstance(v, dict):
            problems.append(f"{here} is a mutable dict")
        elif isinstance(v, Mapping) and not isinstance(v, MappingProxyType):
            problems.append(f"{here} is a mutable mapping")
        elif isinstance(v, list):
            problems.append(f"{here} is a mutable list")
        elif isinstance(v, tuple):
            for k, item in enumerate(v):
                if isinstance(item, np.ndarray) and item.flags.writeable:
                    problems.append(f"{here}[{k}] is a writeable array")
                elif dataclasses.is_dataclass(item):
                    problems += _check(item, f"{here}[{k}]")
    return problems


def _results():
    arm = rc.robots.ur5e()
    q = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    yield "analyze", rc.analyze(arm, q)
    yield "scan", rc.scan(arm, arm.random_q(50, rng=1))
    yield "structure", rc.singularity.structure(arm)
    yield "path_distance", rc.singularity.path_distance(arm, arm.random_q(5, rng=2))
    yield "workspace_map", rc.workspace_map(arm, joints=(1, 2), resolution=8)
    yield "solve", rc.solvers.DLS().solve(arm.jacobian(q), np.ones(6))
    yield "ik", rc.ik(arm, arm.fk(q), q)
    yield "limits", rc.Limits.of(arm, 6)
    yield "bounds", rc.solvers.joint_velocity_bounds(arm, q=q, dt=1e-3)
    ctrl = rc.ResolvedRateController(arm)
    T = arm.fk(q)
    T[:3, 3] += 0.01
    yield "command", ctrl.step(q, target=T, dt=1e-3)
    line = rc.paths.Line(arm.fk(q), T, speed=0.1, acceleration=1.0)
    run = rc.follow(arm, line, q, dt=4e-3)
    yield "execution", run
    yield "governor plan", run.info["plan"]
    yield "joint path", run.info["plan"].joint_path
    yield "joint trajectory", rc.control.move(q, q + 0.01, vmax=arm.vmax, amax=arm.amax, jmax=arm.jmax)
    from ratectl.drivers import ScriptedDriver

    yield "robot state", ScriptedDriver(arm, q).read()
    yield "urdf description", rc.io.parse_urdf(
        '<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="continuous">'
        '<parent link="a"/><child link="b"/></joint></robot>')


@pytest.mark.parametrize(("name", "result"), list(_results()), ids=lambda x: x if isinstance(x, str) else "")
def test_results_are_immutable(name, result):
    problems = _check(result, name)
    assert not problems, "\n".join(problems)
