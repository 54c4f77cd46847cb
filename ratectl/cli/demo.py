"""The singular-crossing line demo: five ways to follow one line past a wrist singularity.

This is what ``ratectl demo`` and ``examples/02_wrist_singularity_line.py`` run.
A straight line at constant orientation passes close to the wrist singularity of a
6-joint arm (closest approach |q5| ≈ 0.01 rad on the UR5e). Along it, the exact
inverse needs joint speeds of order ‖ξ‖/σ_min. Five methods follow the same line:

* ``exact inverse`` — q̇ = J⁻¹ξ, unlimited;
* ``DLS`` — fixed damping λ = 0.05, unlimited;
* ``adaptive DLS`` — σ_min-scheduled damping (ε = λ_max = 0.05), unlimited;
* ``QP`` — the DLS cost with λ = 0.001 and the joint velocity, position and acceleration
  limits as constraints;
* ``governor`` — `ratectl.follow` with its path-speed governor (the default).

The first four run the textbook resolved-rate loop on the nominal time law
``s(t)``: ``ξ = ξ_path(t) + K·e``, ``q̇ = solver(J, ξ)``, ``q ← q + q̇·dt`` (explicit
Euler). The governor instead slows the progress along the path so that the joint
velocities and accelerations stay within limits.

For each method the comparison reports the largest ``|q̇_i|/vmax_i`` and
``|q̈_i|/amax_i`` (> 1 means a limit is exceeded), the largest distance of the tool
from the line [mm] and from the path orientation [deg], the duration, and whether the
end pose was reached (within 1 mm and 0.1°). "On the path" means within 1 mm and 0.5°
everywhere.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, RatectlError, SingularityError
from ..model import robots
from ..planning import ik
from ..spatial import pose_error, rotation_angle, so3_exp

if TYPE_CHECKING:
    from ..solvers.base import Solver

if TYPE_CHECKING:
    from ..model import Chain
    from ..paths import Line

__all__ = ["Scenario", "MethodResult", "Comparison", "wrist_line", "run_fixed_law",
           "run_governor", "compare", "format_table", "plot_comparison", "METHODS", "DEMO_ARMS"]

#: Method names in table order.
METHODS = ("exact inverse", "DLS", "adaptive DLS", "QP", "governor")

#: Arms with a prepared wrist-singular line: name -> (constructor, q at closest approach).
#: q5 = 0.01 rad is 0.01 rad away from the wrist singularity q5 = 0; the line stays clear
#: of the joint position limits and of the other singularities.
DEMO_ARMS = {
    "ur5e": (robots.ur5e, (0.3, -1.3, 1.6, -1.9, 0.01, 0.2)),
}

#: Solver parameters of the comparison: the library defaults for DLS and adaptive DLS
#: (λ = λ_max = 0.05, ε = 0.05); the QP with a small λ, so that it tracks the twist exactly
#: wherever the limits allow (it equals DLS with the same λ when no limit binds).
DLS_DAMPING = 0.05
ADAPTIVE_EPSILON = 0.05
QP_DAMPING = 1e-3

_END_POSITION_TOL = 1e-3     # [m] "completed" = reached the end pose within these
_END_ANGLE_TOL = math.radians(0.1)
_PATH_POSITION_TOL = 1e-3    # [m] "on the path" = within these of the line everywhere
_PATH_ANGLE_TOL = math.radians(0.5)


@dataclass(frozen=True)
class Scenario:
    """A line past a wrist singularity.

    Attributes:
        chain: the arm.
        path: a `ratectl.paths.Line` at constant orientation.
        q0: joint positions at the start of the line (n,) [rad].
        q_closest: joint positions at the closest approach (n,) [rad].
        exact_speed: the largest joint speed the exact inverse needs along the line
            at the path's cruise speed, from a fine continuation [rad/s].
        min_q5: the smallest |q5| along the line [rad].
    """

    chain: Chain
    path: Line
    q0: np.ndarray
    q_closest: np.ndarray
    exact_speed: float
    min_q5: float


@dataclass(frozen=True)
class MethodResult:
    """One method's run along the scenario's line.

    Attributes:
        method: the method name (one of `METHODS`).
        t: times (N,) [s].
        q: joint positions (N, n) [rad].
        qd: joint velocities (N, n) [rad/s].
        qdd: joint accelerations (N, n) [rad/s²], backward differences of qd.
        position_error: distance of the tool origin from the line (N,) [m].
        orientation_error: angle between the tool and the path orientation (N,) [rad].
        max_velocity_ratio: max over time and joints of |q̇_i|/vmax_i.
        max_acceleration_ratio: max over time and joints of |q̈_i|/amax_i.
        max_position_error: the largest position error [m].
        max_orientation_error: the largest orientation error [rad].
        duration: time from which the tool stays at the end pose (within 1 mm and 0.1°),
            or the last time if it never gets there [s].
        nominal: the time law's duration [s].
        completed: the end pose was reached within 1 mm and 0.1°.
        note: what stopped or limited the method, if anything.
        wall_time: computing time of the run [s].
    """

    method: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    max_velocity_ratio: float
    max_acceleration_ratio: float
    max_position_error: float
    max_orientation_error: float
    duration: float
    nominal: float
    completed: bool
    note: str = ""
    wall_time: float = 0.0

    @property
    def within_limits(self) -> bool:
        """|q̇| ≤ vmax and |q̈| ≤ amax at every step (1e-6 relative slack)."""
        return self.max_velocity_ratio <= 1 + 1e-6 and self.max_acceleration_ratio <= 1 + 1e-6


@dataclass(frozen=True)
class Comparison:
    """All methods on one scenario (see `compare`)."""

    scenario: Scenario
    results: tuple[MethodResult, ...]
    dt: float
    info: dict = field(default_factory=dict)

    def __getitem__(self, method: str) -> MethodResult:
        for r in self.results:
            if r.method == method:
                return r
        raise KeyError(f"no result for method {method!r}; have {[r.method for r in self.results]}")


# --------------------------------------------------------------------------- scenario
def _on_line(chain, T_des, q):
    """Newton continuation step: the configuration at T_des from the previous one (undamped)."""
    return np.array(ik(chain, T_des, q, tol=1e-12, max_iter=30, damping=1e-9, max_step=math.inf).q)


def wrist_line(arm: str = "ur5e", *, half_length: float = 0.15, speed: float = 0.2,
               acceleration: float = 1.0, steps: int = 1500) -> Scenario:
    """A constant-orientation line past the wrist singularity of a built-in arm.

    Construction: at the prepared configuration ``q_c`` (|q5| = 0.01 rad, see
    `DEMO_ARMS`) the line direction ``d`` is the unit translation that makes the
    exact inverse fastest, the top right singular vector of the first three columns of
    ``J(q_c)⁻¹`` (maximises ‖J⁻¹[d; 0]‖). The line runs from ``p_c − h·d`` to
    ``p_c + h·d`` at the orientation of ``q_c``. The start configuration ``q0`` and the
    exact-inverse speed are found by Newton continuation along the line (``steps``
    points per half).

    Args:
        arm: a key of `DEMO_ARMS`.
        half_length: h [m].
        speed: the time law's cruise speed [m/s] (trapezoidal law).
        acceleration: the time law's acceleration [m/s²].
        steps: continuation points per half line.
    """
    if arm not in DEMO_ARMS:
        raise InputError(f"the line demo has prepared scenarios for {sorted(DEMO_ARMS)}, got {arm!r}",
                         argument="arm", value=arm)
    from ..paths import Line

    make, q_closest = DEMO_ARMS[arm]
    chain = make()
    qc = np.array(q_closest, dtype=float)
    Tc, Jc = chain.fk_jacobian(qc)
    Jinv = np.linalg.inv(Jc)
    d = np.linalg.svd(Jinv[:, :3])[2][0]
    T0 = Tc.copy()
    T1 = Tc.copy()
    T0[:3, 3] = Tc[:3, 3] - half_length * d
    T1[:3, 3] = Tc[:3, 3] + half_length * d
    # Newton continuation from q_c back to the start, then forward to the end
    q = qc.copy()
    for lam in np.linspace(0.0, 1.0, steps)[1:]:
        T = Tc.copy()
        T[:3, 3] = Tc[:3, 3] - lam * half_length * d
        q = _on_line(chain, T, q)
    q0 = q.copy()
    on_line = [q0]
    for lam in np.linspace(-1.0, 1.0, 2 * steps)[1:]:
        T = Tc.copy()
        T[:3, 3] = Tc[:3, 3] + lam * half_length * d
        q = _on_line(chain, T, q)
        on_line.append(q)
    qs = np.array(on_line)
    ds = 2 * half_length / (2 * steps - 1)
    exact_speed = float(np.abs(np.diff(qs, axis=0)).max() / ds * speed)
    path = Line(T0, T1, speed=speed, acceleration=acceleration)
    return Scenario(chain=chain, path=path, q0=q0, q_closest=qc, exact_speed=exact_speed,
                    min_q5=float(np.abs(qs[:, 4]).min()))


# --------------------------------------------------------------------------- runs
def _line_progress(path, p) -> np.ndarray:
    """Path parameter s [m] of the nearest point of the line for each tool position (N, 3)."""
    d2 = float(path.dp @ path.dp)
    if d2 == 0.0:
        return np.array([path.closest(x) for x in p])
    lam = np.clip((p - path.p0) @ path.dp / d2, 0.0, 1.0)
    return lam * path.length


def _path_errors(path, T) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each pose of T (N, 4, 4) from the line: position [m] and orientation [rad].

    Vectorised ``path.distance``: the nearest point of the segment, and the angle between
    the tool rotation and the path's rotation there (``R(s) = R0 exp((s/L) w)``).
    """
    p = T[:, :3, 3]
    s = _line_progress(path, p)
    lam = s / path.length if path.length > 0 else np.zeros(len(s))
    pos = np.linalg.norm(p - (path.p0 + lam[:, None] * path.dp), axis=1)
    R_path = path.rot.R0 @ so3_exp(lam[:, None] * path.rot.w)
    ang = rotation_angle(np.swapaxes(R_path, -1, -2) @ T[:, :3, :3])
    return pos, np.asarray(ang)


