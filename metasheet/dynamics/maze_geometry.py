"""The maze on the plate: a corridor around a polyline path, bounded by walls.

Coordinates are the maze plane's (u along the rod = world x at rest, v = world y at rest) [mm],
the plate frame's x and y (:mod:`.marble`). :func:`maze_from_path` builds the corridor as the
union of one rectangle per path segment, of the corridor ``width`` across and extended by half
the width beyond both ends (a square cap of side ``width`` at every vertex, turned with its
segment): the corridor is exactly ``width`` wide across every segment and holds the disc of
radius ``width / 2`` about every path point, so a marble of radius below ``width / 2`` can
follow the whole centre line. The union is manifold3d's (Clipper2, coordinates to 1e-8 mm);
the walls are the edges of its boundary, outer contour counter-clockwise and islands clockwise
(the corridor on the left of every wall).

A path that comes back on itself (the default maze returns to its start, its last diagonal
crosses the first corridor) is still a valid corridor: where two corridors overlap the union
merges them and the walls between them vanish, so there the marble may cross from one to the
other; a loop leaves an island (a hole contour, its walls included). Where corridors overlap
the closest centre-line point is ambiguous: :func:`centerline_progress` takes the first along
the path, or with ``track=True`` (a time series) the one that continues the previous progress.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range


@dataclass(frozen=True)
class MazeGeometry:
    """path : (m, 2) [mm] the corridor's centre line; width [mm] the corridor across;
    wall_height [mm]; plate : (2,) [mm] outer (length along u, width along v), centred on the
    walls' bounding box (:func:`plate_bounds`); walls : (w, 2, 2) [mm] wall segments
    ``walls[i] = (start, end)``, the corridor on their left."""

    path: np.ndarray
    width: float = 20.0
    wall_height: float = 6.0
    plate: np.ndarray = (70.0, 60.0)
    walls: np.ndarray = ()

    def __post_init__(self):
        path = _path_array(self.path)
        check_range("width", self.width, 0.0, None, lo_open=True)
        check_range("wall_height", self.wall_height, 0.0, None, lo_open=True)
        plate = np.asarray(self.plate, float)
        if plate.shape != (2,) or not np.all(np.isfinite(plate)) or np.any(plate <= 0):
            raise ConfigError(f"plate: {self.plate!r}: should be two positive lengths [mm]")
        walls = np.asarray(self.walls, float).reshape(-1, 2, 2) if np.size(self.walls) else np.zeros((0, 2, 2))
        if not np.all(np.isfinite(walls)):
            raise ConfigError("walls: should be finite (w, 2, 2) segments [mm]")
        for name, value in (("path", path), ("plate", plate), ("walls", walls)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)


def _path_array(path) -> np.ndarray:
    P = np.array(path, float)
    if P.ndim != 2 or P.shape[1] != 2 or len(P) < 2 or not np.all(np.isfinite(P)):
        raise ConfigError(f"path: shape is {P.shape} and should be (m, 2) with m >= 2, finite [mm]")
    length = np.linalg.norm(np.diff(P, axis=0), axis=1)
    if np.any(length <= 0):
        raise ConfigError(f"path: segment {int(np.argmin(length))} has zero length; allowed: > 0 mm")
    return P


def segment_rectangles(path, width: float) -> list[np.ndarray]:
    """One (4, 2) counter-clockwise rectangle [mm] per segment of ``path`` (m, 2): ``width``
    across, extended by ``width / 2`` beyond both ends (the square caps at the vertices)."""
    P = np.asarray(path, float)
    h = width / 2
    out = []
    for a, b in zip(P[:-1], P[1:]):
        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]])  # left normal
        out.append(np.array([a - h * d - h * n, b + h * d - h * n, b + h * d + h * n, a - h * d + h * n]))
    return out


def maze_from_path(path, width: float = 20.0, wall_height: float = 6.0, margin: float = 5.0) -> MazeGeometry:
    """The :class:`MazeGeometry` of the corridor around ``path`` (m, 2) [mm] (module doc);
    the plate is the corridor's bounding box grown by ``margin`` [mm] on every side."""
    import manifold3d

    P = _path_array(path)
    check_range("width", width, 0.0, None, lo_open=True)
    check_range("wall_height", wall_height, 0.0, None, lo_open=True)
    check_range("margin", margin, 0.0, None)
    corridor = manifold3d.CrossSection(segment_rectangles(P, width), manifold3d.FillRule.Positive)
    # collinear vertices where rectangles meet would split one wall into several; 1e-6 mm is far
    # below any wall but above Clipper2's 1e-8 mm rounding
    polygons = corridor.simplify(1e-6).to_polygons()
    walls = [np.stack([poly, np.roll(poly, -1, axis=0)], axis=1) for poly in polygons]
    walls = np.concatenate(walls) if walls else np.zeros((0, 2, 2))
    lo, hi = walls.reshape(-1, 2).min(axis=0), walls.reshape(-1, 2).max(axis=0)
    return MazeGeometry(P, float(width), float(wall_height), hi - lo + 2 * margin, walls)


