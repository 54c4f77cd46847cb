"""The ``ratectl`` command.

::

    ratectl demo                          # five methods on a line past a wrist singularity
    ratectl info ur5e                     # the model: DH table, limits, structure
    ratectl jacobian ur5e --q 0 -1.2 1.4 -1.8 -1.57 0.3
    ratectl singularity ur5e --q 0 -1.2 1.4 -1.8 0 0.3
    ratectl scan ur5e --samples 100000    # singularity statistics over random configurations
    ratectl view ur5e                     # the arm live in the browser: sliders, drag-to-servo
    ratectl demo --view                   # the demo's five methods side by side in the browser

``ARM`` is a built-in arm (``ratectl.robots.BUILTIN``: ur5e, panda, puma560, stanford,
iiwa7, rpr, planar2r) or a ``.urdf`` / MJCF ``.xml`` file (``--tip`` chooses the tool
link or body). Errors are reported as one message on stderr with exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import numpy as np

from ..errors import InputError, RatectlError
from ..model import robots

if TYPE_CHECKING:
    from ..model.chain import Chain

__all__ = ["main", "build_parser", "load_arm", "parse_q"]

_ROW_NAMES = ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z")


class _Fail(Exception):
    """A command-line usage error with a message for the user."""


# --------------------------------------------------------------------------- helpers
def load_arm(name: str, *, tip: str | None = None) -> Chain:
    """A chain from a built-in name or a URDF/MJCF file path."""
    key = name.lower().replace("-", "").replace("_", "")
    aliases = {k.replace("_", ""): k for k in robots.BUILTIN}
    if key in aliases:
        return robots.BUILTIN[aliases[key]]()
    p = Path(name)
    if p.suffix.lower() in (".urdf", ".xml", ".mjcf"):
        if not p.is_file():
            raise _Fail(f"no such file: {name}")
        from ..model import Chain

        if p.suffix.lower() == ".urdf":
            return Chain.from_urdf(p, tip=tip)
        return Chain.from_mjcf(p, tip=tip)
    raise _Fail(f"unknown arm {name!r}; built-in arms: {', '.join(robots.BUILTIN)} "
                "(or give a .urdf or MJCF .xml file)")


def parse_q(tokens: Sequence[str], chain: Chain, *, degrees: bool = False, seed: int | None = None,
            warn: Callable[[str], None] | None = None) -> np.ndarray:
    """Joint positions from the command line.

    ``tokens`` are joint values (separate or comma-separated), or one of the words
    ``zero``, ``mid`` (middle of the limits) and ``random`` (uniform within the limits;
    ``seed``). A joint value follows the grammar

        value  := [sign] ( number | [number ["*"]] "pi" ["/" number] )
        number := digits ["." digits] [exponent]  |  "." digits [exponent]

    so ``1.57``, ``-0.5``, ``2e-3``, ``pi``, ``-2pi``, ``0.5*pi``, ``pi/2`` and ``-3*pi/4``
    are values, while ``pi/``, ``pipi``, ``1pi1``, ``pi*pi``, ``pi2``, ``nan`` and ``inf``
    are errors naming the token. Revolute values are in degrees when ``degrees``;
    prismatic values always in metres. Values outside a joint's limits are accepted
    with a warning naming the joint, passed to ``warn`` (a callable taking one line of
    text; default: no warning).
    """
    words = [w for tok in tokens for w in str(tok).replace(",", " ").split()]
    n = chain.dof
    if len(words) == 1 and words[0].lower() in _Q_WORDS:
        w = words[0].lower()
        if w.startswith("zero"):
            q = np.zeros(n)
        elif w == "mid":
            lo = np.where(np.isfinite(chain.lower), chain.lower, 0.0)
            hi = np.where(np.isfinite(chain.upper), chain.upper, 0.0)
            q = 0.5 * (lo + hi)
        else:
            return chain.random_q(rng=seed)
    else:
        bad_words = [w for w in words if w.lower() in _Q_WORDS]
        if bad_words:
            raise _Fail(f"--q takes either {n} joint values or one of the words zero, mid, random, "
                        f"not {bad_words[0]!r} among values")
        values = [_number(w) for w in words]
        if len(values) != n:
            raise _Fail(f"--q needs {n} values for {chain.name} (one per joint: "
                        f"{', '.join(chain.joint_names)}), got {len(values)}")
        q = np.array(values, dtype=float)
        if degrees:
            q = np.where(chain.prismatic, q, np.radians(q))
    if warn is not None:
        for i in range(n):
            lo_i, hi_i = float(chain.lower[i]), float(chain.upper[i])
            if not lo_i <= q[i] <= hi_i:
                unit = "m" if chain.prismatic[i] else "rad"
                warn(f"joint {chain.joint_names[i]!r} = {q[i]:.4g} {unit} is outside its limits "
                     f"[{lo_i:.4g}, {hi_i:.4g}] {unit}")
    return q


_Q_WORDS = ("zero", "zeros", "mid", "random")
_NUM = r"(?:\d+(?:\.\d*)?|\.\d+)(?:e[-+]?\d+)?"
_VALUE = re.compile(rf"([-+]?)(?:(?P<plain>{_NUM})|(?:(?P<times>{_NUM})\*?)?(?:pi|π)(?:/(?P<over>{_NUM}))?)",
                    re.IGNORECASE | re.ASCII)
_VALUE_HELP = ("a joint value is a number (1.57, -0.5, 2e-3), optionally times pi (pi, -2pi, 0.5*pi) "
               "and over a number (pi/2, -3*pi/4)")


def _number(w: str) -> float:
    """One joint value by the grammar of `parse_q`; raises ``_Fail`` naming the token."""
    s = w.strip()
    m = _VALUE.fullmatch(s)
    if m is None:
        raise _Fail(f"cannot read {w!r} as a joint value: {_VALUE_HELP}; or use one of the words "
                    "zero, mid, random")
    sign = -1.0 if m.group(1) == "-" else 1.0
    if m.group("plain") is not None:
        value = float(m.group("plain"))
    else:
        value = math.pi * (float(m.group("times")) if m.group("times") is not None else 1.0)
        if m.group("over") is not None:
            den = float(m.group("over"))
            if den == 0.0:
                raise _Fail(f"joint value {w!r} divides by zero")
            value /= den
    if not math.isfinite(value):
        raise _Fail(f"joint value {w!r} is too large (not a finite number)")
    return sign * value


def _fmt_matrix(M, *, rows=None, cols=None, prec: int = 4) -> str:
    """``M`` as a text table; ``rows`` and ``cols`` label its rows and columns (joint names,
    ``v_x`` …); each column is as wide as its widest label or number."""
    M = np.asarray(M, dtype=float)
    width = max([prec + 6, *(len(c) + 2 for c in cols or ())])
    lead = max([5, *(len(r) + 1 for r in rows or ())])
    lines = []
    if cols is not None:
        lines.append(" " * lead + "".join(c.rjust(width) for c in cols))
    for i, row in enumerate(M):
        label = (rows[i] if rows is not None else "").ljust(lead)
        lines.append(label + "".join(f"{v:{width}.{prec}f}" for v in row))
    return "\n".join(lines)


def _progress(message: str) -> None:
    print(f"  ... {message}", file=sys.stderr, flush=True)


def _warner(command: str):
    def warn(message: str) -> None:
        print(f"ratectl {command}: warning: {message}", file=sys.stderr, flush=True)

    return warn


def _check_output(path: str, option: str, *, image: bool = True) -> None:
    """Fail now, before any work, if ``path`` cannot be written (or is not an image format)."""
    p = Path(path)
    if p.is_dir():
        raise _Fail(f"{option} {path}: is a directory; give a file name such as {p / 'plot.png'}")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise _Fail(f"{option} {path}: directory {parent} does not exist")
    if image and p.suffix:
        ext = p.suffix[1:].lower()
        formats = ("png", "pdf", "svg", "svgz", "eps", "ps", "jpg", "jpeg", "tif", "tiff", "webp", "pgf",
                   "raw", "rgba")
        if ext not in formats:
            raise _Fail(f"{option} {path}: unknown image format {p.suffix!r}; use .png, .pdf or .svg")
    existed = p.exists()
    try:
        with open(p, "ab"):
            pass
    except OSError as exc:
        raise _Fail(f"{option} {path}: cannot write there ({exc.strerror or exc})") from None
    if not existed:
        with contextlib.suppress(OSError):
            os.remove(p)


# --------------------------------------------------------------------------- commands
def _cmd_info(args) -> int:
    chain = load_arm(args.arm, tip=args.tip)
    print(chain.describe())
    print(f"degrees of freedom: {chain.dof} ({''.join('RP'[int(p)] for p in chain.prismatic)})")
    print(f"reach (sum of link offsets): {chain.reach():.4f} m; characteristic length: "
          f"{chain.characteristic_length:.4f} m")
    from ..singularity import structure

    st = structure(chain)
    if chain.dof == 6:
        print("spherical wrist: " + ("yes (the last three axes meet in one point; "
                                    "det J = det J11 * det J22 at the wrist centre)"
                                    if st.spherical_wrist else "no"))
    elif chain.dof > 6:
        print(f"redundant: {chain.dof - 6} more joint(s) than task dimensions (null-space motion)")
    else:
        print(f"fewer joints than task dimensions: at most {chain.dof} independent tool twists")
    return 0


def _cmd_jacobian(args) -> int:
    chain = load_arm(args.arm, tip=args.tip)
    q = parse_q(args.q, chain, degrees=args.deg, seed=args.seed, warn=_warner(args.command))
    point = None if args.point is None else np.array(args.point, dtype=float)
    T = chain.fk(q)
    J = chain.jacobian(q, frame=args.frame, point=point)
    np.set_printoptions(precision=4, suppress=True)
    print(f"{chain.name} at q = {np.array2string(q, precision=4)}")
    print("\ntool pose T_world_tool:")
    print(_fmt_matrix(T))
    where = "tool origin" if point is None else f"tool-frame point {point.tolist()} m"
    print(f"\ngeometric Jacobian: rows [v; w] in {args.frame} axes, linear rows at the {where}")
    cols = [name + (" (P)" if p else "") for name, p in zip(chain.joint_names, chain.prismatic, strict=True)]
    print(_fmt_matrix(J, rows=_ROW_NAMES, cols=cols))
    s = np.linalg.svd(J, compute_uv=False)
    print(f"\nsingular values: {np.array2string(s, precision=4)}  (rank "
          f"{int(np.sum(s > 1e-9 * max(s[0], 1e-300)))} of {min(6, chain.dof)})")
    return 0


def _cmd_singularity(args) -> int:
    chain = load_arm(args.arm, tip=args.tip)
    q = parse_q(args.q, chain, degrees=args.deg, seed=args.seed, warn=_warner(args.command))
    from ..singularity import analyze

    r = analyze(chain, q)
    print(f"{chain.name} at q = {np.array2string(q, precision=4)}")
    print(f"kind: {r.kind}" + (" (exactly singular)" if r.singular else
                                " (near-singular)" if r.near_singular else ""))
    print(f"reason: {r.reason}")
    print(f"rank: {r.rank} of {r.max_rank}")
    print(f"singular values of J_L (linear rows / L, L = {r.length:.4f} m): "
          f"{np.array2string(r.sigma_scaled, precision=4)}")
    print(f"sigma_min(J_L) = {r.sigma_min_scaled:.4g}   manipulability sqrt(det JJ^T) = "
          f"{r.manipulability:.4g}   condition(J_L) = {r.condition_scaled:.4g}")
    if math.isfinite(r.joint_distance) and not r.singular:
        print(f"estimated distance to the singular set: {r.joint_distance:.4g} rad (first order)")
    if r.factors:
        print("geometric factors (0 = singular): "
              + ", ".join(f"{k} {v:.4g}" for k, v in r.factors.items()))
    if r.det_arm is not None:
        print(f"wrist-centre decoupling: det J11 = {r.det_arm:.4g} (arm), "
              f"det J22 = {r.det_wrist:.4g} (wrist)")
    np.set_printoptions(precision=3, suppress=True)
    if r.lost_directions_task.shape[1]:
        print("lost task directions (columns, [v/L; w]):")
        print(_fmt_matrix(r.lost_directions_task, rows=_ROW_NAMES, prec=3))
    else:
        print("weakest task direction [v/L; w]: "
              + np.array2string(np.asarray(r.weakest_direction_task), precision=3))
    if r.null_space.shape[1]:
        print("joint-space null space (columns):")
        print(_fmt_matrix(r.null_space, rows=list(chain.joint_names), prec=3))
    return 0


def _cmd_scan(args) -> int:
    chain = load_arm(args.arm, tip=args.tip)
    if args.samples < 1:
        raise _Fail(f"--samples must be a positive count, got {args.samples}")
    from ..errors import InputError
    from ..singularity import KINDS, scan
    from ..singularity.maps import joint_pair

    raw = args.joints if args.joints is not None else (["2", "4"] if chain.dof >= 5 else ["0", "1"])
    try:
        joints = joint_pair(chain, [int(v) if v.lstrip("+-").isdigit() else v for v in raw])
    except InputError as exc:
        raise _Fail(f"--joints: {exc}") from None
    ranges = None
    if args.map_range is not None:
        v = [_number(w) for w in args.map_range]
        ranges = ((v[0], v[1]), (v[2], v[3]))
        if not (v[0] < v[1] and v[2] < v[3]):
            raise _Fail(f"--range must give I_LO < I_HI and J_LO < J_HI, got {args.map_range}")
    if args.plot:
        _check_output(args.plot, "--plot")

    rng = np.random.default_rng(args.seed)
    chunk = 50_000
    counts = dict.fromkeys(KINDS, 0)
    smin, w = [], []
    t0 = time.perf_counter()
    done = 0
    while done < args.samples:
        m = min(chunk, args.samples - done)
        res = scan(chain, chain.random_q(m, rng=rng))
        for k, v in res.count().items():
            counts[k] += v
        smin.append(np.asarray(res.sigma_min_scaled))
        w.append(np.asarray(res.manipulability))
        done += m
        if args.samples > chunk:
            _progress(f"{done}/{args.samples} configurations ({time.perf_counter() - t0:.1f} s)")
    dt = time.perf_counter() - t0
    smin_all = np.concatenate(smin)
    w_all = np.concatenate(w)
    print(f"{chain.name}: {args.samples} random configurations within the joint limits "
          f"(seed {args.seed}), {dt:.2f} s ({args.samples / dt:,.0f} configurations/s)")
    pct = [0, 1, 5, 50, 95, 100]
    print("percentile            " + "".join(f"{p:>10d}%" for p in pct))
    print("sigma_min(J_L)        " + "".join(f"{v:11.4g}" for v in np.percentile(smin_all, pct)))
    print("manipulability        " + "".join(f"{v:11.4g}" for v in np.percentile(w_all, pct)))
    print("classification (regular, or the kind of a near singularity): "
          + ", ".join(f"{k} {v} ({100 * v / args.samples:.2f}%)" for k, v in counts.items() if v))
    if args.plot:
        from ..singularity import plot_workspace_map, workspace_map

        names = chain.joint_names
        _progress(f"workspace map over {names[joints[0]]}, {names[joints[1]]}")
        wmap = workspace_map(chain, joints=joints, ranges=ranges, measure="sigma_min_scaled",
                             resolution=args.resolution)
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 5.5))
        plot_workspace_map(wmap, ax=ax)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        plt.close(fig)
        print(f"workspace map written to {args.plot}")
    return 0


def _cmd_demo(args) -> int:
    from . import demo

    dt = 2e-3 if args.fast else args.dt
    if not (DEMO_DT_RANGE[0] <= dt <= DEMO_DT_RANGE[1]):
        raise _Fail(f"--dt must be between {DEMO_DT_RANGE[0]:g} and {DEMO_DT_RANGE[1]:g} s (the work grows "
                    f"as 1/dt: 1 ms takes about 10 s), got {args.dt:g}")
    if not args.no_plot:
        _check_output(args.out, "--out")
    t0 = time.perf_counter()
    print(f"ratectl demo: following a line past the wrist singularity of {args.arm} with five methods",
          file=sys.stderr)
    comp = demo.compare(args.arm, dt=dt, progress=_progress)
    print(demo.format_table(comp))
    if not args.no_plot:
        try:
            out = demo.plot_comparison(comp, args.out)
        except RatectlError as exc:
            print(f"(no plot: {exc})", file=sys.stderr)
        else:
            print(f"\nplot written to {out}")
    print(f"total time {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    if args.view:
        viewer = _open_viewer(comp.scenario.chain, comp.scenario.q0, port=args.port,
                              path=comp.scenario.path)
        with viewer:
            main_run = next((r for r in comp.results if r.method == "governor"), comp.results[0])
            others = {r.method: r for r in comp.results if r is not main_run}
            viewer.replay(main_run, others=others, play=True)
            _serve(viewer, args.seconds, "the five methods, side by side, on one time slider")
    return 0


def _open_viewer(chain, q, **options):
    try:
        from ..viewer import Viewer
    except RatectlError as exc:
        raise _Fail(str(exc)) from None
    return Viewer(chain, q, **options)


def _serve(viewer, seconds: float | None, what: str, step: Callable[[], None] | None = None,
           dt: float = 0.01) -> None:
    """Print the viewer's address, then call ``step`` every ``dt`` until ``seconds`` passed
    (or Ctrl-C)."""
    if seconds is not None and not seconds >= 0:
        raise _Fail(f"--seconds must be a duration >= 0 in seconds, got {seconds:g}")
    print(f"ratectl: view of {what} at {viewer.url}  (Ctrl-C to stop)", flush=True)
    end = math.inf if seconds is None else time.monotonic() + seconds
    next_time = time.monotonic()
    while time.monotonic() < end:
        if step is not None:
            step()
        next_time += dt
        time.sleep(max(0.0, min(next_time - time.monotonic(), end - time.monotonic())))


def _cmd_view(args) -> int:
    chain = load_arm(args.arm, tip=args.tip)
    q = parse_q(args.q, chain, degrees=args.deg, seed=args.seed, warn=_warner(args.command))
    from ..control import ResolvedRateController

    viewer = _open_viewer(chain, q, port=args.port, sliders=True)
    with viewer:
        servo = viewer.server.gui.add_checkbox("servo to the target", initial_value=bool(args.servo))
        ctrl = ResolvedRateController(chain)
        dt = 0.01

        def step() -> None:
            if servo.value:
                cmd = ctrl.step(viewer.q, target=viewer.target, dt=dt)
                viewer.update(cmd.q_next, command=cmd)

        _serve(viewer, args.seconds, f"{chain.name} (drag the target, tick 'servo to the target')",
               step, dt)
    return 0


# --------------------------------------------------------------------------- parser
#: Control periods ``ratectl demo --dt`` accepts [s].
DEMO_DT_RANGE = (5e-4, 1e-2)
#: Grid points per axis ``ratectl scan --resolution`` accepts.
RESOLUTION_RANGE = (2, 1001)
#: Largest ``ratectl scan --samples``.
MAX_SAMPLES = 100_000_000


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error: ``ratectl CMD: error: ...`` (no usage block)."""

    def error(self, message: str) -> NoReturn:  # noqa: D102 - argparse's hook
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return v


