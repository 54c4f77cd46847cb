"""The ``ratectl`` command, called in-process through ``ratectl.cli.main.main``."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import numbers, run  # noqa: E402 - the helper module beside these tests

import ratectl as rc
from ratectl.cli import demo

DATA = Path(__file__).resolve().parents[1] / "data"
COMMANDS = ("demo", "info", "jacobian", "singularity", "scan")


# ---------------------------------------------------------------------------- help
def test_help_lists_every_command():
    code, out, _ = run(["--help"])
    assert code == 0
    for c in COMMANDS:
        assert c in out
    assert "Built-in arms" in out


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help(command):
    code, out, _ = run([command, "--help"])
    assert code == 0
    assert f"ratectl {command}" in out
    assert len(out.splitlines()) > 5


def test_no_command_prints_help_and_fails():
    code, out, _ = run([])
    assert code == 2
    assert "COMMAND" in out


# ---------------------------------------------------------------------------- info
@pytest.mark.parametrize("name", sorted(rc.robots.BUILTIN))
def test_info_every_builtin_arm(name):
    code, out, err = run(["info", name])
    assert code == 0, err
    chain = rc.robots.BUILTIN[name]()
    assert chain.name in out
    assert f"degrees of freedom: {chain.dof}" in out


def test_info_reports_wrist_structure():
    assert "spherical wrist: yes" in run(["info", "puma560"])[1]
    assert "spherical wrist: no" in run(["info", "ur5e"])[1]
    assert "redundant" in run(["info", "iiwa7"])[1]


def test_info_reads_a_urdf_file():
    code, out, err = run(["info", str(DATA / "ur5e_like.urdf")])
    assert code == 0, err
    assert "degrees of freedom: 6" in out


# ---------------------------------------------------------------------------- jacobian
def _printed_jacobian(out, n):
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("v_x"))
    return np.array([numbers(lines[start + k])[:n] for k in range(6)])


def test_jacobian_prints_the_library_jacobian():
    q = [0.6, 0.35, -0.4]
    code, out, err = run(["jacobian", "rpr", "--q", *map(str, q)])
    assert code == 0, err
    J = _printed_jacobian(out, 3)
    assert np.allclose(J, rc.robots.rpr().jacobian(np.array(q)), atol=6e-5)
    assert "rank 3 of 3" in out


def test_jacobian_tool_frame_and_point():
    arm = rc.robots.ur5e()
    q = np.array([0.1, -1.2, 1.4, -1.8, -1.57, 0.3])
    code, out, _ = run(["jacobian", "ur5e", "--q", *map(str, q), "--frame", "tool",
                        "--point", "0", "0", "0.05"])
    assert code == 0
    J = _printed_jacobian(out, 6)
    assert np.allclose(J, arm.jacobian(q, frame="tool", point=[0, 0, 0.05]), atol=6e-5)


@pytest.mark.parametrize("tokens, expected", [
    (["0", "pi/2", "-pi/4", "-2*pi/3", "0", "0.5"], [0, math.pi / 2, -math.pi / 4, -2 * math.pi / 3, 0, 0.5]),
    (["0,1.5,-1,0.25,0,0"], [0, 1.5, -1, 0.25, 0, 0]),
    (["0", "90", "-45", "0", "30", "0", "--deg"], np.radians([0, 90, -45, 0, 30, 0])),
])
def test_joint_value_formats(tokens, expected):
    code, out, err = run(["jacobian", "ur5e", "--q", *tokens])
    assert code == 0, err
    first = out.splitlines()[0]
    assert np.allclose(numbers(first), expected, atol=1e-4)


def test_joint_value_words():
    arm = rc.robots.panda()
    code, out, _ = run(["jacobian", "panda", "--q", "mid"])
    assert code == 0
    assert np.allclose(numbers(out.splitlines()[0]), 0.5 * (arm.lower + arm.upper), atol=1e-4)
    code1, out1, _ = run(["jacobian", "panda", "--q", "random", "--seed", "3"])
    code2, out2, _ = run(["jacobian", "panda", "--q", "random", "--seed", "3"])
    assert code1 == code2 == 0 and out1 == out2


def test_prismatic_values_are_metres_with_deg():
    code, out, _ = run(["jacobian", "rpr", "--q", "90", "0.3", "0", "--deg"])
    assert code == 0
    assert np.allclose(numbers(out.splitlines()[0]), [math.pi / 2, 0.3, 0.0], atol=1e-4)


@pytest.mark.parametrize("arm", ["ur5e", "panda", "stanford", "rpr"])
def test_jacobian_columns_are_headed_by_the_chains_joint_names(arm):
    chain = rc.robots.__dict__[arm]()
    code, out, err = run(["jacobian", arm, "--q", "mid"])
    assert code == 0, err
    lines = out.splitlines()
    head = lines[next(i for i, line in enumerate(lines) if line.startswith("v_x")) - 1]
    expected = [n + (" (P)" if p else "") for n, p in zip(chain.joint_names, chain.prismatic, strict=True)]
    assert re.split(r"\s{2,}", head.strip()) == expected
    # every column is as wide as its label: the numbers stay under their names
    row = lines[lines.index(head) + 1]
    for name in expected:
        end = head.index(name) + len(name)
        assert row[end - 1].isdigit(), (name, head, row)


def test_urdf_joint_names_head_the_jacobian_and_the_null_space(tmp_path):
    names = ["base_swivel", "a_very_long_shoulder_joint_name", "elbow"]
    links = "".join(f'<link name="l{i}"/>' for i in range(4))
    joints = "".join(f'<joint name="{n}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0 0 0.3"/><axis xyz="{"0 1 0" if i == 1 else "0 0 1"}"/>'
                     '<limit lower="-3" upper="3" velocity="1" effort="1"/></joint>'
                     for i, n in enumerate(names))
    f = tmp_path / "arm.urdf"
    f.write_text(f'<robot name="three">{links}{joints}</robot>')
    code, out, err = run(["jacobian", str(f), "--q", "0", "0.5", "0.5"])
    assert code == 0, err
    assert re.split(r"\s{2,}", out.splitlines()[[i for i, line in enumerate(out.splitlines())
                                                 if line.startswith("v_x")][0] - 1].strip()) == names
    code, out, err = run(["singularity", str(f), "--q", "0", "0", "0"])  # first and last axis on one line
    assert code == 0, err
    block = out.split("joint-space null space (columns):\n")[1].splitlines()
    assert [line.split()[0] for line in block[:3]] == names


# ---------------------------------------------------------------------------- singularity
def test_singularity_names_the_wrist():
    code, out, err = run(["singularity", "ur5e", "--q", "0", "-1.2", "1.4", "-1.8", "0", "0.3"])
    assert code == 0, err
    assert "kind: wrist" in out
    assert "rank: 5 of 6" in out
    assert "lost task directions" in out
    assert "joint-space null space" in out
    null_rows = out.split("joint-space null space (columns):\n")[1].splitlines()
    assert [line.split()[0] for line in null_rows] == list(rc.robots.ur5e().joint_names)


def test_singularity_regular_and_decoupled():
    code, out, _ = run(["singularity", "puma560", "--q", "0.3", "0.5", "-0.4", "0.6", "0.8", "0.3"])
    assert code == 0
    assert "kind: regular" in out
    m = re.search(r"det J11 = (\S+) \(arm\), det J22 = (\S+) \(wrist\)", out)
    assert m is not None
    arm = rc.robots.puma560()
    detJ = np.linalg.det(arm.jacobian(np.array([0.3, 0.5, -0.4, 0.6, 0.8, 0.3])))
    assert float(m.group(1)) * float(m.group(2)) == pytest.approx(detJ, rel=2e-3)


def test_singularity_rpr_states_lost_directions():
    code, out, _ = run(["singularity", "rpr", "--q", "0.6", "0.35", "-0.4"])
    assert code == 0
    assert "rank: 3 of 3" in out
    assert "lost task directions" in out


# ---------------------------------------------------------------------------- scan
def test_scan_prints_statistics():
    code, out, err = run(["scan", "ur5e", "--samples", "3000", "--seed", "1"])
    assert code == 0, err
    assert "3000 random configurations" in out
    assert "sigma_min(J_L)" in out and "manipulability" in out
    counts = {k: int(v) for k, v in re.findall(r"(\w[\w-]*) (\d+) \(", out)}
    assert sum(counts.values()) == 3000
    assert counts.get("regular", 0) > 1000


def test_scan_shows_progress_and_writes_a_map(tmp_path):
    png = tmp_path / "map.png"
    code, out, err = run(["scan", "ur5e", "--samples", "60000", "--plot", str(png), "--resolution", "31"])
    assert code == 0, err
    assert "60000/60000" in err            # progress lines go to stderr
    assert png.stat().st_size > 5000


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("argv, words", [
    (["info", "nosucharm"], "unknown arm"),
    (["jacobian", "ur5e", "--q", "1", "2"], "needs 6 values"),
    (["jacobian", "ur5e", "--q", "nan", "0", "0", "0", "0", "0"], "cannot read 'nan'"),
    (["singularity", "ur5e", "--q", "1", "2", "3"], "needs 6 values"),
    (["info", "missing_file.urdf"], "no such file"),
    (["info", str(DATA / "bad_floating.urdf")], "error"),
    (["info", str(DATA / "bad_malformed.urdf")], "error"),
    (["scan", "ur5e", "--samples", "0"], "--samples"),
    (["scan", "ur5e", "--samples", "10", "--plot", "x.png", "--joints", "1", "9"], "--joints"),
    (["demo", "--dt", "-1"], "--dt"),
])
def test_errors_are_messages_not_tracebacks(argv, words):
    code, out, err = run(argv)
    assert code == 2
    assert words in err
    assert "Traceback" not in err + out
    assert err.count("\n") <= 2


def test_usage_errors_exit_2():
    code, _, err = run(["jacobian"])
    assert code == 2
    assert "ARM" in err


# ---------------------------------------------------------------------------- demo
@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    """``ratectl demo --fast`` once, keeping the Comparison it printed."""
    png = tmp_path_factory.mktemp("demo") / "demo.png"
    seen = []
    original = demo.compare

    def spy(*a, **k):
        seen.append(original(*a, **k))
        return seen[-1]

    demo.compare = spy
    try:
        code, out, err = run(["demo", "--fast", "--out", str(png)])
    finally:
        demo.compare = original
    return code, out, err, png, seen[0]


@pytest.mark.xdist_group("demo")
def test_demo_prints_the_table_and_writes_the_plot(demo_run):
    code, out, err, png, _ = demo_run
    assert code == 0, err
    for m in demo.METHODS:
        assert m in out
    assert "max|qd|/vmax" in out and "path err [mm]" in out and "duration [s]" in out
    assert png.stat().st_size > 20_000
    assert "scenario:" in err                # progress on stderr
    wrist = rc.robots.ur5e().joint_names[4]  # joints are named as the chain names them
    assert f"closest |{wrist}| = " in out and f"closest |{wrist}| = " in err
    assert "q5" not in out + err


@pytest.mark.xdist_group("demo")
def test_demo_governor_stays_on_the_path_where_the_others_do_not(demo_run):
    *_, comp = demo_run
    gov = comp["governor"]
    assert gov.completed and gov.within_limits
    assert gov.max_position_error < 1e-3
    assert gov.max_orientation_error < math.radians(0.5)
    assert gov.duration > gov.nominal        # it pays in time
    for r in comp.results:
        if r.method == "governor":
            continue
        off_path = r.max_position_error > 1e-3 or r.max_orientation_error > math.radians(0.5)
        assert off_path or not r.within_limits, r.method
    exact = comp["exact inverse"]
    assert exact.max_velocity_ratio > 5      # ~40 rad/s needed against vmax = π
    assert comp["QP"].max_velocity_ratio <= 1 + 1e-6


@pytest.mark.xdist_group("demo")
def test_demo_table_rows_match_the_results(demo_run):
    _, out, _, _, comp = demo_run
    rows = {line.split("  ")[0].strip(): line for line in out.splitlines()
            if line.split("  ")[0].strip() in demo.METHODS}
    assert set(rows) == set(demo.METHODS)
    assert "on the path, within limits" in rows["governor"]
    for m in ("exact inverse", "DLS", "adaptive DLS", "QP"):
        assert "on the path, within limits" not in rows[m]
        v = numbers(rows[m])
        assert v[0] == pytest.approx(comp[m].max_velocity_ratio, abs=0.006)


@pytest.mark.xdist_group("demo")
def test_demo_scenario_passes_close_to_the_wrist_singularity(demo_run):
    *_, comp = demo_run
    sc = comp.scenario
    assert 0.005 < sc.min_q5 < 0.02
    assert np.allclose(sc.chain.fk(sc.q0), sc.path.start, atol=1e-9)
    assert sc.exact_speed > 10 * np.min(sc.chain.vmax)


def test_demo_rejects_unknown_arm_and_method():
    with pytest.raises(rc.InputError, match="prepared scenarios"):
        demo.wrist_line("panda")
    with pytest.raises(rc.InputError, match="unknown method"):
        demo.compare("ur5e", methods=("magic",))
