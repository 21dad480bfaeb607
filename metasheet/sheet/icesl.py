"""IceSL print map: field textures on a 64^3 grid and the Lua script that binds them.

IceSL (https://icesl.loria.fr) varies print settings in space through 3D textures made in
its Lua modelling script: ``tex = tex3d_r8f(64, 64, 64)``, ``tex:set(i, j, k, v(x, 0, 0))``
and ``set_setting_value(name, tex, v(xmin, ymin, zmin), v(xmax, ymax, zmax))``, the box in
world millimetres, i, j, k along x, y, z. Texture values lie in [0, 1].

Scales written here (all fields in [0, 1]):

- density (``infill_percentage_0``): value = infill percentage / 100, so 0 is the minimum
  (0 %) and 1 the maximum (100 %). The percentage is ``clip(100 * gain * rho, pmin, pmax)``
  with rho the element's relative density; gain = 1 by default, i.e. the infill
  percentage is taken as the printed volume fraction.
- theta (``phasor_infill_theta_0``, and ``infill_angle_0`` for Polyfoam): the fibre's
  in-plane angle atan2(l_y, l_x) / 360 deg, in [0, 1) (1 = 360 deg). A fibre is an axis,
  so theta and theta + 0.5 describe the same microstructure; the field keeps the spiral's
  continuous vector orientation, which wraps once around the centre.
- phi (``phasor_infill_phi_0``): inclination above the layer plane, asin(l_z), as
  (angle mod 360 deg) / 360 deg: 0 for an in-plane fibre.
- iso (``phasor_infill_iso_0``): isotropy, 0 = fully oriented, 1 = isotropic;
  1 - alpha / alpha_design per element.

Texel (i, j, k) is sampled at its centre ``lo + (i + 1/2) (hi - lo) / 64``. Texels whose
centre lies outside the part take the value of the nearest inside texel (Euclidean
distance in mm), so the slicer's interpolation at the boundary sees no spurious values.

Field files are text: 64 numbers per line (i = 0..63), lines ordered j fastest then k,
so value number c (from 0) is texel (c mod 64, (c // 64) mod 64, c // 4096).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..errors import ConfigError, check_range
from .fibers import fiber_angles

N = 64
INFILLS = ("phasor", "polyfoam")


@dataclass(frozen=True)
class GridBox:
    """The texture box: ``lo``, ``hi`` (3,) [mm] and ``n`` texels per axis."""

    lo: np.ndarray
    hi: np.ndarray
    n: int = N

    @property
    def spacing(self) -> np.ndarray:
        """Texel size (3,) [mm]."""
        return (self.hi - self.lo) / self.n

    def axes(self) -> list[np.ndarray]:
        """Texel-centre coordinates along x, y, z: three (n,) arrays [mm]."""
        return [self.lo[a] + (np.arange(self.n) + 0.5) * self.spacing[a] for a in range(3)]

    def centers(self) -> np.ndarray:
        """Texel centres (n, n, n, 3) [mm], indexed [i, j, k]."""
        return np.stack(np.meshgrid(*self.axes(), indexing="ij"), axis=-1)

    def index_of(self, points: np.ndarray) -> np.ndarray:
        """Index (m, 3) int of the texel containing each point (m, 3) [mm] (clipped to the box)."""
        ijk = np.floor((np.asarray(points) - self.lo) / self.spacing).astype(np.int64)
        return np.clip(ijk, 0, self.n - 1)


@dataclass(frozen=True)
class PrintFields:
    """Texture fields of one sheet.

    box : the :class:`GridBox`; cell : (n, n, n) int, element containing each texel
    centre (-1 outside); fields : name ("density", "theta", "phi", "iso") -> (n, n, n)
    float in [0, 1]; percent_range : (min, max) infill percentage over the part [%].
    """

    box: GridBox
    cell: np.ndarray
    fields: dict[str, np.ndarray]
    percent_range: tuple[float, float]


def grid_box(points: np.ndarray, n: int = N) -> GridBox:
    """The bounding box of points (k, 3) [mm] as a texture box of n^3 texels."""
    p = np.asarray(points, dtype=float)
    return GridBox(p.min(axis=0), p.max(axis=0), int(n))


def locate(points: np.ndarray, tets: np.ndarray, box: GridBox) -> np.ndarray:
    """Element (n, n, n) int containing each texel centre, -1 outside (VTK cell locator)."""
    import pyvista as pv

    grid = pv.UnstructuredGrid({pv.CellType.TETRA: np.asarray(tets)}, np.asarray(points, dtype=float))
    cell = grid.find_containing_cell(box.centers().reshape(-1, 3))
    return np.asarray(cell, dtype=np.int64).reshape((box.n,) * 3)


def extend_nearest(values: np.ndarray, inside: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """Copy of ``values`` (n, n, n) where outside texels take their nearest inside value.

    ``inside`` (n, n, n) bool must hold at least one True; distance measured in mm
    with the texel ``spacing`` (3,).
    """
    if not inside.any():
        raise ConfigError("inside: no texel centre lies inside the part; the grid misses the mesh")
    _, idx = ndimage.distance_transform_edt(~inside, sampling=spacing, return_indices=True)
    return values[tuple(idx)]


def normalise_angle(angle: np.ndarray) -> np.ndarray:
    """Angle [rad] -> texture value in [0, 1) with 1 = 360 deg."""
    return np.mod(np.asarray(angle, dtype=float), 2 * np.pi) / (2 * np.pi)


def density_percent(rho: np.ndarray, *, gain: float = 1.0, min_percent: float = 0.0,
                    max_percent: float = 100.0) -> np.ndarray:
    """IceSL infill percentage [%] for relative densities rho [-] (see module doc)."""
    check_range("gain", gain, 0.0, None, lo_open=True)
    check_range("min_percent", min_percent, 0.0, 100.0)
    check_range("max_percent", max_percent, min_percent, 100.0)
    return np.clip(100.0 * gain * np.asarray(rho, dtype=float), min_percent, max_percent)


def print_fields(
    points: np.ndarray,
    tets: np.ndarray,
    *,
    fiber_fn: Callable[[np.ndarray], np.ndarray],
    density: np.ndarray,
    iso: np.ndarray,
    gain: float = 1.0,
    min_percent: float = 0.0,
    max_percent: float = 100.0,
    n: int = N,
) -> PrintFields:
    """Sample a sheet's design on the n^3 texture grid over its bounding box.

    Parameters
    ----------
    points : (k, 3) float [mm]; tets : (m, 4) int.
    fiber_fn : fibre field, points (q, 3) [mm] -> unit fibres (q, 3); evaluated at the
        texel centres inside the part, so the texture resolves the continuous field
        rather than the element-wise constant one.
    density : (m,) relative density [-] per element; iso : (m,) isotropy in [0, 1].
    gain, min_percent, max_percent : density -> infill percentage (:func:`density_percent`).
    """
    tets = np.asarray(tets)
    density, iso = np.asarray(density, dtype=float), np.asarray(iso, dtype=float)
    if density.shape != (len(tets),) or iso.shape != (len(tets),):
        raise ConfigError(
            f"density, iso: shapes {density.shape}, {iso.shape} should both be ({len(tets)},)"
        )
    if np.any((iso < 0) | (iso > 1)):
        raise ConfigError(f"iso: values in [{iso.min():g}, {iso.max():g}]: allowed range is [0, 1]")
    box = grid_box(points, n)
    cell = locate(points, tets, box)
    inside = cell >= 0
    centres = box.centers()[inside]
    theta, phi = fiber_angles(fiber_fn(centres))
    percent = density_percent(density, gain=gain, min_percent=min_percent, max_percent=max_percent)
    raw = {
        "density": percent[cell[inside]] / 100.0,
        "theta": normalise_angle(theta),
        "phi": normalise_angle(phi),
        "iso": iso[cell[inside]],
    }
    fields = {}
    for name, val in raw.items():
        full = np.zeros((n, n, n))
        full[inside] = val
        fields[name] = extend_nearest(full, inside, box.spacing)
    used = percent[np.unique(cell[inside])]
    return PrintFields(box, cell, fields, (float(used.min()), float(used.max())))


def field_text(values: np.ndarray) -> str:
    """Text of one field file (layout in the module doc), 4 decimals per value."""
    v = np.asarray(values, dtype=float)
    if v.ndim != 3 or len(set(v.shape)) != 1:
        raise ConfigError(f"values: shape is {v.shape} and should be (n, n, n)")
    if np.any((v < 0) | (v > 1)) or not np.all(np.isfinite(v)):
        raise ConfigError(f"values: range [{np.nanmin(v):g}, {np.nanmax(v):g}]: allowed range is [0, 1]")
    rows = v.transpose(2, 1, 0).reshape(-1, v.shape[0])  # row (k, j) holds i = 0..n-1
    return "\n".join(" ".join(f"{x:.4f}" for x in row) for row in rows) + "\n"


def surface(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles of a positively oriented tet mesh, outward normals.

    Returns vertices (k, 3) [mm] (only those on the surface) and faces (f, 3) int.
    """
    t = np.asarray(tets)
    # for a positive tet the faces below are counter-clockwise seen from outside
    faces = np.concatenate([t[:, [0, 2, 1]], t[:, [0, 1, 3]], t[:, [1, 2, 3]], t[:, [0, 3, 2]]])
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    bnd = faces[np.sort(first[count == 1])]
    used, inv = np.unique(bnd, return_inverse=True)
    return np.asarray(points, dtype=float)[used], inv.reshape(-1, 3)


