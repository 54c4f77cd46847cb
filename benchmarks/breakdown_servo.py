"""Where a servo step's time goes: the kinematics and dense linear algebra it calls, and the rest.

The loop of ``bench_servo.py`` (UR5e, the QP solver, a target on a 5 cm circle at 0.2 m/s,
dt = 1 ms, ``cmd = ctrl.step(q, target=T_t, dt); q = cmd.q_next``), run once while counting
per step the calls of the primitives every step is built on:

* ``Chain.fk_jacobian`` and ``Chain.jacobian`` (the generated kernel and its array);
* the SVDs of the singularity watch (``thin_svd``: σ_min, the share of the direction in the
  weakest singular direction; ``svd_values``: σ_min one small step and one joint step ahead);
* the Cholesky solves and the symmetric eigenvalues of the direction and the feedback
  (LAPACK ``dposv``, ``dpotrs``, ``dsyev`` through SciPy).

Steps are split by whether the watch ran (σ_min below its threshold, 4 × ``stop_sigma``).
Each primitive's cost per call is then timed alone on the loop's own Jacobians, and for
each kind of step the table gives: the median time of the step (this thread's CPU time,
gc enabled), the calls per step, their summed cost (the **floor** of a step that makes
those calls through NumPy and SciPy), and the rest (Python between the calls, small NumPy
arithmetic, the command). Beside it, half of mink + daqp's median step on the same targets
(``bench_servo.py``'s peer) when mink is installed.

Run:  python benchmarks/breakdown_servo.py [--steps N] [--update-docs] [--figure PATH]

``--update-docs`` writes the table into docs/benchmarks.md between the
``breakdown_servo.py --update-docs`` markers; ``--figure PATH`` draws each kind of step's
median as its calls (kinematics, SVDs, Cholesky and eigenvalues) and the rest, beside the
cost goal.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _timing import machine, update_docs  # noqa: E402
from bench_controller import DT, Q0, MinkLoop  # noqa: E402
from bench_servo import circle_targets, mink_target_loop  # noqa: E402

import ratectl as rc  # noqa: E402
import ratectl.control.progress_stage as _stage  # noqa: E402
import ratectl.solvers.base as _base  # noqa: E402
import ratectl.solvers.qp.qp as _qp  # noqa: E402
from ratectl.model.chain import Chain  # noqa: E402

PRIMITIVES = ("fk_jacobian", "jacobian", "thin_svd", "svd_values", "dposv", "dpotrs", "dsyev")


class Counter:
    """Counts calls of the primitives while installed (module globals and Chain methods)."""

    def __init__(self) -> None:
        self.n = dict.fromkeys(PRIMITIVES, 0)
        self._undo: list = []

    def _wrap(self, owner, attr: str, key: str) -> None:
        orig = getattr(owner, attr)
        n = self.n

        def counted(*a, **k):
            n[key] += 1
            return orig(*a, **k)

        setattr(owner, attr, counted)
        self._undo.append((owner, attr, orig))

    def __enter__(self) -> Counter:
        self._wrap(Chain, "fk_jacobian", "fk_jacobian")
        self._wrap(Chain, "jacobian", "jacobian")
        self._wrap(_stage, "thin_svd", "thin_svd")
        self._wrap(_stage, "svd_values", "svd_values")
        for mod in (_base, _qp):
            self._wrap(mod, "_dposv", "dposv")
            self._wrap(mod, "_dpotrs", "dpotrs")
        self._wrap(_base, "_dsyev", "dsyev")
        return self

    def __exit__(self, *exc) -> None:
        for owner, attr, orig in reversed(self._undo):
            setattr(owner, attr, orig)

    def snapshot(self) -> dict[str, int]:
        return dict(self.n)


STAGES = ("gate: validate + check", "servo: fk_jacobian", "servo: direction + feedback solve",
          "servo: the rest (segment, pose errors, progress bounds, watch, advance)", "limiter",
          "integration (q_next, q̈)", "arrival status", "command (state, Command)")


class StageTimer:
    """Times the stages of a controller's cycle (this thread's CPU time per call, summed per
    stage), by wrapping the controller's stage objects and methods in place: the gate, the
    servo (its fk_jacobian and its solver call timed apart), the limiter, the integration
    (``_smooth``), the arrival status and the command. What a reading of the clock itself
    costs (``tick``, the median of two readings in a row) is taken off every timed call."""

    def __init__(self, ctrl, clock) -> None:
        self.t = dict.fromkeys(STAGES, 0.0)
        t, clk = self.t, clock
        tick = self.tick = statistics.median(-clk() + clk() for _ in range(2001))

        def timed(f, key, acc=t):
            """``f`` timed, its calls' time summed into ``acc[key]``."""
            def call(*a, **k):
                t0 = clk()
                try:
                    return f(*a, **k)
                finally:
                    acc[key] += clk() - t0 - tick
            return call

        class Proxy:
            def __init__(self, obj, methods):
                self._obj, self._methods = obj, methods

            def __getattr__(self, name):
                attr = getattr(self._obj, name)
                key = self._methods.get(name)
                return attr if key is None else timed(attr, key)

        gate = STAGES[0]
        ctrl._gate = Proxy(ctrl._gate, {"validate": gate, "check": gate})
        ctrl._limiter = Proxy(ctrl._limiter, {"limit": STAGES[4]})
        ctrl._smooth = timed(ctrl._smooth, STAGES[5])
        ctrl._command = timed(ctrl._command, STAGES[7])
        servo = ctrl._servo
        inner = {"fk": 0.0}
        # (an instance attribute: this chain only)
        ctrl.chain.fk_jacobian = timed(ctrl.chain.fk_jacobian, "fk", inner)
        ctrl._progress._direction_twist = timed(ctrl._progress._direction_twist, STAGES[2])

        def servo_step(*a, **k):
            inner["fk"] = 0.0
            d0 = t[STAGES[2]]
            t0 = clk()
            try:
                return servo.step(*a, **k)
            finally:
                total = clk() - t0 - tick
                t[STAGES[1]] += inner["fk"]
                # (the two inner timers' own readings: two ticks each)
                t[STAGES[3]] += total - inner["fk"] - (t[STAGES[2]] - d0) - 4.0 * tick

        proxy = Proxy(servo, {"arrival": STAGES[6]})
        proxy.step = servo_step
        ctrl._servo = proxy

    def snapshot(self) -> dict[str, float]:
        return dict(self.t)


