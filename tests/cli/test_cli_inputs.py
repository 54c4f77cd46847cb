"""Malformed numbers, out-of-range options and unwritable paths on the command line:
each gives a one-line message naming what was wrong, a non-zero exit and no traceback,
and is caught before any work is done."""

import math
import time

import numpy as np
import pytest
from cli_helpers import numbers, run  # noqa: E402 - the helper module beside these tests

from ratectl.cli import main as cli


def assert_one_line_error(code, out, err, *words):
    assert code == 2, (code, out, err)
    assert "Traceback" not in out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "error:" in lines[0]
    for w in words:
        assert w in lines[0], (w, lines[0])


# ---------------------------------------------------------------------------- the number grammar
@pytest.mark.parametrize("text, value", [
    ("0", 0.0), ("1.57", 1.57), ("-0.5", -0.5), ("+2", 2.0), (".5", 0.5), ("2.", 2.0), ("2e-3", 2e-3),
    ("-1E+1", -10.0), ("pi", math.pi), ("-pi", -math.pi), ("PI", math.pi), ("π", math.pi),
    ("2pi", 2 * math.pi), ("-2*pi", -2 * math.pi), ("0.5*pi", 0.5 * math.pi), ("pi/2", math.pi / 2),
    ("-pi/4", -math.pi / 4), ("3pi/4", 0.75 * math.pi), ("-3*pi/4", -0.75 * math.pi),
    ("pi/2.5", math.pi / 2.5), ("1e-1pi", 0.1 * math.pi),
])
def test_number_grammar_accepts(text, value):
    assert cli._number(text) == pytest.approx(value, rel=1e-15, abs=0)


@pytest.mark.parametrize("text", [
    "pi/", "pipi", "1pi1", "pi*pi", "pi2", "2**pi", "pi/pi", "/2", "pi//2", "--1", "+-1", "1.2.3", "1e",
    "e5", "nan", "-nan", "inf", "-inf", "infinity", "0x10", "1_0", "", "pi/-2", "2 pi", "½", "1/2", "deg",
])
def test_number_grammar_rejects_naming_the_token(text):
    with pytest.raises(cli._Fail) as info:
        cli._number(text)
    assert repr(text) in str(info.value)


def test_pi_over_zero_and_overflow_are_clear_errors():
    with pytest.raises(cli._Fail, match="divides by zero"):
        cli._number("pi/0")
    with pytest.raises(cli._Fail, match="divides by zero"):
        cli._number("-3pi/0.0")
    with pytest.raises(cli._Fail, match="too large"):
        cli._number("1e999")
    with pytest.raises(cli._Fail, match="too large"):
        cli._number("1e308pi")


# ---------------------------------------------------------------------------- --q on the command line
@pytest.mark.parametrize("values, bad", [
    (["0", "pi/", "0", "0", "0", "0"], "'pi/'"),
    (["0", "pipi", "1pi1", "pi*pi", "pi2", "0"], "'pipi'"),
    (["pi/0", "0", "0", "0", "0", "0"], "'pi/0'"),
    (["0", "0", "0", "0", "0", "nan"], "'nan'"),           # last position: same message as first
    (["nan", "0", "0", "0", "0", "0"], "'nan'"),
    (["0", "0", "0", "0", "0", "-inf"], "'-inf'"),
    (["0", "0", "0", "0", "0", "pi2"], "'pi2'"),
    (["0,0,0,0,0,1pi1"], "'1pi1'"),
    (["0", "0", "0", "0", "0", "zero"], "'zero'"),
])
@pytest.mark.parametrize("command", ["jacobian", "singularity"])
def test_malformed_joint_values(command, values, bad):
    code, out, err = run([command, "ur5e", "--q", *values])
    assert_one_line_error(code, out, err, bad)
    assert out == ""                                       # nothing computed


def test_bad_last_value_is_not_an_unrecognized_argument():
    code, out, err = run(["jacobian", "ur5e", "--q", "0", "0", "0", "0", "0", "nan"])
    assert_one_line_error(code, out, err, "cannot read 'nan' as a joint value")
    assert "unrecognized" not in err


def test_values_before_an_option_and_arm_after_q():
    argv = ["jacobian", "ur5e", "--q", "0", "-pi/2", "pi/2", "0", "pi/2", "0", "--frame", "tool"]
    code, out, err = run(argv)
    assert code == 0, err
    assert np.allclose(numbers(out.splitlines()[0]), [0, -math.pi / 2, math.pi / 2, 0, math.pi / 2, 0],
                       atol=1e-4)
    code, out, err = run(["jacobian", "--q", "0", "0", "0", "0", "0", "0", "ur5e"])
    assert code == 0, err
    assert out.startswith("UR5e at q")