def plate_bounds(geometry: MazeGeometry) -> np.ndarray:
    """(2, 2) [mm] the plate's ``[[u_min, v_min], [u_max, v_max]]``: ``plate`` centred on the
    walls' bounding box (on the path's without walls)."""
    pts = geometry.walls.reshape(-1, 2) if len(geometry.walls) else geometry.path
    mid = (pts.min(axis=0) + pts.max(axis=0)) / 2
    return np.stack([mid - geometry.plate / 2, mid + geometry.plate / 2])


def segment_distances(points, segments) -> tuple[np.ndarray, np.ndarray]:
    """Distances (k, s) [mm] from ``points`` (k, 2) to ``segments`` (s, 2, 2) and the
    parameters (k, s) in [0, 1] of the closest points along each segment."""
    X = np.asarray(points, float)[:, None, :]
    a, b = segments[None, :, 0], segments[None, :, 1]
    d = b - a
    t = np.clip(np.sum((X - a) * d, axis=-1) / np.sum(d * d, axis=-1), 0.0, 1.0)
    return np.linalg.norm(X - (a + t[..., None] * d), axis=-1), t


def inside_corridor(geometry: MazeGeometry, points) -> np.ndarray:
    """(k,) bool: ``points`` (k, 2) [mm] inside the corridor (even-odd rule over all walls, so
    islands are outside)."""
    X = np.asarray(points, float).reshape(-1, 2)
    a, b = geometry.walls[:, 0], geometry.walls[:, 1]
    x, y = X[:, None, 0], X[:, None, 1]
    straddle = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    return (np.count_nonzero(straddle & (xc > x), axis=1) % 2) == 1


def centerline_progress(geometry: MazeGeometry, points, *, track: bool = False) -> np.ndarray:
    """(k,) [mm] arc length along the path of the closest path point to each of ``points``
    (k, 2) [mm]: the path's length means the marble travelled it all.

    Ties (a revisiting path) go to the first along the path. With ``track`` the points are a
    time series: each takes the closest among the segments whose corridor (with its square
    caps) holds it and whose closest point continues the previous point's progress within one
    corridor ``width``, else the global closest: a marble crossing an overlap or coming back to
    the start keeps counting, and one that leaves its segment is not held at its end.
    """
    X = np.asarray(points, float).reshape(-1, 2)
    seg = np.stack([geometry.path[:-1], geometry.path[1:]], axis=1)
    length = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    start = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    dist, t = segment_distances(X, seg)
    s = start[None, :] + t * length[None, :]  # (k, s) progress on every segment
    out = s[np.arange(len(X)), np.argmin(dist, axis=1)]
    if track:
        h = geometry.width / 2 + 1e-9
        d = (seg[:, 1] - seg[:, 0]) / length[:, None]
        rel = X[:, None, :] - seg[None, :, 0]  # (k, s, 2)
        along = np.sum(rel * d, axis=-1)
        held = (np.abs(rel[..., 1] * d[:, 0] - rel[..., 0] * d[:, 1]) <= h) & (along >= -h) & (along <= length + h)
        for k in range(1, len(X)):
            # a window, not the nearest progress: past a corner the previous segment's end
            # stays as near in progress as the next segment's start, but farther in space
            near = (np.abs(s[k] - out[k - 1]) <= geometry.width) & held[k]  # in the segment's rectangle
            if near.any():
                out[k] = s[k, near][np.argmin(dist[k, near])]
    return out


def to_json(geometry: MazeGeometry) -> dict:
    """The geometry as a JSON-ready dict (a maze.json file): path, width, wall_height, plate,
    walls, lengths in mm."""
    return {"path": geometry.path.tolist(), "width": float(geometry.width),
            "wall_height": float(geometry.wall_height), "plate": geometry.plate.tolist(),
            "walls": geometry.walls.tolist()}


def from_json(data: dict) -> MazeGeometry:
    """The :class:`MazeGeometry` of a :func:`to_json` dict; ConfigError naming a missing key."""
    keys = ("path", "width", "wall_height", "plate", "walls")
    missing = [k for k in keys if k not in data]
    if missing:
        raise ConfigError(f"maze.json: missing {', '.join(missing)}; expected keys {', '.join(keys)}")
    walls = np.asarray(data["walls"], float)
    if walls.size and (walls.ndim != 3 or walls.shape[1:] != (2, 2)):
        raise ConfigError(f"walls: shape is {walls.shape} and should be (w, 2, 2) [mm]")
    return MazeGeometry(data["path"], data["width"], data["wall_height"], data["plate"], walls)
