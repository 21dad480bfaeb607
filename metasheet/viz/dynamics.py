"""Pictures of the robot in motion: the maze run as a GIF, the modes, step responses, tracking.

Drawn from plain arrays (node positions per frame, the rod's pose, the maze's walls in the
plate frame), so a run can be redrawn from its artefacts; this module does not import
:mod:`metasheet.dynamics`. 3D pictures are pyvista off screen, plots matplotlib (Agg).
Units: mm, s (plots show ms where a step lasts milliseconds).
"""

from __future__ import annotations

import io

import numpy as np

from ..errors import ConfigError, check_range
from . import figure_png, image_png, one_at_a_time

#: tet faces with outward normals for a positively oriented tet (det(x1-x0, x2-x0, x3-x0) > 0)
_TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _array(field, value, shape):
    """``value`` as a finite float array of ``shape`` (a name: any size >= 1 there), else ConfigError."""
    a = np.asarray(value, float)
    if a.ndim != len(shape) or any(n != s if isinstance(s, int) else n < 1 for s, n in zip(shape, a.shape)):
        raise ConfigError(f"{field}: shape is {a.shape} and should be ({', '.join(map(str, shape))})")
    if not np.all(np.isfinite(a)):
        raise ConfigError(f"{field}: holds a value that is not finite")
    return a


def _tets(tets, n_points):
    t = np.asarray(tets)
    if t.ndim != 2 or t.shape[1] not in (4, 10) or len(t) == 0:
        raise ConfigError(f"tets: shape is {t.shape} and should be (m, 4) or (m, 10), m >= 1")
    t = t[:, :4].astype(np.int64)
    if t.min() < 0 or t.max() >= n_points:
        raise ConfigError(f"tets: node index {int(t.max())} out of range for {n_points} nodes")
    return t


def boundary_faces(tets) -> np.ndarray:
    """The boundary triangles (f, 3) int of a tet mesh: faces used by one tet only.

    tets : (m, 4) or (m, 10) node indices (the first 4, the vertices, are used). A face keeps
    its tet's orientation, outward for positively oriented tets.
    """
    t = np.asarray(tets, dtype=np.int64)[:, :4]
    faces = t[:, _TET_FACES].reshape(-1, 3)
    _, inverse, counts = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def _surface(tets):
    """Boundary triangles over the nodes they use: (used node indices (u,), faces (f, 3) into them)."""
    faces = boundary_faces(tets)
    used, local = np.unique(faces, return_inverse=True)
    return used, local.reshape(-1, 3)


def _polydata(points, tris):
    import pyvista as pv

    tris = np.asarray(tris, np.int64)
    cells = np.hstack([np.full((len(tris), 1), 3), tris]).ravel()
    return pv.PolyData(np.asarray(points, float), cells)


#: a box's 12 triangles over its 8 corners c[i + 2j + 4k], i, j, k in {0, 1} along its 3 edges
_BOX_TRIS = np.array([t for a, b, c, d in ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2),
                                           (1, 3, 7, 5)) for t in ((a, b, c), (a, c, d))])


def _maze_mesh(walls, lo, hi, top, plate_thickness, wall_height):
    """The plate and its walls in the rod frame: points (p, 3) [mm], triangles (f, 3)."""
    boxes = [((0.0, 0.0), (1.0, 0.0), (lo[0], hi[0]), (lo[1], hi[1]), (top - plate_thickness, top))]
    for a, b in walls:  # a box 2 mm thick centred on the segment a -> b
        L = float(np.linalg.norm(b - a))
        if L > 0.0:
            boxes.append((a, (b - a) / L, (0.0, L), (-1.0, 1.0), (top, top + wall_height)))
    pts = []
    for o, d, us, vs, zs in boxes:  # corners o + u d + v d_perp at heights z
        o, d = np.asarray(o, float), np.asarray(d, float)
        n = np.array([-d[1], d[0]])
        pts += [[*(o + u * d + v * n), z] for z in zs for v in vs for u in us]
    tris = _BOX_TRIS[None] + 8 * np.arange(len(boxes))[:, None, None]
    return np.array(pts, float), tris.reshape(-1, 3)


def _to_palette(img):
    """An (h, w, 3) uint8 screenshot as a deterministic 'P' image (fast octree, no dither)."""
    from PIL import Image

    return Image.fromarray(np.ascontiguousarray(img[..., :3])).quantize(
        colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)


