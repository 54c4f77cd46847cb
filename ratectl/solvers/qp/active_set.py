"""Exact primal active-set steps for a box-constrained QP, accepted only with a KKT
certificate, and the polish of an approximate backend answer on its active set.
"""

from __future__ import annotations

import math
from operator import sub as _sub
from typing import Any

import numpy as np
from scipy.linalg import cho_solve
from scipy.linalg import lapack as _lapack
from scipy.optimize import nnls

_dposv = _lapack.dposv
_dot = np.dot
_EYE: dict[int, np.ndarray] = {}


def _box_active_set(P, b, lo, hi, x0, max_iter: int = 4, lists=None):
    """Exact minimiser of ½xᵀPx − bᵀx over lo ≤ x ≤ hi (P positive definite) by a few
    primal active-set steps from the unconstrained minimiser x0 = P⁻¹b.

    With the working set A (joints held at a bound x_A = f) the minimiser is, by the
    Schur complement of P⁻¹,

        x = x0 − P⁻¹E S⁻¹ (x0_A − f),   S = (P⁻¹)_AA,   g = Px − b = −E S⁻¹ (x0_A − f),

    so each step is one Cholesky solve for the held columns P⁻¹E and one small solve of
    size |A| (a division when one joint is held, the common case).
    The working set starts as the bounds x0 violates; free joints that leave the box
    join it, and held joints whose multiplier has the wrong sign (g > 0 at an upper
    bound, g < 0 at a lower one) leave it. When neither happens the KKT conditions hold
    and x is the optimum (the problem is strictly convex).

    Returns (x, state, steps) with state[i] = +1 / −1 / 0 for a joint at its upper /
    lower bound / free, or (None, None, steps) when ``max_iter`` steps do not settle or
    a solve fails (the caller then uses the backend).
    """
    n = x0.shape[0]
    x0l, lol, hil = (x0.tolist(), lo.tolist(), hi.tolist()) if lists is None else lists
    state = [1 if x0l[i] > hil[i] else (-1 if x0l[i] < lol[i] else 0) for i in range(n)]
    kkt = None
    eye = _eye(n)
    for it in range(1, max_iter + 1):
        A = [i for i in range(n) if state[i]]
        if not A:
            # every bound was released: x0 is the answer only if it was feasible to begin
            # with (it = 1); otherwise the working set cycled back to an infeasible point
            return (x0, state, it) if it == 1 else (None, None, it)
        fix = [hil[i] if state[i] > 0 else lol[i] for i in A]
        # only the held columns of P⁻¹ are needed: P⁻¹E from one Cholesky solve
        if len(A) == 1:  # the common case: S is (P⁻¹)_aa, a division
            a = A[0]
            _, col, info = _dposv(P, eye[a])
            caa = float(col[a])
            if info != 0 or not caa > 0.0:  # (P⁻¹)_aa underflows for a huge P
                return None, None, it
            coef = [(x0l[a] - fix[0]) / caa]
            x = x0 - col * coef[0]
        else:
            _, cols, info = _dposv(P, eye[:, A])
            if info != 0:
                return None, None, it
            _, c, info = _dposv(cols[A], np.array([x0l[i] - f for i, f in zip(A, fix, strict=True)]))
            if info != 0:
                return None, None, it
            coef = c.tolist()
            x = x0 - cols.dot(c)
        for i, f in zip(A, fix, strict=True):
            x[i] = f  # held joints sit exactly on their bound
        xl = x.tolist()
        moved = False
        for i in range(n):
            if state[i] == 0:
                if xl[i] > hil[i]:
                    state[i] = 1
                    moved = True
                elif xl[i] < lol[i]:
                    state[i] = -1
                    moved = True
        if moved:
            continue
        if kkt is None:
            kkt = 1e-10 * (1.0 + max(map(abs, b.tolist())))
        for j, i in enumerate(A):
            g = -coef[j]
            if (state[i] > 0 and g > kkt) or (state[i] < 0 and g < -kkt):
                state[i] = 0
                moved = True
        if not moved:
            # the KKT conditions hold: free joints inside their box (checked above), held
            # ones on their bound, every held multiplier of the right sign
            return x, state, it
    return None, None, max_iter