def _finish(method, chain, path, t, q, qd, dt, *, note="", wall=0.0, pos=None, ang=None,
            duration=None, nominal=None) -> MethodResult:
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    qdd = np.zeros_like(qd)
    if len(qd) > 1:
        qdd[1:] = np.diff(qd, axis=0) / dt
    Tq = chain.fk(q)
    if pos is None or ang is None:
        pos, ang = _path_errors(path, Tq)
    Tend = Tq[-1]
    e_end = pose_error(path.end, Tend)
    completed = bool(np.linalg.norm(e_end[:3]) <= _END_POSITION_TOL
                     and np.linalg.norm(e_end[3:]) <= _END_ANGLE_TOL)
    if duration is None:
        # first time from which the tool stays within the end tolerance (else the last time)
        end_pos = np.linalg.norm(Tq[:, :3, 3] - path.end[:3, 3], axis=1)
        end_ang = rotation_angle(path.end[:3, :3].T @ Tq[:, :3, :3])
        ok = (end_pos <= _END_POSITION_TOL) & (end_ang <= _END_ANGLE_TOL)
        bad = np.flatnonzero(~ok)
        first = 0 if len(bad) == 0 else int(bad[-1]) + 1
        duration = t[first] if first < len(t) else t[-1]
    vr = float(np.max(np.abs(qd) / chain.vmax)) if len(qd) else 0.0
    ar = float(np.max(np.abs(qdd) / chain.amax)) if len(qdd) else 0.0
    return MethodResult(
        method=method, t=t, q=q, qd=qd, qdd=qdd, position_error=np.asarray(pos),
        orientation_error=np.asarray(ang), max_velocity_ratio=vr, max_acceleration_ratio=ar,
        max_position_error=float(np.max(pos)), max_orientation_error=float(np.max(ang)),
        duration=float(duration),
        nominal=path.duration if nominal is None else float(nominal),
        completed=completed, note=note, wall_time=wall)


