"""Occupancy grids: built from scans at known poses, saved and loaded as ROS map_server maps (PGM + YAML).

Building (:func:`occupancy_from_scans`). Each scan's beams mark the cells they cross as passed and the cells
of their returns as hit (each scan counts a cell once). A cell is occupied when at least ``occupied_share``
of the scans that reached it ended a beam in it (a quarter, as gmapping's ``occ_thresh``), free otherwise;
cells no beam reached stay unknown. The free space of a scan is the polygon from the laser through its
returns in beam order, each vertex two cells short of its return (so that the polygon's edges, which run
along the surface hit, do not pass through it); a beam without a return clears nothing.

The map_server format. ``map.yaml``::

    image: map.pgm            # the picture, relative to the YAML file
    resolution: 0.05          # m per cell
    origin: [x, y, yaw]       # the pose of the lower-left cell's corner, m, m, rad
    negate: 0                 # 0: white (255) is free, black (0) occupied
    occupied_thresh: 0.65     # p above: occupied
    free_thresh: 0.196        # p below: free
    mode: trinary

The PGM (binary P5, 8 bits, the top row first) holds p = (255 - value) / 255 when ``negate`` is 0 (value / 255
when 1); :func:`save_map` writes 254 for free, 0 for occupied and 205 for unknown, as map_server's saver
does. :func:`load_map` reads P5 and P2 pictures and returns an :class:`OccupancyGrid` of -1 (unknown), 0
(free) and 100 (occupied), the values of a ROS OccupancyGrid message, with row 0 at the bottom (y grows
with the row).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from ..types import FloatArray

__all__ = ["OccupancyGrid", "MapFileError", "occupancy_from_scans", "save_map", "load_map", "map_picture",
           "FREE", "OCCUPIED", "UNKNOWN"]

FREE, OCCUPIED, UNKNOWN = 0, 100, -1
_PGM_FREE, _PGM_OCC, _PGM_UNKNOWN = 254, 0, 205


class MapFileError(ValueError):
    """A map's YAML or picture that cannot be read; the message names the file and what is wrong."""


@dataclass(frozen=True)
class OccupancyGrid:
    """Cells (rows, cols) of -1 / 0 / 100, row 0 at ``origin``'s y, column 0 at its x; ``resolution_m``
    a cell's side; ``origin`` the pose of cell (0, 0)'s outer corner (x m, y m, yaw rad)."""

    cells: npt.NDArray[np.int8]
    resolution_m: float
    origin: tuple[float, float, float]

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.cells.shape[0]), int(self.cells.shape[1]))