def _lua_value(name: str, value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        if not np.isfinite(value):
            raise ConfigError(f"settings.{name}: {value!r}: must be finite")
        return repr(value)
    if isinstance(value, str):
        return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"
    raise ConfigError(f"settings.{name}: {value!r}: expected a number, a boolean or a string")


SETTINGS = {  # IceSL setting bound to each field, per infill
    "phasor": {"density": "infill_percentage_0", "theta": "phasor_infill_theta_0",
               "phi": "phasor_infill_phi_0", "iso": "phasor_infill_iso_0"},
    "polyfoam": {"density": "infill_percentage_0", "theta": "infill_angle_0"},
}
INFILL_TYPE = {"phasor": "Phasor", "polyfoam": "Polyfoam"}


def lua_script(*, stl: str, infill: str, files: dict[str, str], box: GridBox,
               settings: dict[str, object], title: str = "") -> str:
    """IceSL modelling script that prints ``stl`` with the field textures ``files``.

    ``files`` maps field names of :data:`SETTINGS` [infill] to file names sitting next to
    the script; ``settings`` are plain IceSL settings (name -> number, bool or str) set
    before the fields. Paths resolve against IceSL's ``Path`` (the script's folder) when
    defined, else the working directory. The mesh is loaded with ``load`` (not
    ``load_centered``) so its coordinates, and hence the texture box, are preserved.
    """
    if infill not in SETTINGS:
        raise ConfigError(f"infill: {infill!r}: allowed values are {list(SETTINGS)}")
    missing = set(SETTINGS[infill]) - set(files)
    if missing:
        raise ConfigError(f"files: missing fields {sorted(missing)} for infill {infill!r}")
    lo = ", ".join(f"{x:.6f}" for x in box.lo)
    hi = ", ".join(f"{x:.6f}" for x in box.hi)
    out = [
        f"-- {title or 'metasheet print map'}",
        "-- generated by metasheet; fields are 64^3 textures in [0, 1] (see metasheet.sheet.icesl)",
        "local here = Path or ''",
        f"local N = {box.n}",
        "",
        "-- read a field file (64 values per line, i fastest, then j, then k) into a texture",
        "local function read_field(name)",
        "  local f = assert(io.open(here .. name, 'r'), 'cannot open ' .. name)",
        "  local tex = tex3d_r8f(N, N, N)",
        "  local c = 0",
        "  for line in f:lines() do",
        "    for word in string.gmatch(line, '%S+') do",
        "      local x = tonumber(word)",
        "      assert(x and x >= 0 and x <= 1, name .. ': bad value ' .. word)",
        "      assert(c < N * N * N, name .. ': too many values')",
        "      local i, j, k = c % N, math.floor(c / N) % N, math.floor(c / (N * N))",
        "      tex:set(i, j, k, v(x, 0, 0))",
        "      c = c + 1",
        "    end",
        "  end",
        "  f:close()",
        "  assert(c == N * N * N, name .. ': expected ' .. (N * N * N) .. ' values, read ' .. c)",
        "  return tex",
        "end",
        "",
        f"emit(load(here .. {_lua_value('stl', stl)}))",
        f"set_setting_value('infill_type_0', '{INFILL_TYPE[infill]}')",
    ]
    for name, value in settings.items():
        if not name.replace("_", "").isalnum():
            raise ConfigError(f"settings: {name!r}: a setting name has letters, digits and '_' only")
        out.append(f"set_setting_value('{name}', {_lua_value(name, value)})")
    out += ["", f"local lo, hi = v({lo}), v({hi})  -- texture box [mm]"]
    for field, setting in SETTINGS[infill].items():
        out.append(f"set_setting_value('{setting}', read_field({_lua_value(field, files[field])}), lo, hi)")
    return "\n".join(out) + "\n"