def run_fixed_law(scenario: Scenario, solver: Solver, *, method: str, dt: float = 1e-3, gain: float = 10.0,
                  settle: float = 2.0, limits: bool = False,
                  progress: Callable[[str], None] | None = None) -> MethodResult:
    """The textbook resolved-rate loop on the nominal time law.

    Every step: ``ξ = ξ_path(t) + gain·e`` with ``e = pose_error(T_path(t), T(q))``,
    ``q̇ = solver.solve(J, ξ).qd``, ``q ← q + q̇·dt``. Runs the time law's duration plus
    ``settle`` seconds holding the end pose (time for a method that fell behind to
    arrive); stops early when the solver raises a
    `SingularityError` (the note says so).

    Args:
        scenario: the line and its start configuration (`wrist_line`).
        solver: any object with ``solve(J, xi, **options)`` returning ``.qd``.
        method: the name for the result.
        dt: step [s].
        gain: feedback K [1/s].
        settle: time after the time law to hold the end pose [s].
        limits: pass the chain's limits, q, the previous q̇ and dt to the solver (the QP
            uses them); otherwise the solver gets no limits.
        progress: called with one line of text when the run ends.
    """
    chain, path = scenario.chain, scenario.path
    n_steps = int(math.ceil((path.duration + settle) / dt))
    q = scenario.q0.copy()
    qd_prev = np.zeros(chain.dof)
    ts, qs, qds = [0.0], [q.copy()], [qd_prev.copy()]
    note = ""
    wall = time.perf_counter()
    for k in range(n_steps):
        t = k * dt
        T, J = chain.fk_jacobian(q)
        xi = path.twist(t) + gain * pose_error(path.pose(t), T)
        try:
            if limits:
                res = solver.solve(J, xi, limits=chain, q=q, qd_prev=qd_prev, dt=dt)
            else:
                res = solver.solve(J, xi)
        except SingularityError as exc:
            note = f"stopped at t = {t:.3f} s: singular (sigma_min = {exc.sigma_min:.2e})"
            break
        qd = res.qd
        if not np.all(np.isfinite(qd)):
            note = f"stopped at t = {t:.3f} s: non-finite joint velocity"
            break
        q = q + qd * dt
        qd_prev = qd
        ts.append(t + dt)
        qs.append(q.copy())
        qds.append(qd.copy())
    wall = time.perf_counter() - wall
    if progress is not None:
        progress(f"{method}: {len(ts) - 1} steps in {wall:.2f} s")
    return _finish(method, chain, path, ts, qs, qds, dt, note=note, wall=wall)