def _int_in(lo: int, hi: int | None, what: str):
    def parse(text: str) -> int:
        try:
            v = int(text.replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number ({what})") from None
        if v < lo or (hi is not None and v > hi):
            allowed = f"at least {lo}" if hi is None else f"from {lo} to {hi}"
            raise argparse.ArgumentTypeError(f"{what} must be {allowed}, got {v}")
        return v

    parse.__name__ = what
    return parse


def _demo_arms():
    from .demo import DEMO_ARMS

    return DEMO_ARMS


def _view_args(sp: argparse.ArgumentParser) -> None:
    """The options of a command that serves the browser view."""
    sp.add_argument("--port", type=_int_in(0, 65535, "a port"), default=None,
                    help="TCP port of the view (default: a free one; the address is printed)")
    sp.add_argument("--seconds", type=_finite_float, default=None,
                    help="stop the view after this many seconds (default: run until Ctrl-C)")


def _arm_args(sp: argparse.ArgumentParser, arms: str, *, with_q: bool) -> None:
    """The ARM argument (and, ``with_q``, the configuration options) of a command."""
    sp.add_argument("arm", metavar="ARM", help=f"built-in arm ({arms}) or a .urdf/.xml file")
    sp.add_argument("--tip", help="tool link (URDF) or body (MJCF) when ARM is a file")
    if with_q:
        sp.add_argument("--q", nargs="+", default=["zero"], metavar="VALUE",
                        help="joint positions, one per joint, in rad (m for prismatic joints); "
                             "'pi/2' style values are accepted; or one word: zero (default), mid "
                             "(middle of the limits), random")
        sp.add_argument("--deg", action="store_true", help="revolute values of --q are in degrees")
        sp.add_argument("--seed", type=_int_in(0, None, "a seed"), default=None,
                        help="seed for --q random (a whole number >= 0)")


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of the ``ratectl`` command."""
    arms = ", ".join(robots.BUILTIN)
    p = _Parser(
        prog="ratectl",
        description="Resolved-rate motion control for serial robot arms: Jacobians, singularity "
                    "analysis, damped and QP inverse velocity, path following with a path-speed "
                    "governor.",
        epilog=f"Built-in arms: {arms}. ARM may also be a .urdf or MJCF .xml file. "
               "Run 'ratectl COMMAND --help' for the options of a command.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    sp = sub.add_parser(
        "demo", help="compare five methods on a line past a wrist singularity (the main demo)",
        description="Follow a straight line at constant orientation that passes 0.01 rad from the "
                    "UR5e's wrist singularity (wrist_2 = 0) with the exact inverse, fixed-damping "
                    "DLS, adaptive DLS, the QP and ratectl's path-speed governor. Prints a table of "
                    "joint speed and acceleration relative to the limits, path error, duration and "
                    "completion, and writes a plot.")
    sp.add_argument("--arm", default="ur5e", choices=sorted(_demo_arms()),
                    help="arm with a prepared scenario (default ur5e)")
    sp.add_argument("--out", default="ratectl_demo.png", help="plot file (default ratectl_demo.png)")
    sp.add_argument("--no-plot", action="store_true", help="print the table only")
    sp.add_argument("--dt", type=_finite_float, default=1e-3,
                    help=f"control period in seconds, {DEMO_DT_RANGE[0]:g} to {DEMO_DT_RANGE[1]:g} "
                         "(default 0.001)")
    sp.add_argument("--fast", action="store_true", help="coarser period (2 ms) for a quicker run")
    sp.add_argument("--view", action="store_true",
                    help="replay the five methods side by side in the browser (needs the view extra)")
    _view_args(sp)
    sp.set_defaults(func=_cmd_demo)

    sp = sub.add_parser(
        "view", help="the arm live in the browser: joint sliders, singularity report, drag-to-servo",
        description="Serve a 3-D view of the arm on this machine (open the printed address in a "
                    "browser): move the joints with sliders, read sigma_min and the kind of "
                    "singularity with arrows along the lost directions, and tick 'servo to the "
                    "target' to make the arm follow the target you drag (resolved-rate control "
                    "at 100 Hz). Needs the view extra: pip install -e '.[view]'.")
    _arm_args(sp, arms, with_q=True)
    sp.add_argument("--servo", action="store_true", help="start with servo to the target on")
    _view_args(sp)
    sp.set_defaults(func=_cmd_view)

    sp = sub.add_parser("info", help="describe an arm: DH table, limits, structure",
                        description="Print an arm's kinematic table, joint limits, reach, "
                                    "characteristic length and wrist structure.")
    _arm_args(sp, arms, with_q=False)
    sp.set_defaults(func=_cmd_info)

    sp = sub.add_parser("jacobian", help="tool pose and geometric Jacobian at q",
                        description="Print the tool pose and the 6xn geometric Jacobian (rows "
                                    "[v; w]) at the joint positions --q, with its singular values.")
    _arm_args(sp, arms, with_q=True)
    sp.add_argument("--frame", choices=["base", "tool"], default="base",
                    help="axes of the Jacobian rows (default base)")
    sp.add_argument("--point", nargs=3, type=_finite_float, metavar=("X", "Y", "Z"),
                    help="reference point for the linear rows, tool-frame coordinates in m")
    sp.set_defaults(func=_cmd_jacobian)

    sp = sub.add_parser("singularity", help="singularity analysis at q: kind, reason, lost directions",
                        description="Analyse the configuration --q: rank, singular values, "
                                    "manipulability, kind of singularity (wrist, elbow, shoulder, "
                                    "boundary, ...), a plain-language reason, lost task directions "
                                    "and joint-space null vectors.")
    _arm_args(sp, arms, with_q=True)
    sp.set_defaults(func=_cmd_singularity)

    sp = sub.add_parser("scan", help="singularity statistics over random configurations",
                        description="Sample random configurations within the joint limits and report "
                                    "percentiles of sigma_min and manipulability and how many are "
                                    "near each kind of singularity. --plot also draws a map of "
                                    "sigma_min over two joints.")
    _arm_args(sp, arms, with_q=False)
    sp.add_argument("--samples", type=_int_in(1, MAX_SAMPLES, "the number of samples"), default=100_000,
                    help="number of configurations (default 100000)")
    sp.add_argument("--seed", type=_int_in(0, None, "a seed"), default=0,
                    help="random seed, a whole number >= 0 (default 0)")
    sp.add_argument("--plot", metavar="FILE", help="write a workspace map (PNG) to FILE")
    sp.add_argument("--joints", nargs=2, default=None, metavar=("I", "J"),
                    help="the map's two joints: joint names, or 0-based indices (default 2 4 on arms "
                         "with 5 or more joints, else 0 1)")
    sp.add_argument("--range", nargs=4, default=None, metavar=("I_LO", "I_HI", "J_LO", "J_HI"),
                    dest="map_range",
                    help="the map's range of each joint in rad (m for prismatic joints), 'pi/2' style "
                         "values accepted (default: the joints' limits; -pi..pi without limits)")
    sp.add_argument("--resolution", type=_int_in(*RESOLUTION_RANGE, "the resolution"), default=121,
                    help=f"map grid points per axis, {RESOLUTION_RANGE[0]} to {RESOLUTION_RANGE[1]} "
                         "(default 121)")
    sp.set_defaults(func=_cmd_scan)
    return p


def _is_option(token: str) -> bool:
    """An option name (``--x``, ``-h``), not a joint value such as ``-1.2``, ``-pi/2`` or ``-nan``
    (every short option of ``ratectl`` is ``-h``)."""
    return token.startswith("--") or token == "-h"


def _is_arm(token: str) -> bool:
    key = token.lower().replace("-", "").replace("_", "")
    return (key in {k.replace("_", "") for k in robots.BUILTIN}
            or Path(token).suffix.lower() in (".urdf", ".xml", ".mjcf"))


def _join_q(argv: list[str]) -> list[str]:
    """Rewrite ``--q v1 v2 ...`` as ``--q=v1,v2,...`` so that values such as ``-pi/2``
    are not mistaken for options by argparse.

    Every token up to the next option is a value (so that a malformed last value is
    reported by the value parser, naming it), except a trailing arm name or model file
    when the positional ``ARM`` comes after ``--q``.
    """
    out: list[str] = []
    i = 0
    while i < len(argv):
        tok = argv[i]
        if tok == "--q":
            vals = []
            i += 1
            while i < len(argv) and not _is_option(argv[i]):
                vals.append(argv[i])
                i += 1
            if len(vals) > 1 and _is_arm(vals[-1]) and not any(_is_arm(t) for t in out[1:]):
                i -= 1
                vals.pop()
            out.append("--q=" + ",".join(vals) if vals else tok)
            continue
        out.append(tok)
        i += 1
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``ratectl`` command with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    Usage errors exit with code 2 (argparse's convention) and a one-line message on stderr;
    so do ratectl errors (bad joint values, unknown arms, unreadable model files, output
    paths that cannot be written, which are checked before any work). Other failures
    (out of memory, a write that fails midway, an internal error) print one line and exit
    with code 1; set ``RATECTL_DEBUG=1`` to see the traceback of an internal error.
    """
    parser = build_parser()
    argv = _join_q(list(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (_Fail, RatectlError, InputError) as exc:
        print(f"ratectl {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ratectl: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `ratectl scan ... | head`
        return 0
    except OSError as exc:  # e.g. the disk filled up while writing a plot
        print(f"ratectl {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except MemoryError:
        print(f"ratectl {args.command}: error: out of memory (ask for fewer samples or a coarser grid)",
              file=sys.stderr)
        return 1
    except Exception as exc:
        if os.environ.get("RATECTL_DEBUG"):
            raise
        print(f"ratectl {args.command}: internal error: {type(exc).__name__}: {_one_line(exc)} "
              "(please report it; RATECTL_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