def unit_costs(arm, qs: list[np.ndarray], clock) -> dict[str, float]:
    """Median cost of one call of each primitive [µs], on the loop's own configurations."""
    Js = [arm.jacobian(q) for q in qs]
    P = [J.T @ J + 0.05 ** 2 * np.eye(J.shape[1]) for J in Js]
    F = [_base._dpotrf(p)[0] for p in P]
    b = [np.ones(J.shape[1]) for J in Js]
    lap = _base._lapack
    cases = {
        "fk_jacobian": lambda i: arm.fk_jacobian(qs[i]),
        "jacobian": lambda i: arm.jacobian(qs[i]),
        "thin_svd": lambda i: _base.thin_svd(Js[i]),
        "svd_values": lambda i: _base.svd_values(Js[i]),
        "dposv": lambda i: lap.dposv(P[i], b[i]),
        "dpotrs": lambda i: lap.dpotrs(F[i], b[i]),
        "dsyev": lambda i: lap.dsyev(P[i], compute_v=0),
    }
    out = {}
    m = len(qs)
    for name, f in cases.items():
        rounds = []
        for _ in range(7):
            t0 = clock()
            for i in range(m):
                f(i)
            rounds.append((clock() - t0) / m)
        out[name] = statistics.median(rounds) * 1e6
    return out