def box_qp_exact(P: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, x_start: Any = None, *,
                 max_iter: int | None = None):
    """The exact minimiser of ½xᵀPx − bᵀx over lo ≤ x ≤ hi (P symmetric positive definite)
    by a primal active-set method that stays feasible (Nocedal & Wright, Algorithm 16.3,
    specialised to bounds).

    From a feasible x (``x_start`` projected into the box) with a working set W of joints
    held at a bound: solve the equality-constrained problem with W fixed,
    P_FF x_F = b_F − P_FW x_W (F the free joints); if that point is feasible, move there
    and drop the held joint whose multiplier has the wrong sign (gradient g = Px − b > 0 at
    an upper bound, < 0 at a lower bound), or stop when none has (the KKT conditions hold:
    x is the unique optimum); otherwise step toward it until the first free joint meets
    its bound and add that joint to W. The objective decreases strictly at every step, so
    no working set repeats; the method ends in finitely many steps.

    A positive semidefinite P (no damping) is handled too: where P_FF is singular the
    face's minimiser is the least-squares one (the objective of a least-squares task is
    bounded below, so it exists).

    Returns (x, state) with state[i] = +1 / −1 / 0 for a joint at its upper / lower
    bound / free, or (None, None) when a solve fails or ``max_iter`` steps (default
    10·n + 20) do not settle.
    """
    n = b.shape[0]
    if max_iter is None:
        max_iter = 10 * n + 20
    x = np.zeros(n) if x_start is None else np.array(x_start, dtype=float)
    x = np.minimum(np.maximum(x, lo), hi)
    state = np.where(x >= hi, 1, np.where(x <= lo, -1, 0))
    scale = 1.0 + float(np.max(np.abs(b))) + float(np.max(np.abs(P))) * float(np.max(np.abs(x)))
    tol = 1e-13 * scale
    for _ in range(max_iter):
        free = state == 0
        xt = np.where(state > 0, hi, np.where(state < 0, lo, x))
        if free.any():
            F = np.flatnonzero(free)
            held = ~free
            rhs = b[F] - (P[np.ix_(F, np.flatnonzero(held))] @ xt[held] if held.any() else 0.0)
            PFF = P[np.ix_(F, F)]
            _, xf, info = _dposv(PFF, rhs)
            if info != 0:  # positive semidefinite (no damping): a least-squares minimiser
                try:
                    xf = np.linalg.lstsq(PFF, rhs, rcond=1e-13)[0]
                except (np.linalg.LinAlgError, ValueError):
                    return None, None
            if not np.all(np.isfinite(xf)):
                return None, None
            xt[F] = xf
        d = xt - x
        # largest step in [0, 1] keeping the free joints inside their box
        with np.errstate(divide="ignore", invalid="ignore"):
            steps = np.where(d > 0, (hi - x) / d, np.where(d < 0, (lo - x) / d, np.inf))
        steps = np.where(free, steps, np.inf)
        j = int(np.argmin(steps))
        alpha = float(steps[j])
        if alpha < 1.0:
            x = x + max(alpha, 0.0) * d
            x[j] = hi[j] if d[j] > 0 else lo[j]
            state[j] = 1 if d[j] > 0 else -1
            x = np.minimum(np.maximum(x, lo), hi)
            continue
        x = np.minimum(np.maximum(xt, lo), hi)
        g = P @ x - b
        wrong = np.where(state > 0, g, np.where(state < 0, -g, -np.inf))
        # a held joint leaves when its multiplier has the wrong sign beyond rounding, on
        # the whole problem's scale or on its own (see kkt_violation)
        own = 1e-3 * np.asarray(_own_scale(P, b, x, float(np.max(np.abs(x)))))
        wrong = wrong / np.minimum(tol, own)
        j = int(np.argmax(wrong))
        if not wrong[j] > 1.0:
            return x, state
        state[j] = 0
    return None, None