def run_governor(scenario: Scenario, *, dt: float = 1e-3,
                 progress: Callable[[str], None] | None = None) -> MethodResult:
    """Follow the line with `ratectl.follow` and its default path-speed governor."""
    from ..execution import follow

    chain, path = scenario.chain, scenario.path
    wall = time.perf_counter()
    run = follow(chain, path, scenario.q0, dt=dt)
    wall = time.perf_counter() - wall
    if progress is not None:
        progress(f"governor: {len(run.t) - 1} steps in {wall:.2f} s")
    # path errors measured here like for the other methods (distance of fk(q) from the line)
    return _finish("governor", chain, path, run.t, run.q, run.qd, dt, wall=wall)


def _solver(method: str):
    """(solver, pass limits?) for a fixed-time-law method."""
    from .. import solvers

    if method == "exact inverse":
        return solvers.Inverse(velocity_policy=None), False
    if method == "DLS":
        return solvers.DLS(damping=DLS_DAMPING, velocity_policy=None), False
    if method == "adaptive DLS":
        return solvers.AdaptiveDLS(epsilon=ADAPTIVE_EPSILON, max_damping=DLS_DAMPING,
                                   velocity_policy=None), False
    if method == "QP":
        return solvers.QP(damping=QP_DAMPING), True
    raise InputError(f"unknown method {method!r}", argument="method", value=method)


