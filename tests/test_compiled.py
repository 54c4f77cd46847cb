"""The compiled control cycle (mypyc, ``setup.py``) is the same code as the sources.

An installation compiles the modules of `ratectl.compiled.COMPILED_MODULES`; the sources
also run as plain Python. Both must give the same commands: the loops below (a servo to a
moving target, jogs into a singularity and into a joint limit, a step with a jittered
period; plain and smoothed) run here, on the installed package, and in a subprocess on a
copy of the sources without the compiled files, and their command streams are compared.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ratectl as rc

PACKAGE = Path(rc.__file__).resolve().parent
PURE = os.environ.get("RATECTL_PURE_PYTHON", "").lower() in ("1", "true", "yes")


def streams() -> dict[str, list]:
    """Command streams ``[q̇, q_next, status, reason]`` per step of six short loops."""
    out: dict[str, list] = {}

    def record(name, ctrl, q, steps, dt, **kw):
        rows = []
        for k in range(steps):
            d = dt(k) if callable(dt) else dt
            target = kw["target"](k) if callable(kw.get("target")) else kw.get("target")
            cmd = ctrl.step(q, dt=d, target=target, twist=kw.get("twist"))
            rows.append([cmd.qd.tolist(), cmd.q_next.tolist(), cmd.status, cmd.reason])
            q = cmd.q_next
        out[name] = rows

    ur5e = rc.robots.ur5e()
    q0 = np.array([0.3, -1.3, 1.6, -1.9, -1.2, 0.2])
    T0 = ur5e.fk(q0)

    def circle(k):  # 5 cm circle at 0.2 m/s
        T = T0.copy()
        a = 4.0 * k * 1e-3
        T[:3, 3] += [0.05 * (np.cos(a) - 1.0), 0.05 * np.sin(a), 0.0]
        return T

    for smoothing in (False, True):
        tag = "smoothed" if smoothing else "plain"
        record(f"ur5e qp circle {tag}", rc.ResolvedRateController(ur5e, solver=rc.solvers.QP(),
                                                                  smoothing=smoothing),
               q0.copy(), 400, 1e-3, target=circle)
        # toward the wrist singularity (q5 → 0): the jog slows and stops before it
        record(f"ur5e wrist jog {tag}", rc.ResolvedRateController(ur5e, smoothing=smoothing),
               np.array([0.0, -1.2, 1.4, -1.8, 0.12, 0.3]), 400, 2e-3,
               twist=np.array([0.0, 0.0, 0.0, 0.0, 0.4, 0.0]))
    panda = rc.robots.panda()
    qp0 = np.array([0.0, 0.334, 0.0, -1.177, 0.0, 1.510, 0.785])
    step = panda.fk(qp0)
    step[:3, 3] += [0.1, 0.05, -0.08]
    jitter = np.random.default_rng(3).uniform(0.5, 1.5, 600) * 4e-3
    record("panda step jittered smoothed", rc.ResolvedRateController(panda, smoothing=True),
           qp0.copy(), 600, lambda k: float(jitter[k]), target=step)
    iiwa = rc.robots.iiwa7()
    record("iiwa7 jog into a joint limit smoothed", rc.ResolvedRateController(iiwa, smoothing=True),
           np.array([0.3, 1.9, 0.2, -1.2, 0.1, 0.8, 0.0]), 500, 1e-3,
           twist=np.array([0.0, 0.0, -0.15, 0.0, 0.0, 0.0]))
    return out


def test_the_control_cycle_is_compiled_by_the_install():
    """``pip install -e .`` (the README) compiles every listed module; a failed or skipped
    compilation would leave the cycle interpreted, slower, and this test says so."""
    if PURE:
        pytest.skip("RATECTL_PURE_PYTHON is set: the sources run as plain Python")
    compiled = rc.compiled.modules()
    missing = sorted(name for name, yes in compiled.items() if not yes)
    assert not missing, (f"not compiled: {missing}; reinstall with `pip install -e .` (mypyc needs a "
                         "C compiler), or set RATECTL_PURE_PYTHON=1 to run plain Python")
    assert rc.compiled.stale() == []


def test_compiled_and_interpreted_cycles_give_the_same_commands(tmp_path):
    if not any(rc.compiled.modules().values()):
        pytest.skip("nothing is compiled here: both runs would be the same code")
    pure = tmp_path / "src"
    shutil.copytree(PACKAGE, pure / "ratectl",
                    ignore=shutil.ignore_patterns("*.so", "*.pyd", "__pycache__"))
    code = ("import json, runpy, sys\n"
            f"sys.path.insert(0, {str(pure)!r})\n"
            "import ratectl\n"
            "assert not any(ratectl.compiled.modules().values()), 'the copy runs compiled code'\n"
            f"print(json.dumps(runpy.run_path({__file__!r})['streams']()))\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    interpreted = json.loads(proc.stdout)
    compiled = json.loads(json.dumps(streams()))
    assert interpreted.keys() == compiled.keys()
    # x86-64 has no fused multiply-add in its baseline, so C and the interpreter round alike
    exact = platform.machine().lower() in ("x86_64", "amd64")
    for name in compiled:
        a, b = compiled[name], interpreted[name]
        assert len(a) == len(b)
        for k, (ra, rb) in enumerate(zip(a, b, strict=True)):
            assert ra[2:] == rb[2:], f"{name}, step {k}: status/reason {ra[2:]} vs {rb[2:]}"
            if exact:
                assert ra[:2] == rb[:2], f"{name}, step {k}: commands differ"
            else:
                np.testing.assert_allclose(np.r_[ra[0], ra[1]], np.r_[rb[0], rb[1]], rtol=0, atol=1e-9)


def test_a_compiled_module_older_than_its_source_is_reported(tmp_path):
    """In a source checkout (a ``.git`` folder beside the package), a compiled module whose
    ``.py`` was edited after the build is stale: ``import ratectl`` warns with `stale`."""
    folder = tmp_path / "ratectl" / "control"
    folder.mkdir(parents=True)
    src, built = folder / "servo.py", folder / "servo.cpython-311-x86_64-linux-gnu.so"
    built.write_bytes(b"")
    src.write_text("")
    now = time.time()
    os.utime(built, (now - 10, now - 10))
    os.utime(src, (now, now))
    assert rc.compiled.stale(str(tmp_path)) == []          # not a checkout: an installed wheel
    (tmp_path / ".git").mkdir()
    assert rc.compiled.stale(str(tmp_path)) == ["ratectl.control.servo"]   # no record: by time
    # the build's record of what it compiled: the same bytes, only touched, are not stale
    record = tmp_path / rc.compiled.SOURCES_RECORD
    record.write_text(json.dumps({"ratectl/control/servo.py": rc.compiled.source_digest(str(src))}))
    assert rc.compiled.stale(str(tmp_path)) == []
    src.write_text("x = 1\n")                              # edited after the build
    os.utime(src, (now, now))
    assert rc.compiled.stale(str(tmp_path)) == ["ratectl.control.servo"]
    os.utime(built, (now + 10, now + 10))                   # rebuilt
    assert rc.compiled.stale(str(tmp_path)) == []


def test_the_build_records_the_sources_it_compiled():
    """In this checkout, the record written by the build holds every compiled module."""
    root = PACKAGE.parent
    if PURE or not (root / ".git").exists() or not any(rc.compiled.modules().values()):
        pytest.skip("not a compiled source checkout")
    recorded = json.loads((root / rc.compiled.SOURCES_RECORD).read_text())
    assert sorted(recorded) == sorted(rc.compiled.COMPILED_MODULES)