def test_out_of_limit_values_are_warned_naming_the_joint():
    code, out, err = run(["singularity", "ur5e", "--q", "0", "0", "4", "0", "0", "0.3"])
    assert code == 0
    assert "warning" in err and "joint 'elbow' = 4 rad is outside its limits [-3.142, 3.142]" in err
    assert err.count("warning") == 1
    code, out, err = run(["jacobian", "rpr", "--q", "0", "0.9", "0"])       # prismatic: metres
    assert code == 0 and "q2" in err and " m is outside" in err
    code, _, err = run(["jacobian", "ur5e", "--q", "0", "0", "1", "0", "0", "0"])
    assert code == 0 and "warning" not in err


# ---------------------------------------------------------------------------- option values
@pytest.mark.parametrize("argv, words", [
    (["jacobian", "ur5e", "--q", "random", "--seed", "-1"], ["--seed", "at least 0", "-1"]),
    (["scan", "ur5e", "--seed", "-1"], ["--seed", "at least 0"]),
    (["scan", "ur5e", "--seed", "x"], ["--seed", "'x'"]),
    (["scan", "ur5e", "--samples", "1e5"], ["--samples", "'1e5'"]),
    (["scan", "ur5e", "--samples", "-3"], ["--samples"]),
    (["scan", "ur5e", "--resolution", "100000", "--plot", "m.png"], ["--resolution", "2 to 1001", "100000"]),
    (["scan", "ur5e", "--resolution", "1"], ["--resolution"]),
    (["scan", "ur5e", "--joints", "1", "1"], ["--joints", "two different"]),
    (["scan", "ur5e", "--joints", "0", "6"], ["--joints", "0..5"]),
    (["scan", "ur5e", "--joints", "wrist_9", "0"], ["--joints", "joint names"]),
    (["scan", "ur5e", "--range", "0", "1", "2", "x"], ["'x'"]),
    (["demo", "--dt", "1e-7"], ["--dt", "between", "1e-07"]),
    (["demo", "--dt", "1"], ["--dt", "between"]),
    (["demo", "--dt", "nan"], ["--dt", "'nan'"]),
    (["demo", "--dt", "fast"], ["--dt", "'fast'"]),
    (["demo", "--arm", "panda"], ["--arm", "panda"]),
    (["jacobian", "ur5e", "--point", "0", "0", "nan"], ["--point", "'nan'"]),
    (["jacobian", "ur5e", "--frame", "world"], ["--frame", "world"]),
    (["info"], ["ARM"]),
    (["frobnicate"], ["frobnicate"]),
])
def test_bad_option_values_are_one_line(argv, words):
    t0 = time.perf_counter()
    code, out, err = run(argv)
    assert_one_line_error(code, out, err, *words)
    assert time.perf_counter() - t0 < 2.0                  # refused before any work


# ---------------------------------------------------------------------------- output paths
def _bad_paths(tmp_path):
    return [
        (str(tmp_path / "no" / "such" / "dir" / "x.png"), "does not exist"),
        (str(tmp_path), "is a directory"),
        (str(tmp_path / "x.notanimage"), "unknown image format"),
        ("/proc/x.png", "cannot write"),
    ]


@pytest.mark.parametrize("which", range(4))
def test_unwritable_plot_path_is_refused_before_the_scan(tmp_path, which):
    path, words = _bad_paths(tmp_path)[which]
    t0 = time.perf_counter()
    code, out, err = run(["scan", "ur5e", "--samples", "2000000", "--plot", path])
    assert_one_line_error(code, out, err, "--plot", words)
    assert time.perf_counter() - t0 < 2.0                  # 2 million samples were not drawn
    assert out == ""


@pytest.mark.parametrize("which", range(4))
def test_unwritable_demo_output_is_refused_before_the_runs(tmp_path, which):
    path, words = _bad_paths(tmp_path)[which]
    t0 = time.perf_counter()
    code, out, err = run(["demo", "--out", path])
    assert_one_line_error(code, out, err, "--out", words)
    assert time.perf_counter() - t0 < 2.0
    assert out == ""


def test_path_check_leaves_no_file_behind(tmp_path):
    target = tmp_path / "map.png"
    cli._check_output(str(target), "--plot")
    assert not target.exists()
    target.write_bytes(b"keep")
    cli._check_output(str(target), "--plot")
    assert target.read_bytes() == b"keep"


def test_internal_errors_are_one_line(monkeypatch):
    def boom(args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(cli, "_cmd_info", boom)
    code, out, err = run(["info", "ur5e"])
    assert code == 1
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert "internal error: ZeroDivisionError" in err


# ---------------------------------------------------------------------------- consistent reports
def test_exactly_singular_has_no_distance_estimate():
    code, out, err = run(["singularity", "ur5e", "--q", "zero"])
    assert code == 0, err
    assert "exactly singular" in out
    assert "distance to the singular set" not in out


def test_stretched_planar_arm_is_not_regular():
    code, out, _ = run(["singularity", "planar2r", "--q", "0.3", "0"])
    assert code == 0
    assert "kind: boundary" in out and "stretched or folded" in out
    code, out, _ = run(["singularity", "planar2r", "--q", "0.3", "1.0"])
    assert "kind: regular" in out