def median_of_runs(ctrl, targets, measure) -> np.ndarray:
    """Per step, the median of what ``measure(k, T_k, q) -> (q_next, values)`` gives over
    three runs of the loop from Q0 (after one warm-up run)."""
    runs = []
    for r in range(4):
        ctrl.reset()
        q = Q0.copy()
        out = []
        for k, T in enumerate(targets):
            q, values = measure(k, T, q)
            out.append(values)
        if r > 0:
            runs.append(np.array(out, dtype=float))
    return np.median(runs, axis=0)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000, help="steps of the loop (default 3000)")
    ap.add_argument("--update-docs", action="store_true", help="write the table into docs/benchmarks.md")
    ap.add_argument("--figure", help="draw the split of a step into this PNG file")
    args = ap.parse_args(argv)
    clock = time.thread_time
    arm = rc.robots.ur5e()
    targets = circle_targets(arm, args.steps)
    ctrl = rc.ResolvedRateController(arm, solver=rc.solvers.QP())
    watch = ctrl._progress.bounds.watch_sigma

    # the calls of each step (one counted run), then the times (runs without the counters)
    per_step: list[dict[str, int]] = []
    qs: list[np.ndarray] = []
    with Counter() as c:
        ctrl.reset()
        q = Q0.copy()
        for T in targets:
            before = c.snapshot()
            cmd = ctrl.step(q, target=T, dt=DT)
            after = c.snapshot()
            per_step.append({k: after[k] - before[k] for k in PRIMITIVES})
            qs.append(q)
            q = cmd.q_next
    def timed_step(k, T, q):
        t0 = clock()
        q_next = ctrl.step(q, target=T, dt=DT).q_next
        return q_next, clock() - t0

    times = median_of_runs(ctrl, targets, timed_step) * 1e6
    unit = unit_costs(arm, qs[:: max(1, len(qs) // 200)], clock)

    # the stages, on a controller of its own (the wrappers stay on it)
    staged = rc.ResolvedRateController(rc.robots.ur5e(), solver=rc.solvers.QP())
    timer = StageTimer(staged, clock)

    def staged_step(k, T, q):
        before = timer.snapshot()
        q_next = staged.step(q, target=T, dt=DT).q_next
        after = timer.snapshot()
        return q_next, [after[s] - before[s] for s in STAGES]

    stage_times = median_of_runs(staged, targets, staged_step) * 1e6

    watched = np.array([s["thin_svd"] > 0 for s in per_step])
    rows = []  # (name, share of the steps, p50, floor, calls per step)
    for name, sel in (("every step", np.ones_like(watched)), ("the watch ran", watched),
                      ("the watch was not needed", ~watched)):
        if not sel.any():
            continue
        idx = np.flatnonzero(sel)
        calls = {k: float(np.mean([per_step[i][k] for i in idx])) for k in PRIMITIVES}
        floor = sum(calls[k] * unit[k] for k in PRIMITIVES)
        rows.append((name, float(sel.mean()), float(np.median(times[idx])), floor, calls,
                     np.mean(stage_times[idx], axis=0)))
    half = None
    try:
        peer: MinkLoop | None = MinkLoop(arm)
    except ImportError:
        peer = None
    if peer is not None:
        mink_target_loop(peer, targets[:300], clock)
        half = 0.5 * statistics.median(float(np.median(mink_target_loop(peer, targets, clock)[0]))
                                       for _ in range(3))
    text = markdown(rows, unit, half, watch, args.steps)
    print(text)
    if args.update_docs:
        update_docs("breakdown_servo.py", text)
    if args.figure:
        figure(rows, unit, half, args.figure)


def figure(rows: list, unit: dict[str, float], half: float | None, path: str) -> None:
    """Horizontal bars, one per kind of step: its median split into the calls' cost, by kind
    of call, and the rest; the cost goal as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = (("kinematics (fk_jacobian, jacobian)", ("fk_jacobian", "jacobian"), "#4c72b0"),
              ("SVDs of the singularity watch", ("thin_svd", "svd_values"), "#dd8452"),
              ("Cholesky solves, eigenvalues", ("dposv", "dpotrs", "dsyev"), "#55a868"),
              ("the rest: Python and small NumPy arithmetic", (), "#b0b0b0"))
    fig, ax = plt.subplots(figsize=(9.0, 2.8), dpi=100)
    labels = [r[0] for r in rows]
    for y, (_name, _share, p50, floor, calls, _stages) in enumerate(rows):
        left = 0.0
        for label, keys, color in groups:
            width = sum(calls[k] * unit[k] for k in keys) if keys else p50 - floor
            ax.barh(y, width, left=left, color=color, label=label if y == 0 else None)
            left += width
        ax.text(left + 0.8, y, f"{p50:.0f} µs", va="center", fontsize=9)
    if half is not None:
        ax.axvline(half, color="#c44e52", linestyle="--", linewidth=1.5,
                   label=f"the goal: half of mink + daqp ({half:.0f} µs)")
    ax.set_yticks(range(len(rows)), labels)
    ax.invert_yaxis()
    ax.set_xlabel("median time of a servo step [µs] (UR5e, QP, moving target, dt = 1 ms)")
    ax.set_xlim(0.0, max(r[2] for r in rows) * 1.12)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.3), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path)
    print(f"wrote {path}")


def markdown(rows: list, unit: dict[str, float], half: float | None, watch: float, steps: int) -> str:
    out = [f"Measured by `benchmarks/breakdown_servo.py` on {machine()}: UR5e, QP, {steps} steps of "
           f"`bench_servo.py`'s moving target, dt = 1 ms; the watch runs below σ_min = {watch:.3g}.",
           "",
           "| steps | share | p50 [µs] | the calls [µs] | the rest [µs] | calls per step |",
           "|---|---|---|---|---|---|"]
    for name, share, p50, floor, calls, _ in rows:
        shown = ", ".join(f"{k} {v:.2f}" for k, v in calls.items() if v > 0.005)
        out.append(f"| {name} | {share:.0%} | {p50:.1f} | {floor:.1f} | {p50 - floor:.1f} | {shown} |")
    out.append("")
    out.append("| stage of the cycle, mean per step [µs] | " + " | ".join(r[0] for r in rows) + " |")
    out.append("|---|" + "---|" * len(rows))
    for i, stage in enumerate(STAGES):
        out.append(f"| {stage} | " + " | ".join(f"{r[5][i]:.1f}" for r in rows) + " |")
    out.append("| (sum of the stages: the step with the wrappers' calls) | "
               + " | ".join(f"{float(np.sum(r[5])):.1f}" for r in rows) + " |")
    out.append("")
    out.append("One call [µs]: " + ", ".join(f"`{k}` {v:.2f}" for k, v in unit.items()) + ".")
    if half is not None:
        out.append(f"Half of mink + daqp's median step on the same targets (the cost goal): {half:.1f} µs.")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    main()
