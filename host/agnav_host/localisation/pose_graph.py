"""A planar pose graph and its least-squares optimisation (sparse Gauss-Newton with Levenberg damping).

Nodes are poses ``(x_m, y_m, yaw_rad)``; an edge (i, j, z, Omega) says that node j seen from node i is z,
with information matrix Omega (3, 3; the inverse covariance in x m, y m, yaw rad). The error of an edge is
e = z^-1 (+) (x_i^-1 (+) x_j) as (dx, dy, dyaw), and the optimisation minimises the sum of e^T Omega e
over the edges, node 0 held fixed.

Loop-closure edges may be wrong (a corridor that looks like another). They carry dynamic covariance scaling
(Agarwal et al. 2013, "Robust map optimization using dynamic covariance scaling"): an edge whose error
chi^2 = e^T Omega e is large compared with ``phi`` has its information scaled down by
s^2 = min(1, 2 phi / (phi + chi^2))^2, so one bad closure cannot pull the map apart.

The normal equations are sparse (each edge couples two nodes) and solved with SciPy's sparse LU.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..types import FloatArray

__all__ = ["PoseGraph", "Edge", "OptimiseResult"]


@dataclass(frozen=True)
class Edge:
    """Node ``j`` seen from node ``i`` is ``z`` (x m, y m, yaw rad) with information ``info`` (3, 3);
    ``robust``: scaled by dynamic covariance scaling (a loop closure)."""

    i: int
    j: int
    z: FloatArray
    info: FloatArray
    robust: bool = False
    loop: bool = False  # a loop closure (what the caller says it is; the optimisation treats all alike)


@dataclass(frozen=True)
class OptimiseResult:
    """Iterations run, the cost sum(e^T Omega e) (robust edges as scaled) at the start and at the end, and
    how many robust edges end with a scale below 0.5 (taken for wrong)."""

    iterations: int
    cost_start: float
    cost_end: float
    rejected: int


def _wrap(a: FloatArray) -> FloatArray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@dataclass
class PoseGraph:
    """Nodes (``poses``: (n, 3)) and edges; :meth:`optimise` moves the poses in place."""

    poses: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    edges: list[Edge] = field(default_factory=list)
    phi: float = 5.0

    def add_node(self, pose: FloatArray) -> int:
        self.poses = np.vstack([self.poses, np.asarray(pose, dtype=float).reshape(1, 3)])
        return len(self.poses) - 1

    def add_edge(self, i: int, j: int, z: FloatArray, info: FloatArray, robust: bool = False,
                 loop: bool = False) -> None:
        self.edges.append(Edge(i, j, np.asarray(z, dtype=float), np.asarray(info, dtype=float), robust, loop))

    def _arrays(self) -> tuple[np.ndarray, ...]:
        ii = np.array([e.i for e in self.edges], dtype=np.int64)
        jj = np.array([e.j for e in self.edges], dtype=np.int64)
        zz = np.array([e.z for e in self.edges]).reshape(-1, 3)
        om = np.array([e.info for e in self.edges]).reshape(-1, 3, 3)
        rb = np.array([e.robust for e in self.edges], dtype=bool)
        return ii, jj, zz, om, rb

    def _linearise(self, x: FloatArray, ii: np.ndarray, jj: np.ndarray, zz: FloatArray
                   ) -> tuple[FloatArray, FloatArray, FloatArray]:
        xi, xj = x[ii], x[jj]
        ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
        cz, sz = np.cos(zz[:, 2]), np.sin(zz[:, 2])
        dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
        # x_i^-1 x_j
        rx, ry = ci * dx + si * dy, -si * dx + ci * dy
        # z^-1 (x_i^-1 x_j)
        tx, ty = rx - zz[:, 0], ry - zz[:, 1]
        e = np.column_stack([cz * tx + sz * ty, -sz * tx + cz * ty, _wrap(xj[:, 2] - xi[:, 2] - zz[:, 2])])
        m = len(ii)
        # d e / d x_i and d e / d x_j (3 x 3 each)
        a = np.zeros((m, 3, 3))
        b = np.zeros((m, 3, 3))
        # d(rx, ry)/d(xi, yi, thi)
        d_r_xi = np.stack([np.column_stack([-ci, -si, -si * dx + ci * dy]),
                           np.column_stack([si, -ci, -ci * dx - si * dy])], axis=1)  # (m, 2, 3)
        d_r_xj = np.stack([np.column_stack([ci, si, np.zeros(m)]),
                           np.column_stack([-si, ci, np.zeros(m)])], axis=1)
        rz = np.stack([np.column_stack([cz, sz]), np.column_stack([-sz, cz])], axis=1)  # (m, 2, 2)
        a[:, :2, :] = rz @ d_r_xi
        b[:, :2, :] = rz @ d_r_xj
        a[:, 2, 2] = -1.0
        b[:, 2, 2] = 1.0
        return e, a, b

    def _scales(self, e: FloatArray, om: FloatArray, rb: np.ndarray) -> tuple[FloatArray, FloatArray]:
        chi2 = np.einsum("mi,mij,mj->m", e, om, e)
        s = np.ones(len(e))
        if rb.any():
            s[rb] = np.minimum(1.0, 2.0 * self.phi / (self.phi + chi2[rb])) ** 2
        return chi2, s

    def cost(self) -> float:
        if not self.edges:
            return 0.0
        ii, jj, zz, om, rb = self._arrays()
        e, _, _ = self._linearise(self.poses, ii, jj, zz)
        chi2, s = self._scales(e, om, rb)
        return float((s * chi2).sum())

    def optimise(self, iterations: int = 20, tol: float = 1e-6, fixed: int = 0) -> OptimiseResult:
        """Gauss-Newton steps (Levenberg-damped when a step raises the cost) until the relative cost change
        is below ``tol``; node ``fixed`` stays where it is."""
        n = len(self.poses)
        if not self.edges or n < 2:
            return OptimiseResult(0, 0.0, 0.0, 0)
        ii, jj, zz, om, rb = self._arrays()
        m = len(ii)
        x = self.poses.copy()
        e, a, b = self._linearise(x, ii, jj, zz)
        chi2, s = self._scales(e, om, rb)
        cost0 = cost = float((s * chi2).sum())
        lam = 0.0
        # sparsity pattern of H: blocks (i,i), (j,j), (i,j), (j,i) of every edge
        rows3 = np.arange(3)
        it = 0
        for it in range(1, iterations + 1):  # noqa: B007 -- the count is read after the loop
            w = om * s[:, None, None]
            at_w = np.transpose(a, (0, 2, 1)) @ w
            bt_w = np.transpose(b, (0, 2, 1)) @ w
            hii, hij, hjj = at_w @ a, at_w @ b, bt_w @ b
            gi = np.einsum("mij,mj->mi", at_w, e)
            gj = np.einsum("mij,mj->mi", bt_w, e)
            bi, bj = 3 * ii, 3 * jj

            def blocks(r0: np.ndarray, c0: np.ndarray, blk: FloatArray) -> tuple[np.ndarray, ...]:
                r = (r0[:, None, None] + rows3[None, :, None]) + np.zeros((1, 1, 3), dtype=np.int64)
                c = (c0[:, None, None] + rows3[None, None, :]) + np.zeros((1, 3, 1), dtype=np.int64)
                return r.ravel(), c.ravel(), blk.ravel()

            parts = [blocks(bi, bi, hii), blocks(bj, bj, hjj), blocks(bi, bj, hij),
                     blocks(bj, bi, np.transpose(hij, (0, 2, 1)))]
            r = np.concatenate([p[0] for p in parts])
            c = np.concatenate([p[1] for p in parts])
            v = np.concatenate([p[2] for p in parts])
            h = sp.csc_matrix((v, (r, c)), shape=(3 * n, 3 * n))
            g = np.zeros(3 * n)
            np.add.at(g, (bi[:, None] + rows3).ravel(), gi.ravel())
            np.add.at(g, (bj[:, None] + rows3).ravel(), gj.ravel())
            diag = h.diagonal()
            fix = np.zeros(3 * n)
            fix[3 * fixed:3 * fixed + 3] = 1e12
            while True:
                damp = sp.diags(diag * lam + fix + 1e-9)
                try:
                    dx = -spla.spsolve((h + damp).tocsc(), g)
                except RuntimeError:
                    dx = np.zeros(3 * n)
                if not np.all(np.isfinite(dx)):
                    dx = np.zeros(3 * n)
                xn = x + dx.reshape(n, 3)
                xn[:, 2] = _wrap(xn[:, 2])
                en, an, bn = self._linearise(xn, ii, jj, zz)
                chi2n, sn = self._scales(en, om, rb)
                costn = float((sn * chi2n).sum())
                if costn <= cost or lam > 1e6:
                    break
                lam = max(lam * 10.0, 1e-4)
            if costn > cost:
                break
            rel = (cost - costn) / max(cost, 1e-12)
            x, e, a, b, s, cost = xn, en, an, bn, sn, costn
            lam = lam / 10.0 if lam > 1e-6 else 0.0
            if rel < tol:
                break
        self.poses = x
        rejected = int(((s < 0.25) & rb).sum())
        del m
        return OptimiseResult(it, cost0, cost, rejected)
