"""Occupancy grid built from laser points and a bounded A* search over it (used by follow-path).

Cells are ``res_m`` squares in the world frame, in a fixed window of ``size_m`` centred on the first
pose seen; unknown cells count as free (optimistic planning, replanned as the scan reveals more).
Each cell keeps a hit count: a return adds ``HIT`` (once per scan), a beam passing through the cell
removes ``MISS``; a cell is occupied at ``OCCUPIED`` or more. This forgets the stray returns of mixed
pixels and people who walked away.
"""

from __future__ import annotations

import heapq
import math
import time

import numpy as np

from ..types import FloatArray
from .base import DeadlineMissed, NoPathFound

__all__ = ["OccupancyGrid"]

HIT, MISS, OCCUPIED, CAP = 2, 1, 4, 12


class OccupancyGrid:
    def __init__(self, centre_xy: tuple[float, float], size_m: float = 40.0, res_m: float = 0.1) -> None:
        self.res = res_m
        self.n = int(round(size_m / res_m))
        self.x0 = centre_xy[0] - 0.5 * size_m
        self.y0 = centre_xy[1] - 0.5 * size_m
        self.hits = np.zeros((self.n, self.n), dtype=np.uint8)

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return int((x - self.x0) / self.res), int((y - self.y0) / self.res)

    def covers(self, x: float, y: float, margin_m: float = 0.0) -> bool:
        """True when (x, y) lies in the window, at least ``margin_m`` inside its edges."""
        size = self.n * self.res
        return self.x0 + margin_m <= x <= self.x0 + size - margin_m and self.y0 + margin_m <= y <= self.y0 + size - margin_m

    def centre(self, i: int, j: int) -> tuple[float, float]:
        return self.x0 + (i + 0.5) * self.res, self.y0 + (j + 0.5) * self.res

    def _ij(self, xy: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        ij = ((xy - (self.x0, self.y0)) / self.res).astype(int)
        ok = (ij[:, 0] >= 0) & (ij[:, 0] < self.n) & (ij[:, 1] >= 0) & (ij[:, 1] < self.n)
        return ij[ok, 0], ij[ok, 1]

    def add_points(self, xy_world: FloatArray, origin: tuple[float, float] | None = None, max_clear_m: float = 6.0) -> None:
        """Count the returns (k, 2), world frame, m; with the sensor ``origin``, also clear the cells
        the beams crossed (up to ``max_clear_m`` and 0.25 m short of each return)."""
        if len(xy_world) == 0:
            return
        if origin is not None:
            d = xy_world - origin
            r = np.hypot(d[:, 0], d[:, 1])
            step = 1.5 * self.res
            m = int(min(max_clear_m, float(r.max())) / step) + 1
            t = step * np.arange(1, m)
            keep = t[None, :] < (np.minimum(r, max_clear_m) - 0.25)[:, None]
            u = d / np.maximum(r, 1e-9)[:, None]
            px = origin[0] + u[:, 0:1] * t[None, :]
            py = origin[1] + u[:, 1:2] * t[None, :]
            i, j = self._ij(np.column_stack((px[keep], py[keep])))
            h = self.hits[i, j].astype(np.int16) - MISS
            self.hits[i, j] = np.maximum(h, 0).astype(np.uint8)
        i, j = self._ij(xy_world)
        self.hits[i, j] = np.minimum(self.hits[i, j].astype(np.int16) + HIT, CAP).astype(np.uint8)

    def inflated(self, radius_m: float, box: tuple[int, int, int, int]) -> np.ndarray:
        """Occupied cells grown by ``radius_m`` inside ``box`` = (i0, j0, i1, j1) (exclusive ends)."""
        i0, j0, i1, j1 = box
        k = int(math.ceil(radius_m / self.res))
        pad = np.zeros((i1 - i0 + 2 * k, j1 - j0 + 2 * k), dtype=bool)
        a0, b0 = max(i0 - k, 0), max(j0 - k, 0)
        a1, b1 = min(i1 + k, self.n), min(j1 + k, self.n)
        pad[a0 - (i0 - k): a1 - (i0 - k), b0 - (j0 - k): b1 - (j0 - k)] = self.hits[a0:a1, b0:b1] >= OCCUPIED
        out = np.zeros((i1 - i0, j1 - j0), dtype=bool)
        for di in range(-k, k + 1):
            for dj in range(-k, k + 1):
                if di * di + dj * dj <= (radius_m / self.res) ** 2 + 0.5:
                    out |= pad[k + di: k + di + i1 - i0, k + dj: k + dj + j1 - j0]
        return out

    def plan(self, start: tuple[float, float], goal: tuple[float, float], radius_m: float, margin_cells: int = 25,
             deadline_s: float = 0.05, max_expansions: int = 60000) -> FloatArray:
        """A* (8-connected) from ``start`` to ``goal`` (world, m) around inflated obstacles, inside the
        bounding box of both plus ``margin_cells``. Returns the path (n, 2), m, start to goal.

        Raises :class:`NoPathFound` or :class:`DeadlineMissed` (``deadline_s`` wall time or
        ``max_expansions`` nodes)."""
        t_end = time.perf_counter() + deadline_s
        si, sj = self.cell(*start)
        gi, gj = self.cell(*goal)
        i0 = max(min(si, gi) - margin_cells, 0)
        j0 = max(min(sj, gj) - margin_cells, 0)
        i1 = min(max(si, gi) + margin_cells + 1, self.n)
        j1 = min(max(sj, gj) + margin_cells + 1, self.n)
        occ = self.inflated(radius_m, (i0, j0, i1, j1))
        W, H = i1 - i0, j1 - j0
        s = (si - i0, sj - j0)
        g = (gi - i0, gj - j0)
        if not (0 <= s[0] < W and 0 <= s[1] < H and 0 <= g[0] < W and 0 <= g[1] < H):
            raise NoPathFound("start or goal outside the grid")
        occ[s] = False  # the robot stands here; the goal cell is kept free as well
        occ[g] = False
        blocked = occ.ravel().tolist()
        sidx, gidx = s[0] * H + s[1], g[0] * H + g[1]
        gcost = {sidx: 0.0}
        parent = {sidx: -1}
        heap = [(0.0, sidx)]
        steps = ((1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0), (1, 1, 1.4142), (1, -1, 1.4142), (-1, 1, 1.4142), (-1, -1, 1.4142))
        gx, gy = g
        n = 0
        closed = set()
        while heap:
            _, cur = heapq.heappop(heap)
            if cur in closed:
                continue
            if cur == gidx:
                break
            closed.add(cur)
            n += 1
            if n > max_expansions or (n & 255) == 0 and time.perf_counter() > t_end:
                raise DeadlineMissed(f"A* stopped after {n} expansions")
            ci, cj = divmod(cur, H)
            base = gcost[cur]
            for di, dj, c in steps:
                ni, nj = ci + di, cj + dj
                if 0 <= ni < W and 0 <= nj < H:
                    k = ni * H + nj
                    if blocked[k] or k in closed:
                        continue
                    nc = base + c
                    if nc < gcost.get(k, math.inf):
                        gcost[k] = nc
                        parent[k] = cur
                        dx, dy = abs(ni - gx), abs(nj - gy)
                        heapq.heappush(heap, (nc + max(dx, dy) + 0.4142 * min(dx, dy), k))
        else:
            raise NoPathFound("no path in the known grid")
        if gidx not in parent:
            raise NoPathFound("no path in the known grid")
        cells = []
        k = gidx
        while k != -1:
            ci, cj = divmod(k, H)
            cells.append(self.centre(ci + i0, cj + j0))
            k = parent[k]
        cells.reverse()
        path = np.array(cells)
        path[0] = start
        path[-1] = goal
        return _shortcut(path, occ, i0, j0, self)


def _shortcut(path: FloatArray, occ: np.ndarray, i0: int, j0: int, grid: OccupancyGrid) -> FloatArray:
    """Drop intermediate points while the straight segment stays on free cells (line of sight)."""
    if len(path) <= 2:
        return path
    out = [path[0]]
    i = 0
    W, H = occ.shape
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1:
            a, b = path[i], path[j]
            m = max(2, int(np.hypot(*(b - a)) / (0.5 * grid.res)))
            t = np.linspace(0.0, 1.0, m)
            xs = ((a[0] + t * (b[0] - a[0]) - grid.x0) / grid.res).astype(int) - i0
            ys = ((a[1] + t * (b[1] - a[1]) - grid.y0) / grid.res).astype(int) - j0
            ok = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
            if ok.all() and not occ[xs, ys][1:-1].any():
                break
            j -= 1
        out.append(path[j])
        i = j
    return np.array(out)