@one_at_a_time
def maze_animation(tets, frames_x, rod_p, rod_R, times, *, walls, plate_lo, plate_hi, top, rod_length,
                   rod_radius=3.0, plate_thickness=3.0, wall_height=6.0, marble=None, marble_radius=4.0,
                   path=None, fps=10, window=(800, 600), title="") -> bytes:
    """An animated GIF (bytes) of the robot, its maze plate and the marble, one frame per sample.

    tets : (m, 4) or (m, 10) node indices (drawn by the boundary of the linear tets);
    frames_x : (K, n, 3) [mm] node positions; rod_p : (K, 3) [mm], rod_R : (K, 3, 3) the rod's
    pose (rod frame -> world: x = rod_p + rod_R @ x_rod; the rod along the rod frame's x);
    times : (K,) [s], in the caption; walls : (w, 2, 2) [mm] segments in the plate's (u, v) =
    rod frame (x, y); plate_lo, plate_hi : (2,) [mm] the plate's (u, v) bounds; top [mm] the
    plate's top face above the rod axis (plate z in [top - plate_thickness, top], walls z in
    [top, top + wall_height], 2 mm thick); rod_length, rod_radius [mm]; marble : None or
    (K, 3) [mm] world centres; path : None or (p, 2) [mm] a line on the plate top;
    fps : frames per second; window : (w, h) pixels of each frame.

    One off-screen plotter draws every frame (only the points move) from one fixed camera,
    looking down from above and a side; frames are reduced to a palette (fast octree, no dither),
    so the same inputs give the same bytes.
    """
    import pyvista as pv

    X = _array("frames_x", frames_x, ("K", "n", 3))
    K, n = X.shape[:2]
    t4 = _tets(tets, n)
    P = _array("rod_p", rod_p, (K, 3))
    R = _array("rod_R", rod_R, (K, 3, 3))
    T = _array("times", times, (K,))
    W = _array("walls", walls, ("w", 2, 2)) if np.size(walls) else np.zeros((0, 2, 2))
    lo, hi = _array("plate_lo", plate_lo, (2,)), _array("plate_hi", plate_hi, (2,))
    if np.any(hi <= lo):
        raise ConfigError(f"plate_hi: {hi.tolist()}: should exceed plate_lo {lo.tolist()} on both axes")
    check_range("top", top)
    for name, v in (("rod_length", rod_length), ("rod_radius", rod_radius), ("plate_thickness", plate_thickness),
                    ("wall_height", wall_height), ("marble_radius", marble_radius), ("fps", fps)):
        check_range(name, v, 0.0, None, lo_open=True)
    M = None if marble is None else _array("marble", marble, (K, 3))
    Q = None if path is None else _array("path", path, ("p", 2))
    w, h = (int(v) for v in window)
    check_range("window", min(w, h), 16, 4096)

    used, tris = _surface(t4)
    sheets = _polydata(X[0, used], tris)
    maze_pts, maze_tris = _maze_mesh(W, lo, hi, float(top), float(plate_thickness), float(wall_height))
    plate = _polydata(maze_pts, maze_tris)
    rod0 = pv.Cylinder(center=(0, 0, 0), direction=(1, 0, 0), radius=float(rod_radius),
                       height=float(rod_length), resolution=24)
    rod_pts, rod_normals = np.array(rod0.points), np.array(rod0.point_data["Normals"])
    rod = rod0.copy()
    line_pts = None
    if Q is not None and len(Q) > 1:
        line_pts = np.column_stack([Q, np.full(len(Q), float(top) + 0.2)])
        line = pv.lines_from_points(line_pts)
    if M is not None:
        sphere0 = pv.Sphere(radius=float(marble_radius), theta_resolution=20, phi_resolution=14)
        sphere_pts = np.array(sphere0.points)
        ball = sphere0.copy()

    def pose(k):
        sheets.points = X[k, used]
        plate.points = P[k] + maze_pts @ R[k].T
        rod.points = P[k] + rod_pts @ R[k].T
        rod.point_data["Normals"] = rod_normals @ R[k].T  # turned with the rod, for its shading
        if line_pts is not None:
            line.points = P[k] + line_pts @ R[k].T
        if M is not None:
            ball.points = M[k] + sphere_pts

    # the fixed camera sees every frame: the union of all frames' bounds
    allp = [X.reshape(-1, 3)] + [P[k] + maze_pts @ R[k].T for k in range(K)]
    allp += [P + R[:, :, 0] * (rod_length / 2), P - R[:, :, 0] * (rod_length / 2)]
    if M is not None:
        allp += [M + marble_radius, M - marble_radius]
    allp = np.concatenate(allp)
    bmin, bmax = allp.min(axis=0), allp.max(axis=0)
    bounds = (bmin[0], bmax[0], bmin[1], bmax[1], bmin[2], bmax[2])

    pl = pv.Plotter(off_screen=True, window_size=(w, h), border=False)
    try:
        pl.set_background("white")
        pose(0)
        pl.add_mesh(sheets, color="lightsteelblue", ambient=0.3)
        pl.add_mesh(plate, color="burlywood", ambient=0.3)
        pl.add_mesh(rod, color="dimgray")
        if line_pts is not None:
            pl.add_mesh(line, color="royalblue", line_width=3)
        if M is not None:
            pl.add_mesh(ball, color="crimson", smooth_shading=True)
        caption = pl.add_text("", position="upper_left", font_size=12, color="black")
        # from above and a side: the plate's top is seen, and the sheets at both rod ends
        pl.view_vector((0.45, -1.0, 1.1), viewup=(0, 0, 1))
        pl.reset_camera(bounds=bounds)
        pl.camera.zoom(1.1)
        frames = []
        for k in range(K):
            pose(k)
            caption.set_text("upper_left", (f"{title}\n" if title else "") + f"t = {T[k]:.3f} s")
            pl.render()
            frames.append(_to_palette(pl.screenshot(return_img=True)))
    finally:
        pl.close()
    buf = io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:],
                   duration=max(int(1000 / fps), 10), loop=0, optimize=False)
    return buf.getvalue()


