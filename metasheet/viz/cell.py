"""Pictures of unit cells: 2 x 2 x 2 tiled so that the periodicity shows.

Functions return PNG bytes (pyvista off screen); the stage layer writes them.
"""

from __future__ import annotations

import itertools

import numpy as np
from . import image_png, one_at_a_time

#: Colours of phases 1, 2, ... (void is not drawn), and their names for the captions.
PHASE_COLOURS = ("#d9a441", "#4a7fb5", "#8fb54a", "#b54a6d")
COLOUR_NAMES = ("tan", "blue", "green", "red")


def _png(image: np.ndarray) -> bytes:
    return image_png(image)


def _tile_offsets(size: np.ndarray, tiles: int) -> list[np.ndarray]:
    return [np.array(t, dtype=float) * size for t in itertools.product(range(tiles), repeat=3)]


def _box_lines(size: np.ndarray, tiles: int):
    import pyvista as pv

    boxes = [pv.Box(bounds=(o[0], o[0] + size[0], o[1], o[1] + size[1], o[2], o[2] + size[2]))
             for o in _tile_offsets(size, tiles)]
    return pv.merge([b.extract_all_edges() for b in boxes])


def _render(meshes, size: np.ndarray, tiles: int, title: str, window: tuple[int, int]) -> bytes:
    import pyvista as pv

    pl = pv.Plotter(off_screen=True, window_size=window)
    pl.set_background("white")
    for mesh, kwargs in meshes:
        pl.add_mesh(mesh, **kwargs)
    pl.add_mesh(_box_lines(size, tiles), color="#595959", line_width=1.0)
    pl.add_axes(color="black", line_width=2)
    if title:
        pl.add_text(title, position="upper_left", font_size=10, color="black")
    pl.camera_position = "iso"
    pl.camera.azimuth = 15.0
    pl.camera.elevation = 5.0
    pl.reset_camera()
    # a multi-line title needs head room, and a slender box (Polyfoam: ~1 x 5 x 10) would reach it
    slender = float(np.max(size) / np.min(size)) > 3.0
    pl.camera.zoom(0.8 if slender or title.count("\n") >= 2 else 1.0)
    image = pl.screenshot(return_img=True)
    pl.close()
    return _png(image)


@one_at_a_time
def surface_picture(vertices: np.ndarray, faces: np.ndarray, size, *, tiles: int = 2, title: str = "",
                    window: tuple[int, int] = (900, 900)) -> bytes:
    """A triangle surface of one cell, repeated ``tiles`` times along x, y and z.

    Parameters
    ----------
    vertices : (v, 3) float [mm]; faces : (f, 3) int; size : (3,) [mm] the cell box.
    tiles : copies per axis; title : text in the upper left corner.
    """
    import pyvista as pv

    size = np.asarray(size, dtype=float)
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    cells = np.hstack([np.full((len(f), 1), 3), f]).ravel()
    one = pv.PolyData(v, cells)
    tiled = pv.merge([one.translate(o, inplace=False) for o in _tile_offsets(size, tiles)])
    kwargs = {"color": PHASE_COLOURS[0], "smooth_shading": False, "specular": 0.2}
    return _render([(tiled, kwargs)], size, tiles, title, window)


@one_at_a_time
def voxel_picture(phases: np.ndarray, size, *, tiles: int = 2, title: str = "",
                  labels: dict[int, str] | None = None, window: tuple[int, int] = (900, 900)) -> bytes:
    """The voxels of a phase grid (void hidden), coloured by phase, tiled ``tiles`` times.

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 void; size : (3,) [mm] the cell box.
    labels : phase -> legend text (no legend when None).
    """
    import pyvista as pv

    size = np.asarray(size, dtype=float)
    ph = np.asarray(phases)
    grid = pv.ImageData(dimensions=np.array(ph.shape) + 1, spacing=size / np.array(ph.shape))
    grid.cell_data["phase"] = ph.ravel(order="F").astype(np.int32)
    solid = grid.threshold(0.5, scalars="phase").extract_surface(algorithm="dataset_surface")
    tiled = pv.merge([solid.translate(o, inplace=False) for o in _tile_offsets(size, tiles)])
    present = [int(p) for p in np.unique(ph) if p > 0]
    meshes, captions = [], []
    for p in present:
        part = tiled.threshold((p - 0.5, p + 0.5), scalars="phase")
        k = (p - 1) % len(PHASE_COLOURS)
        if part.n_cells:
            meshes.append((part, {"color": PHASE_COLOURS[k]}))
        if labels and p in labels:
            captions.append(f"{COLOUR_NAMES[k]}: {labels[p]}")
    return _render(meshes, size, tiles, "\n".join([title, *captions]).strip(), window)