def occupancy_from_scans(poses: FloatArray, points: Sequence[FloatArray], origins: Sequence[FloatArray],
                         resolution_m: float = 0.05, occupied_share: float = 0.25,
                         margin_m: float = 1.0, max_free_m: float = 20.0) -> OccupancyGrid:
    """The grid of the scans ``points[i]`` (k, 2, robot frame) taken from ``poses[i]`` (x, y, yaw) by a
    laser at ``origins[i]`` (x, y in the robot frame). Beams clear free space up to ``max_free_m`` from
    the laser (their returns beyond it still mark occupied cells)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    world = []
    lasers = []
    for pose, pts, org in zip(poses, points, origins):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        rot = np.array([[c, -s], [s, c]])
        world.append(pts @ rot.T + pose[:2])
        lasers.append(rot @ np.asarray(org, dtype=float)[:2] + pose[:2])
    allpts = np.concatenate([*world, np.array(lasers).reshape(-1, 2)]) if world else np.zeros((1, 2))
    lo = allpts.min(axis=0) - margin_m
    hi = allpts.max(axis=0) + margin_m
    nx, ny = (np.ceil((hi - lo) / resolution_m).astype(int) + 1)
    hits = np.zeros((ny, nx), dtype=np.uint16)
    passes = np.zeros((ny, nx), dtype=np.uint16)
    scratch = np.zeros((ny, nx), dtype=np.uint8)
    for pts, org in zip(world, lasers):
        if len(pts) == 0:
            continue
        ij = np.floor((pts - lo) / resolution_m).astype(np.int32)
        o = np.floor((org - lo) / resolution_m).astype(np.int32)
        flat = np.unique(ij[:, 1].astype(np.int64) * nx + ij[:, 0])
        hits.ravel()[flat] += 1  # once per scan: the indices are unique
        d = pts - org
        r = np.hypot(d[:, 0], d[:, 1])
        # short of the return by two cells (the polygon's edges run along the wall it hit), at most max_free_m
        pull = np.clip((np.minimum(r, max_free_m) - 2.0 * resolution_m) / np.maximum(r, 1e-9), 0.0, 1.0)
        fij = np.floor((org + d * pull[:, None] - lo) / resolution_m).astype(np.int32)
        x0, y0 = np.minimum(fij.min(axis=0), o)
        x1, y1 = np.maximum(fij.max(axis=0), o) + 1
        sub = scratch[y0:y1, x0:x1]
        sub[:] = 0
        poly = np.vstack([o, fij]) - [x0, y0]
        cv2.fillPoly(sub, [poly.reshape(-1, 1, 2)], 1)
        inside = (ij[:, 0] >= x0) & (ij[:, 0] < x1) & (ij[:, 1] >= y0) & (ij[:, 1] < y1)
        sub[ij[inside, 1] - y0, ij[inside, 0] - x0] = 0  # a return's own cell is not passed through
        passes[y0:y1, x0:x1] += sub
    seen = (hits + passes) > 0
    share = hits.astype(float) / np.maximum(hits.astype(float) + passes.astype(float), 1.0)
    cells = np.full((ny, nx), UNKNOWN, dtype=np.int8)
    cells[seen] = FREE
    cells[seen & (share >= occupied_share)] = OCCUPIED
    return OccupancyGrid(cells, resolution_m, (float(lo[0]), float(lo[1]), 0.0))


def _pgm_values(grid: OccupancyGrid) -> npt.NDArray[np.uint8]:
    img = np.full(grid.cells.shape, _PGM_UNKNOWN, dtype=np.uint8)
    img[grid.cells == FREE] = _PGM_FREE
    img[grid.cells == OCCUPIED] = _PGM_OCC
    return img[::-1]  # the picture's top row is the map's highest y


def save_map(grid: OccupancyGrid, yaml_path: str | Path, image_name: str | None = None) -> tuple[Path, Path]:
    """Write ``grid`` as map_server's YAML at ``yaml_path`` and its PGM beside it (``image_name``, default the
    YAML's name with ``.pgm``). Returns the two paths."""
    y = Path(yaml_path)
    img_path = y.with_name(image_name) if image_name else y.with_suffix(".pgm")
    img = _pgm_values(grid)
    h, w = img.shape
    with open(img_path, "wb") as f:
        f.write(f"P5\n# agnav slam occupancy grid, {grid.resolution_m:g} m/cell\n{w} {h}\n255\n".encode("ascii"))
        f.write(img.tobytes())
    ox, oy, oyaw = grid.origin
    y.write_text(f"image: {img_path.name}\nresolution: {grid.resolution_m:.6g}\n"
                 f"origin: [{ox:.6f}, {oy:.6f}, {oyaw:.6f}]\nnegate: 0\noccupied_thresh: 0.65\n"
                 "free_thresh: 0.196\nmode: trinary\n", encoding="utf-8")
    return y, img_path


def _read_pgm(path: Path) -> npt.NDArray[np.uint8]:
    data = path.read_bytes()
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4:
        m = re.compile(rb"\s*(#[^\n]*\n\s*)*([^\s#]+)").match(data, pos)
        if m is None:
            raise MapFileError(f"{path}: not a PGM picture (its header ends early)")
        tokens.append(m.group(2))
        pos = m.end()
    magic = tokens[0]
    if magic not in (b"P5", b"P2"):
        raise MapFileError(f"{path}: not a PGM picture (starts with {magic[:8]!r}, not P5 or P2)")
    try:
        w, h, maxval = int(tokens[1]), int(tokens[2]), int(tokens[3])
    except ValueError:
        raise MapFileError(f"{path}: the PGM header's size is not numbers") from None
    if w <= 0 or h <= 0 or not 0 < maxval < 65536:
        raise MapFileError(f"{path}: the PGM header gives size {w}x{h}, maximum {maxval}")
    if magic == b"P5":
        pos += 1  # the single white-space byte after the maximum
        depth = 1 if maxval < 256 else 2
        raw = data[pos:pos + w * h * depth]
        if len(raw) < w * h * depth:
            raise MapFileError(f"{path}: the picture is cut off ({len(raw)} of {w * h * depth} bytes)")
        vals = np.frombuffer(raw, dtype=np.uint8 if depth == 1 else ">u2").astype(float)
    else:
        try:
            vals = np.array(data[pos:].split()[: w * h], dtype=float)
        except ValueError:
            raise MapFileError(f"{path}: a P2 value is not a number") from None
        if len(vals) < w * h:
            raise MapFileError(f"{path}: the picture is cut off ({len(vals)} of {w * h} values)")
    scaled = np.rint(vals.reshape(h, w) * (255.0 / maxval))
    return np.clip(scaled, 0, 255).astype(np.uint8)


