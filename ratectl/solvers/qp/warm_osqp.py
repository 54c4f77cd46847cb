"""A warm-started OSQP problem: set up once, updated in place on later steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

_OSQP_DEFAULTS = dict(
    verbose=False,
    eps_abs=1e-7,
    eps_rel=1e-7,
    eps_prim_inf=1e-9,
    eps_dual_inf=1e-9,
    # OSQP 1.x prints "Polishing not needed" on stdout, verbose or not, when the optimum has
    # no active bound: its polishing stays off (ratectl solves the active set exactly itself)
    polishing=False,
    polish_refine_iter=3,
    check_termination=5,
    max_iter=4000,
    warm_starting=True,
)


class _WarmOSQP:
    """One OSQP instance set up for a fixed structure (n, extra rows k) and updated in place."""

    def __init__(self, n: Any, k: Any, P: np.ndarray, c: np.ndarray, G: np.ndarray, h: np.ndarray,
                 lo: np.ndarray, hi: np.ndarray, settings: Any):
        import osqp
        import scipy.sparse as sp

        self.n, self.k = n, k
        r, cidx = np.triu_indices(n)
        order = np.lexsort((r, cidx))  # CSC order: by column, then row
        self.pr, self.pc = r[order], cidx[order]
        Pm = sp.csc_matrix((P[self.pr, self.pc], (self.pr, self.pc)), shape=(n, n))
        if k:
            A = np.vstack([np.eye(n), G])
            # CSC of a dense (n+k)×n with identity on top: column j holds row j, then rows n..n+k-1
            ar = np.concatenate([np.concatenate([[j], n + np.arange(k)]) for j in range(n)])
            ac = np.repeat(np.arange(n), k + 1)
            self.ar, self.ac = ar, ac
            Am = sp.csc_matrix((A[ar, ac], (ar, ac)), shape=(n + k, n))
            l = np.concatenate([lo, np.full(k, -np.inf)])
            u = np.concatenate([hi, h])
        else:
            Am = sp.identity(n, format="csc")
            l, u = lo, hi
        self.osqp = osqp.OSQP()
        self.osqp.setup(Pm, c, Am, np.maximum(l, -1e30), np.minimum(u, 1e30), **settings)
        # the low-level solver avoids the Python wrapper's per-call bookkeeping (~15 µs)
        self._s = getattr(self.osqp, "_solver", None)
        self._lk = np.full(k, -1e30)

    def solve(self, P: np.ndarray, c: np.ndarray, G: np.ndarray, h: np.ndarray, lo: np.ndarray,
              hi: np.ndarray):
        s = self._s
        Px = P[self.pr, self.pc]
        if self.k:
            Ax = np.vstack([np.eye(self.n), G])[self.ar, self.ac]
            l = np.concatenate([lo, self._lk])
            u = np.concatenate([hi, np.minimum(h, 1e30)])
        else:
            Ax = None
            l, u = lo, hi
        if s is not None:
            s.update_data_mat(P_x=Px, P_i=None, A_x=Ax, A_i=None)
            s.update_data_vec(q=c, l=l, u=u)
            s.solve()
            info = s.info
            return s.solution.x, int(info.status_val), str(info.status), int(info.iter), \
                int(info.status_polish)
        kw = dict(Px=Px, q=c, l=l, u=u)
        if Ax is not None:
            kw["Ax"] = Ax
        self.osqp.update(**kw)
        res = self.osqp.solve(raise_error=False)
        return (res.x, int(res.info.status_val), str(res.info.status), int(res.info.iter),
                int(res.info.status_polish))