def compare(arm: str = "ur5e", *, dt: float = 1e-3, methods: Sequence[str] = METHODS,
            half_length: float = 0.15, speed: float = 0.2, progress: Callable[[str],
            None] | None = None) -> Comparison:
    """Run every method of ``methods`` on `wrist_line` and collect the results.

    Args:
        arm: a key of `DEMO_ARMS`.
        dt: control period [s].
        methods: a subset of `METHODS`, in the order wanted.
        half_length: half the line's length [m], passed to `wrist_line`.
        speed: the line's cruise speed [m/s], passed to `wrist_line`.
        progress: called with one line of text after each stage (for a progress display).
    """
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise InputError(f"unknown method(s) {unknown}; choose from {list(METHODS)}",
                         argument="methods", value=methods)
    if not (dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt must be a positive time step [s], got {dt!r}", argument="dt", value=dt)
    wall = time.perf_counter()
    scenario = wrist_line(arm, half_length=half_length, speed=speed)
    if progress is not None:
        wrist = scenario.chain.joint_names[4]
        progress(f"scenario: {scenario.chain.name}, line of {2 * half_length:.2f} m at {speed} m/s, "
                 f"closest |{wrist}| = {scenario.min_q5:.4f} rad, exact inverse needs "
                 f"{scenario.exact_speed:.1f} rad/s")
    results = []
    for m in methods:
        if m == "governor":
            results.append(run_governor(scenario, dt=dt, progress=progress))
        else:
            solver, limited = _solver(m)
            results.append(run_fixed_law(scenario, solver, method=m, dt=dt, limits=limited,
                                         progress=progress))
    return Comparison(scenario=scenario, results=tuple(results), dt=dt,
                      info={"wall_time": time.perf_counter() - wall})


# --------------------------------------------------------------------------- output
def _verdict(r: MethodResult) -> str:
    issues = []
    if r.max_velocity_ratio > 1 + 1e-6:
        issues.append(f"exceeds vmax x{r.max_velocity_ratio:.1f}")
    if r.max_acceleration_ratio > 1 + 1e-6:
        issues.append(f"exceeds amax x{r.max_acceleration_ratio:.0f}")
    off = []
    if r.max_position_error > _PATH_POSITION_TOL:
        off.append(f"{r.max_position_error * 1e3:.1f} mm")
    if r.max_orientation_error > _PATH_ANGLE_TOL:
        off.append(f"{math.degrees(r.max_orientation_error):.1f} deg")
    if off:
        issues.append("leaves the path by " + " and ".join(off))
    if not r.completed:
        issues.append("end not reached")
    if r.note:
        issues.append(r.note)
    return "; ".join(issues) if issues else "on the path, within limits"


def format_table(comparison: Comparison) -> str:
    """The comparison as a plain-text table (one row per method)."""
    sc = comparison.scenario
    wrist = sc.chain.joint_names[4]
    head = (f"{sc.chain.name}: line of {sc.path.length:.2f} m at {sc.path.speed:g} m/s, constant "
            f"orientation, closest |{wrist}| = {sc.min_q5:.3f} rad (wrist singularity at {wrist} = 0); "
            f"exact inverse needs {sc.exact_speed:.0f} rad/s, vmax = {np.min(sc.chain.vmax):.2f} rad/s; "
            f"dt = {comparison.dt * 1e3:g} ms")
    cols = ("method", "max|qd|/vmax", "max|qdd|/amax", "path err [mm]", "orient err [deg]",
            "duration [s]", "completed", "verdict")
    rows = []
    for r in comparison.results:
        rows.append((r.method, f"{r.max_velocity_ratio:.2f}", f"{r.max_acceleration_ratio:.2f}",
                     f"{r.max_position_error * 1e3:.3f}", f"{math.degrees(r.max_orientation_error):.3f}",
                     f"{r.duration:.2f}", "yes" if r.completed else "no", _verdict(r)))
    widths = [max(len(c), *(len(row[i]) for row in rows)) for i, c in enumerate(cols)]
    lines = [head, ""]
    lines.append("  ".join(c.ljust(w) for c, w in zip(cols, widths, strict=True)))
    lines.append("  ".join("-" * w for w in widths))
    for row in rows:
        lines.append("  ".join(v.ljust(w) for v, w in zip(row, widths, strict=True)))
    lines.append("")
    lines.append(f"nominal time law {sc.path.duration:.2f} s. Ratios > 1 exceed a limit; 'on the path' = "
                 "within 1 mm and 0.5 deg everywhere; 'completed' = end pose reached within 1 mm and "
                 "0.1 deg.")
    lines.append(f"exact inverse, DLS (lambda = {DLS_DAMPING}), adaptive DLS (epsilon = {ADAPTIVE_EPSILON}, "
                 f"lambda_max = {DLS_DAMPING}): the solver's raw command on the nominal time law; QP "
                 f"(lambda = {QP_DAMPING}): joint velocity, position and acceleration limits as "
                 "constraints; governor: ratectl.follow, which slows the progress along the path.")
    return "\n".join(lines)


def plot_comparison(comparison: Comparison, path: str | os.PathLike[str]) -> str:
    """Plot joint speeds (relative to vmax), path error, wrist joint 4 and progress per method; save a PNG.

    Needs matplotlib (the ``plot`` extra). Returns the file name written.
    """
    try:
        import matplotlib

        if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo"):
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RatectlError("plotting needs matplotlib: pip install matplotlib (or, in ratectl's source tree, "
                           "pip install -e '.[plot]')") from exc
    sc = comparison.scenario
    colours = dict(zip(METHODS, ["tab:red", "tab:orange", "tab:purple", "tab:blue", "tab:green"],
                       strict=True))
    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    ax_v, ax_e, ax_o, ax_q, ax_q5, ax_s = axes.ravel()
    for r in comparison.results:
        c = colours[r.method]
        ax_v.plot(r.t, np.max(np.abs(r.qd) / sc.chain.vmax, axis=1), color=c, label=r.method)
        ax_e.plot(r.t, np.maximum(r.position_error * 1e3, 1e-6), color=c, label=r.method)
        ax_o.plot(r.t, np.degrees(r.orientation_error), color=c, label=r.method)
        ax_q.plot(r.t, r.q[:, 3], color=c, label=r.method)
        ax_q5.plot(r.t, r.q[:, 4], color=c, label=r.method)
        s = _line_progress(sc.path, sc.chain.fk(r.q)[:, :3, 3])
        ax_s.plot(r.t, s / sc.path.length, color=c, label=r.method)
    ax_v.axhline(1.0, color="k", ls="--", lw=1)
    ax_v.set_yscale("log")
    ax_v.set_ylim(1e-2, None)
    ax_v.set_ylabel("max_i |q̇_i| / vmax_i")
    ax_v.set_title("joint speed / limit (dashed: the limit)")
    ax_e.set_yscale("log")
    ax_e.set_ylim(1e-4, None)
    ax_e.set_ylabel("distance from the line [mm]")
    low = [r.method for r in comparison.results if r.max_position_error * 1e3 < 1e-4]
    ax_e.set_title("position error" + (f" ({', '.join(low)}: below 1e-4 mm)" if low else ""))
    ax_o.set_ylabel("orientation error [deg]")
    ax_o.set_title("orientation error (the path keeps it constant)")
    names = sc.chain.joint_names
    ax_q.set_ylabel(f"{names[3]} [rad]")
    ax_q.set_title(f"{names[3]} (turns by ~π past the singularity)")
    ax_q5.axhline(0.0, color="k", ls=":", lw=1)
    ax_q5.set_ylabel(f"{names[4]} [rad]")
    ax_q5.set_title(f"{names[4]} (singular at 0)")
    ax_s.set_ylabel("progress along the line (0 … 1)")
    ax_s.set_title("progress (the governor takes longer)")
    for ax in axes.ravel():
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    ax_v.legend(fontsize=8)
    fig.suptitle(f"{sc.chain.name}: line past the wrist singularity "
                 f"(closest |{names[4]}| = {sc.min_q5:.3f} rad)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return str(path)