def _yaml_fields(path: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        if ":" not in text:
            raise MapFileError(f"{path}: line {number}: expected 'key: value'")
        key, val = text.split(":", 1)
        out[key.strip()] = val.strip().strip("'\"")
    return out


def load_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server map (its YAML and the picture it names). Raises OSError when a file cannot be read
    and :class:`MapFileError` when one breaks the format."""
    y = Path(yaml_path)
    f = _yaml_fields(y)
    for key in ("image", "resolution", "origin"):
        if key not in f:
            raise MapFileError(f"{y}: no '{key}' in the map's YAML")
    try:
        res = float(f["resolution"])
        origin = [float(v) for v in f["origin"].strip("[]").split(",")]
        negate = int(f.get("negate", "0"))
        occ_t = float(f.get("occupied_thresh", "0.65"))
        free_t = float(f.get("free_thresh", "0.196"))
    except ValueError:
        raise MapFileError(f"{y}: resolution, origin, negate or a threshold is not a number") from None
    if not (math.isfinite(res) and res > 0) or len(origin) != 3:
        raise MapFileError(f"{y}: resolution must be > 0 and origin [x, y, yaw]")
    img = _read_pgm(y.parent / f["image"])
    p = img.astype(float) / 255.0 if negate else (255.0 - img.astype(float)) / 255.0
    cells = np.full(img.shape, UNKNOWN, dtype=np.int8)
    cells[p > occ_t] = OCCUPIED
    cells[p < free_t] = FREE
    return OccupancyGrid(cells[::-1].copy(), res, (origin[0], origin[1], origin[2]))


def map_picture(grid: OccupancyGrid, path_xy: FloatArray | None = None, scale: int = 1,
                max_side_px: int = 4000) -> npt.NDArray[np.uint8]:
    """A colour picture (BGR, top row = highest y) of the grid: free white, occupied black, unknown grey,
    with ``path_xy`` ((n, 2) m) drawn as a red line, its start a green dot and its end a blue one, and a
    scale bar."""
    img: npt.NDArray[np.uint8] = np.where(_pgm_values(grid) == _PGM_UNKNOWN, 190, _pgm_values(grid)).astype(np.uint8)
    shrink = max(1, math.ceil(max(img.shape) / max_side_px))
    if shrink > 1:
        img = np.asarray(cv2.resize(img, (img.shape[1] // shrink, img.shape[0] // shrink),
                                    interpolation=cv2.INTER_AREA), dtype=np.uint8)
    if scale > 1:
        img = np.asarray(cv2.resize(img, (img.shape[1] * scale, img.shape[0] * scale),
                                    interpolation=cv2.INTER_NEAREST), dtype=np.uint8)
    px_m = grid.resolution_m * shrink / scale
    out: npt.NDArray[np.uint8] = np.asarray(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    h = out.shape[0]
    thick = max(1, round(max(out.shape) / 1500))
    if path_xy is not None and len(path_xy):
        uv = np.column_stack([(path_xy[:, 0] - grid.origin[0]) / px_m, h - (path_xy[:, 1] - grid.origin[1]) / px_m])
        pts = np.rint(uv).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(out, [pts], False, (0, 0, 220), thick, cv2.LINE_AA)
        cv2.circle(out, tuple(int(v) for v in pts[0, 0]), 4 * thick, (0, 160, 0), -1)
        cv2.circle(out, tuple(int(v) for v in pts[-1, 0]), 4 * thick, (200, 80, 0), -1)
    span_m = out.shape[1] * px_m
    bar_m = 10 ** math.floor(math.log10(max(span_m / 5, 1e-3)))
    bar_px = int(round(bar_m / px_m))
    x0, y0 = 10, h - 12
    cv2.line(out, (x0, y0), (x0 + bar_px, y0), (0, 0, 0), 2 * thick)
    cv2.putText(out, f"{bar_m:g} m", (x0, y0 - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4 * thick, (0, 0, 0), thick,
                cv2.LINE_AA)
    return out