def kkt_violation(P: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, x: np.ndarray) -> float:
    """How far x is from the optimum of ½xᵀPx − bᵀx over lo ≤ x ≤ hi, as the largest
    violation of the KKT conditions scaled by the problem's size: bound violation
    max(lo − x, x − hi, 0) and the projected gradient g = Px − b (zero for a free joint,
    ≤ 0 at an upper bound, ≥ 0 at a lower one), relative to 1 + ‖b‖∞ + ‖P‖∞‖x‖∞, and
    each joint's projected gradient in its own units, g_i / (P_ii·(1 + ‖x‖∞) + 10⁻³·r_i)
    with r_i = |b_i| + Σ_j |P_ij x_j| (the size of the terms that make g_i, so rounding
    stays below 1e-12 of it). |g_i| / P_ii is a lower bound of how far joint i would move
    if released: with weights of very different size (1e6 and 1e-6) a wrong-sign
    multiplier can be tiny against ‖P‖∞ and still move the optimum by a large q̇.
    0 at the exact optimum; ratectl accepts an answer below 1e-9 (inf when an input is not
    finite: never accepted).

    It runs on Python floats, one joint at a time (a few joints: cheaper than a dozen numpy
    calls; a control step certifies every active-set answer with it)."""
    if not x.size:
        return 0.0
    xl = x.tolist()
    gl = (P.dot(x) - b).tolist()  # the gradient g = Px − b
    ax = max(map(abs, xl))
    scale = 1.0 + max(map(abs, b.tolist())) + max(map(abs, P.ravel().tolist())) * ax
    t = scale + sum(gl)
    if t - t != 0.0:  # NaN or inf somewhere
        return math.inf
    lol, hil = lo.tolist(), hi.tolist()
    feas = max(0.0, max(map(_sub, lol, xl)), max(map(_sub, xl, hil)))  # bound violation
    gmax = jmax = 0.0
    own = None
    for i, (xi, li, ui, gi) in enumerate(zip(xl, lol, hil, gl, strict=True)):
        eps = 1e-12 * (1.0 + abs(xi))
        if max(ui - li, 0.0) <= eps:  # a fixed joint (lo = hi) has any multiplier
            continue
        if xi >= ui - eps:  # at the upper bound: g ≤ 0
            gv = gi if gi > 0.0 else 0.0
        elif xi <= li + eps:  # at the lower bound: g ≥ 0
            gv = -gi if gi < 0.0 else 0.0
        else:  # free: g = 0
            gv = abs(gi)
        if gv > gmax:
            gmax = gv
        if gv > 0.0:
            if own is None:
                own = _own_scale(P, b, x, ax)
            jv = gv / own[i]
            if jv > jmax:
                jmax = jv
    return max(feas / (1.0 + ax), gmax / scale, jmax)


def _own_scale(P: np.ndarray, b: np.ndarray, x: np.ndarray, ax: float) -> list[float]:
    """Each joint's gradient scale P_ii·(1 + ‖x‖∞) + 10⁻³·(|b_i| + Σ_j |P_ij x_j|) (see
    `kkt_violation`; the floor keeps an all-zero row from dividing by 0)."""
    r = np.abs(b) + np.abs(P).dot(np.abs(x))
    return (np.abs(np.diagonal(P)) * (1.0 + ax) + 1e-3 * r + 1e-300).tolist()


def _eye(n):
    e = _EYE.get(n)
    if e is None:
        e = _EYE[n] = np.eye(n)
        e.setflags(write=False)
    return e


def _polish(P, b, lo, hi, x):
    """Exact solution on the active set of an approximate one (box constraints only).

    Joints within 1e-5 of a bound are fixed there; the others solve
    P_FF x_F = b_F − P_FA x_A. Accepted if the result is inside the box and the KKT signs
    hold (gradient g = Px − b ≤ 0 at upper bounds, ≥ 0 at lower bounds, with a small
    tolerance); otherwise None (keep the backend's solution).
    """
    tol_act = 1e-5 * (1.0 + np.abs(x))
    up = x >= hi - tol_act
    dn = (x <= lo + tol_act) & ~up
    act = up | dn
    xa = np.where(up, hi, np.where(dn, lo, x))
    free = ~act
    if free.any():
        Pff = P[np.ix_(free, free)]
        rhs = b[free] - P[np.ix_(free, act)] @ xa[act]
        _, xf, info = _dposv(Pff, rhs)
        if info != 0:
            return None
        xa[free] = xf
    scale = 1e-12 * (1.0 + float(np.max(np.abs(xa))))
    if np.any(xa > hi + scale) or np.any(xa < lo - scale):
        return None
    g = P @ xa - b
    kkt = 1e-8 * (1.0 + float(np.max(np.abs(b))))
    if np.any(g[up] > kkt) or np.any(g[dn] < -kkt):
        return None
    return np.minimum(np.maximum(xa, lo), hi)