@one_at_a_time
def modes_picture(points, tets, shapes, frequencies_hz, *, n_show=6, window=(1500, 900), title="") -> bytes:
    """PNG bytes: a 2 x 3 grid of mode shapes, each the sheets' surface moved by the shape.

    points : (n, 3) [mm]; tets : (m, 4) or (m, 10); shapes : (k, n, 3) mode shapes (any
    normalisation: each is scaled so its largest displacement is 8 mm, coloured by that
    scaled |u| [mm]); frequencies_hz : (k,) [Hz]; n_show : 1..6 panels (the first modes);
    window : (w, h) pixels (a title adds a band above).
    """
    import pyvista as pv

    X = _array("points", points, ("n", 3))
    n = len(X)
    t4 = _tets(tets, n)
    S = _array("shapes", shapes, ("k", n, 3))
    F = _array("frequencies_hz", frequencies_hz, (len(S),))
    check_range("n_show", n_show, 1, 6)
    w, h = (int(v) for v in window)
    used, tris = _surface(t4)
    rest = _polydata(X[used], tris)
    outline = rest.extract_feature_edges(feature_angle=30.0, boundary_edges=True, non_manifold_edges=False,
                                         manifold_edges=False)
    pl = pv.Plotter(off_screen=True, shape=(2, 3), window_size=(w, h), border=False)
    try:
        for i in range(min(int(n_show), len(S))):
            pl.subplot(i // 3, i % 3)
            pl.set_background("white")
            u = S[i, used]
            umax = float(np.linalg.norm(u, axis=1).max())
            scale = 8.0 / umax if umax > 0 else 0.0  # largest displacement drawn as 8 mm
            moved = _polydata(X[used] + scale * u, tris)
            moved.point_data["|u| [mm]"] = scale * np.linalg.norm(u, axis=1)
            pl.add_mesh(moved, scalars="|u| [mm]", cmap="viridis", clim=(0.0, 8.0), show_scalar_bar=(i == 0),
                        scalar_bar_args={"title": "|u| drawn [mm]", "color": "black", "vertical": False,
                                         "position_x": 0.3, "position_y": 0.02, "width": 0.4, "height": 0.08})
            if outline.n_points:  # the undeformed outline
                pl.add_mesh(outline, color="black", line_width=1.5, opacity=0.7)
            pl.add_text(f"mode {i + 1}: {F[i]:.1f} Hz", position="upper_edge", font_size=12, color="black")
            pl.view_vector((1.0, -1.2, 0.8), viewup=(0, 0, 1))
            pl.reset_camera()
        img = pl.screenshot(return_img=True)
    finally:
        pl.close()
    if title:
        img = _with_title(img, title)
    return image_png(img)


def _with_title(img, title, band=40):
    """The image with a white band above holding ``title`` (Pillow's default font)."""
    from PIL import Image, ImageDraw, ImageFont

    im = Image.fromarray(np.ascontiguousarray(img[..., :3]))
    out = Image.new("RGB", (im.width, im.height + band), "white")
    out.paste(im, (0, band))
    try:
        font = ImageFont.load_default(size=22)
    except TypeError:  # pragma: no cover - Pillow without FreeType
        font = ImageFont.load_default()
    ImageDraw.Draw(out).text((im.width // 2, band // 2), title, fill="black", font=font, anchor="mm")
    return np.asarray(out)


def _ms(v, digits=1):
    return "-" if v is None else f"{1e3 * float(v):.{digits}f}"


@one_at_a_time
def step_picture(t, responses, targets, labels, metrics, *, title="") -> bytes:
    """PNG bytes: the step response of each of 6 DOFs, normalised, in a 2 x 3 grid.

    t : (T,) [s]; responses : (6, T) each stepped DOF's value (its own unit), drawn as
    (r - r[0]) / (target - r[0]), 0 at the start, 1 at the quasi-static target; targets : (6,)
    the quasi-static values; labels : 6 names (e.g. "x [mm]"); metrics : 6 dicts with rise_s,
    overshoot_pct, settling_s (None: not reached, printed "-"). Lines at 10 / 90 % and the
    +-2 % settling band.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = _array("t", t, ("T",))
    Y = _array("responses", responses, (6, len(t)))
    G = _array("targets", targets, (6,))
    labels, metrics = list(labels), list(metrics)
    if len(labels) != 6:
        raise ConfigError(f"labels: {len(labels)} given and should be 6")
    keys = {"rise_s", "overshoot_pct", "settling_s"}
    if len(metrics) != 6 or not all(isinstance(m, dict) and keys <= set(m) for m in metrics):
        raise ConfigError(f"metrics: should be 6 dicts with the keys {sorted(keys)}")
    step = G - Y[:, 0]
    if np.any(step == 0):
        raise ConfigError(f"targets: {G.tolist()}: each should differ from its response's start")
    Z = (Y - Y[:, :1]) / step[:, None]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
    tm = 1e3 * t  # [ms]
    for i, ax in enumerate(axes.ravel()):
        ax.axhspan(0.98, 1.02, color="C2", alpha=0.15, label="settling band +-2 %")
        for lvl in (0.1, 0.9):
            ax.axhline(lvl, color="0.5", ls=":", lw=1)
        ax.axhline(1.0, color="0.3", ls="--", lw=1)
        ax.plot(tm, Z[i], color="C0", lw=1.5)
        m = metrics[i]
        ov = m["overshoot_pct"]
        txt = (f"rise {_ms(m['rise_s'])} ms\novershoot {'-' if ov is None else f'{float(ov):.1f}'} %\n"
               f"settling {_ms(m['settling_s'])} ms")
        ax.text(0.97, 0.05, txt, transform=ax.transAxes, ha="right", va="bottom", fontsize=9,
                bbox={"facecolor": "white", "edgecolor": "0.7", "alpha": 0.9})
        ax.set_title(f"{labels[i]}: step to {G[i]:.4g}", fontsize=10)
        if i >= 3:
            ax.set_xlabel("time [ms]")
        if i % 3 == 0:
            ax.set_ylabel("normalised response [-]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="lower right", fontsize=7, bbox_to_anchor=(1.0, 0.35))
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return figure_png(fig)


@one_at_a_time
def tracking_picture(t, gap_mm, gap_deg, marble_progress_t, marble_progress, path_length, *, title="") -> bytes:
    """PNG bytes: top, the robot's distance from its quasi-static path (mm left, deg right);
    bottom, the marble's progress along the path [mm] with the path's length dashed.

    t : (T,) [s]; gap_mm, gap_deg : (T,) [mm], [deg]; marble_progress_t : (M,) [s];
    marble_progress : (M,) [mm]; path_length [mm].
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = _array("t", t, ("T",))
    gm = _array("gap_mm", gap_mm, (len(t),))
    gd = _array("gap_deg", gap_deg, (len(t),))
    mt = _array("marble_progress_t", marble_progress_t, ("M",))
    mp = _array("marble_progress", marble_progress, (len(mt),))
    check_range("path_length", path_length, 0.0, None, lo_open=True)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True)
    l1 = a1.plot(t, gm, color="C0", label="position gap [mm]")
    a1.set_ylabel("distance from path [mm]", color="C0")
    a1b = a1.twinx()
    l2 = a1b.plot(t, gd, color="C3", label="rotation gap [deg]")
    a1b.set_ylabel("rotation from path [deg]", color="C3")
    a1.legend(l1 + l2, [ln.get_label() for ln in l1 + l2], loc="upper right", fontsize=8)
    a1.grid(alpha=0.3)
    a1.set_title("robot: distance from its quasi-static path")
    a2.plot(mt, mp, color="C2", label="marble")
    a2.axhline(float(path_length), color="0.3", ls="--", label=f"path length {float(path_length):.1f} mm")
    a2.set_xlabel("time [s]")
    a2.set_ylabel("progress along the path [mm]")
    a2.legend(loc="lower right", fontsize=8)
    a2.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return figure_png(fig)