def polish_general(P: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, G: np.ndarray, h: np.ndarray,
                   x: np.ndarray, *, tol_act: float = 1e-6):
    """The exact solution of min ½xᵀPx − bᵀx s.t. lo ≤ x ≤ hi, G x ≤ h on the active set of
    an approximate solution ``x`` (from OSQP), with its certificate; or None.

    Every constraint is written a_iᵀx ≤ c_i (the box as ±e_i rows); those within
    ``tol_act`` (relative) of equality form A x = c. The KKT system
    [P Aᵀ; A 0] [x; μ] = [b; c] is solved (least squares when rows are dependent), and the
    answer is accepted only when it is feasible (1e-9 relative), its multipliers are
    non-negative (μ ≥ −1e-9·scale; with dependent active rows, where μ is not unique, the
    non-negative least-squares μ) and it satisfies the KKT stationarity to 1e-9·scale:
    then it is the optimum (the problem is convex)."""
    n = x.shape[0]
    eye = _eye(n)
    rows = [eye, -eye, G]
    rhs = [hi, -lo, h]
    A = np.vstack(rows)
    c = np.concatenate(rhs)
    fin = np.isfinite(c) & (np.abs(c) < 1e14)
    A, c = A[fin], c[fin]
    slack = c - A @ x
    act = slack <= tol_act * (1.0 + np.abs(c))
    Aa, ca = A[act], c[act]
    k = Aa.shape[0]
    K = np.zeros((n + k, n + k))
    K[:n, :n] = P
    K[:n, n:] = Aa.T
    K[n:, :n] = Aa
    r = np.concatenate([b, ca])
    try:
        sol = np.linalg.lstsq(K, r, rcond=1e-13)[0]
    except (np.linalg.LinAlgError, ValueError):
        return None
    xs = sol[:n]
    scale = 1.0 + float(np.max(np.abs(b))) + float(np.max(np.abs(P))) * (1.0 + float(np.max(np.abs(xs))))
    if not np.all(np.isfinite(xs)):
        return None
    if np.any(A @ xs - c > 1e-9 * (1.0 + np.abs(c))):
        return None
    # stationarity: P x − b + Aᵀμ = 0 with μ ≥ 0
    if k:
        mu = np.linalg.lstsq(Aa.T, b - P @ xs, rcond=1e-13)[0]
        if np.any(mu < -1e-9 * scale):
            # dependent active rows (a fixed joint lo = hi holds both ±e_i, or rows of G
            # that coincide) leave μ undetermined, and the least-norm μ may have a wrong
            # sign although a valid one exists: the non-negative least-squares μ decides
            try:
                mu = nnls(Aa.T, b - P @ xs)[0]
            except (ValueError, RuntimeError):
                return None
        res = P @ xs - b + Aa.T @ mu
    else:
        res = P @ xs - b
    if float(np.max(np.abs(res))) > 1e-9 * scale:
        return None
    return np.minimum(np.maximum(xs, lo), hi)


def _all_rows(lo: np.ndarray, hi: np.ndarray, G: np.ndarray, h: np.ndarray):
    """Every constraint as a row a_iᵀx ≤ c_i: (A, c) = ([I; −I; G], [hi; −lo; h]), without
    the rows whose c is infinite or beyond 1e14 (no constraint in floating point)."""
    eye = _eye(lo.shape[0])
    A = np.vstack([eye, -eye, G])
    c = np.concatenate([hi, -lo, h])
    fin = np.isfinite(c) & (np.abs(c) < 1e14)
    return A[fin], c[fin]


def qp_via_dual(P: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, G: np.ndarray, h: np.ndarray):
    """The exact minimiser of ½xᵀPx − bᵀx s.t. lo ≤ x ≤ hi, G x ≤ h (P positive definite)
    through its dual, a bound-constrained QP solved by `box_qp_exact`; or None.

    With every constraint written a_iᵀx ≤ c_i (A, c), stationarity gives
    x(μ) = P⁻¹(b − Aᵀμ) and the dual is min_{μ ≥ 0} ½μᵀ(AP⁻¹Aᵀ)μ − μᵀ(AP⁻¹b − c): a QP over a
    box (0 ≤ μ), positive semidefinite, which the primal active-set method solves exactly.
    The answer is the exact solution on x(μ)'s active set, returned only with its KKT
    certificate (`polish_general`)."""
    A, c = _all_rows(lo, hi, G, h)
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return None
    PiAt = cho_solve((L, True), A.T)
    x0 = cho_solve((L, True), b)
    H = A @ PiAt
    H = 0.5 * (H + H.T)
    d = A @ x0 - c
    m = c.shape[0]
    mu, _ = box_qp_exact(H, d, np.zeros(m), np.full(m, np.inf), np.zeros(m), max_iter=20 * m + 50)
    if mu is None:
        return None
    x = x0 - PiAt @ mu
    if not np.all(np.isfinite(x)):
        return None
    # the dual's accuracy follows cond(P): finish on x's active set, with the KKT certificate
    return polish_general(P, b, lo, hi, G, h, x, tol_act=1e-5)


def qp_primal_active_set(P: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, G: np.ndarray,
                         h: np.ndarray, *, max_iter: int | None = None):
    """The exact minimiser of ½xᵀPx − bᵀx s.t. lo ≤ x ≤ hi, G x ≤ h (P positive
    semidefinite, the objective bounded on the feasible set) by the primal active-set method
    (Nocedal & Wright, Algorithm 16.3) on all rows a_iᵀx ≤ c_i at once; or None when the
    rows have no common point or the method does not settle. The last resort of the QP when
    OSQP, its polish and the dual fail (degenerate or ill-conditioned problems).

    A feasible start comes from a linear programme (HiGHS, through ``scipy.optimize.linprog``:
    the point that maximises the smallest slack, so it is inside wherever it can be). Each
    iteration solves the equality-constrained step on the working set W,

        [P  A_Wᵀ] [p]   [−(Px − b)]
        [A_W  0 ] [λ] = [    0    ],

    moves along p until the first blocking row (added to W), or, at p = 0, drops the row with
    the most negative multiplier λ; it stops when every λ ≥ 0, which is the KKT certificate
    (x feasible, stationary, multipliers of the right sign) — the optimum of a convex problem.
    """
    from scipy.optimize import linprog

    n = b.shape[0]
    A, c = _all_rows(lo, hi, G, h)
    m = c.shape[0]
    if max_iter is None:
        max_iter = 20 * (n + m) + 50
    # phase 1: max t s.t. A x + t·‖a_i‖ ≤ c, t ≤ 1 (a point as far inside as the rows allow)
    norms = np.sqrt(np.sum(A * A, axis=1))
    res = linprog(np.concatenate([np.zeros(n), [-1.0]]), A_ub=np.hstack([A, norms[:, None]]), b_ub=c,
                  bounds=[(None, None)] * n + [(None, 1.0)], method="highs")
    if res.status != 0 or res.x is None or res.x[-1] < -1e-9:
        return None
    x = np.array(res.x[:n])
    scale_c = 1.0 + np.abs(c)
    W: list[int] = []
    gscale = 1.0 + float(np.max(np.abs(b))) + float(np.max(np.abs(P))) * (1.0 + float(np.max(np.abs(x))))
    for _ in range(max_iter):
        g = P @ x - b
        # the step in the null space Z of the working rows: p = Z·y, (ZᵀPZ) y = −Zᵀg
        if W:
            Aw = A[W]
            _, sv, Vt = np.linalg.svd(Aw)
            rank = int(np.sum(sv > 1e-12 * sv[0]))
            Z = Vt[rank:].T
        else:
            Aw, Z = A[:0], _eye(n)
        if Z.shape[1]:
            try:
                y = np.linalg.lstsq(Z.T @ P @ Z, -(Z.T @ g), rcond=1e-14)[0]
            except (np.linalg.LinAlgError, ValueError):
                return None
            p = Z @ y
        else:
            p = np.zeros(n)
        if not np.all(np.isfinite(p)):
            return None
        # p is zero when it is, or when it would not lower the objective beyond rounding (an
        # ill-conditioned P leaves p ~ 1e-13 where it should vanish; stepping on it cycles)
        gain = -float(g @ p) - 0.5 * float(p @ P @ p)
        fx = abs(0.5 * float(x @ P @ x) - float(b @ x))
        if (float(np.max(np.abs(p))) <= 1e-13 * (1.0 + float(np.max(np.abs(x))))
                or gain <= 1e-13 * (1.0 + fx + gscale * float(np.max(np.abs(p))))):
            if not W:
                return x
            lam = np.linalg.lstsq(Aw.T, -g, rcond=1e-14)[0]  # g + A_Wᵀλ = 0
            if float(lam.min()) >= -1e-12 * gscale:
                return x
            W.pop(int(np.argmin(lam)))
            continue
        Ap = A @ p
        slack = c - A @ x
        block = (Ap > 0.0) & ~np.isin(np.arange(m), W)
        alpha, j = 1.0, -1
        if block.any():
            steps = np.where(block, np.maximum(slack, 0.0) / np.where(block, Ap, 1.0), np.inf)
            j = int(np.argmin(steps))
            if steps[j] < 1.0:
                alpha = float(steps[j])
            else:
                j = -1
        x = x + alpha * p
        if j >= 0:
            W.append(j)
        if np.any(A @ x - c > 1e-9 * scale_c):
            return None
    return None
