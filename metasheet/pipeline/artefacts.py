"""Stage artefacts on disk: every file one stage writes and another reads, in one place.

A stage reads its upstream stages only through the readers here, and the files other
stages read are written by the writers here, side by side, so a file's layout is defined
once. A missing file or field is a :class:`~metasheet.errors.ConfigError` naming the file;
nothing falls back silently to a default material or geometry.

| stage      | artefact                                  | reader / writer                      |
|------------|-------------------------------------------|--------------------------------------|
| cell       | ``cell.json``, ``voxels.npz``, ``cell.vtu`` | :func:`read_cell`, :func:`read_cell_tets` |
| homogenize | ``constants.json``                        | :func:`read_constants`               |
| chart      | ``chart.csv``                             | :func:`read_chart`                   |
| material   | ``material.json``                         | :func:`write_material`, :func:`read_material` |
| orient     | ``sheet.vtu``, ``sheet_mirrored.vtu``, ``sheet.json`` | :func:`write_sheet`, :func:`read_orient` |
| robot      | ``jacobian.json``, ``rest.vtu``           | :func:`write_jacobian`, :func:`read_robot_scene`, :func:`write_rest_vtu` |
| studies    | ``<stage>.json`` or the manifest's summary | :func:`read_summary`                 |

Stage-private outputs (pictures, print fields, local strain fields) are written by their
stage modules, which like this one belong to the pipeline layer: no code below it does I/O.
Every mesh file is read by :func:`read_mesh`: a corrupt one is a
:class:`~metasheet.errors.MeshError` naming it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..conventions import GRAVITY
from ..errors import ConfigError, MeshError
from ..mechanics.material import CONSTANT_NAMES, TransverseIsotropic
from ..mechanics.material_model import authors_effective, check_model, model_stiffness
from ..robot.builder import SheetPair
from ..robot.scenes import RobotScene  # noqa: F401  (the robot stage's scene; read_robot_scene returns it)
from ..sheet.geometry import SheetMesh
from ..sheet.outline import SheetParams
from ..runtime.stop_signals import Stopped
from .manifest import read_manifest, write_json_atomic

SHEET_FILES = {"normal": "sheet.vtu", "mirrored": "sheet_mirrored.vtu"}


def read_mesh(path: Path):
    """The ``meshio.Mesh`` in ``path``; every reader failure is a :class:`MeshError` naming the file.

    The one place the project reads a mesh file. ``meshio.read`` prints its reader's error
    and calls ``sys.exit(1)`` on a file it cannot parse (meshio 5.3): that exit status is
    ``metasheet diff``'s "trees differ", and no ``error:`` line is printed. So a VTU goes
    straight to meshio's VTU reader (it raises ``meshio.ReadError``), and whatever a reader
    raises on corrupt bytes (ReadError, ValueError, an XML ParseError, zlib's error,
    SystemExit) becomes one message saying to rerun the stage that wrote the file
    (``metasheet run`` rewrites outputs whose bytes no longer match their manifest).
    """
    import meshio

    path = Path(path)
    reader = meshio.vtu.read if path.suffix.lower() == ".vtu" else meshio.read
    try:
        return reader(str(path))
    except (Exception, SystemExit) as exc:  # noqa: BLE001  (any parse failure of corrupt bytes)
        if isinstance(exc, Stopped):  # a stop signal during the read: the run unwinds
            raise
        cause = type(exc).__name__ + (f": {exc}" if str(exc) else "")  # meshio's ReadError has no text
        raise MeshError(f"{path}: unreadable mesh file ({cause}): it is corrupt or truncated; rerun the stage "
                        "that wrote it (`metasheet run PIPELINE` rewrites outputs whose bytes changed)") from exc


def _json(path: Path) -> dict:
    if not path.is_file():
        raise ConfigError(f"{path}: missing (did its stage run?)")
    try:
        return json.loads(path.read_text())
    except ValueError as exc:
        raise ConfigError(f"{path}: not valid JSON: {exc}") from exc


def _field(data: dict, key: str, path: Path):
    if key not in data:
        raise ConfigError(f"{path}: no field {key!r}")
    return data[key]


# ------------------------------------------------------------------------------- cell

@dataclass(frozen=True)
class CellFile:
    """The cell stage's artefact: ``info`` (cell.json), ``phases`` (nx, ny, nz) int (0 void),
    ``size`` (3,) [mm], ``axis`` (3,) the design's longitudinal axis or None."""

    info: dict
    phases: np.ndarray
    size: np.ndarray
    axis: np.ndarray | None


def read_cell(directory: Path) -> CellFile:
    """``cell.json`` and ``voxels.npz`` of a cell stage's output directory."""
    info = _json(directory / "cell.json")
    npz = directory / "voxels.npz"
    if not npz.is_file():
        raise ConfigError(f"{npz}: missing (did the cell stage run?)")
    with np.load(npz) as z:
        phases = z["phases"].astype(np.int64)
        size = z["size"].astype(float)
        axis = z["axis"].astype(float) if "axis" in z else None
    return CellFile(info, phases, size, axis)


def read_cell_tets(directory: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``cell.vtu``: points (n, 3) [mm], tets (m, 4), per-tet phase (m,) or None."""
    vtu = directory / "cell.vtu"
    if not vtu.exists():
        raise ConfigError("homogenize.mesh_route: true: the cell stage wrote no cell.vtu (set cell.tet_mesh = true)")
    mesh = read_mesh(vtu)
    tets = mesh.get_cells_type("tetra")
    phase = None
    for name in ("phase", "phases"):
        if name in mesh.cell_data_dict and "tetra" in mesh.cell_data_dict[name]:
            phase = np.asarray(mesh.cell_data_dict[name]["tetra"]).astype(np.int64)
    return mesh.points, tets, phase


def read_cell_density(directory: Path) -> float | None:
    """The cell's relative density [-] from ``cell.json``, None when it records none."""
    f = directory / "cell.json"
    if not f.exists():
        return None
    rho = _json(f).get("relative_density")
    return None if rho is None else float(rho)


# ----------------------------------------------------------------- homogenize, chart

def read_constants(directory: Path) -> dict:
    """``constants.json`` of a homogenize stage (the five constants, C, misfit...)."""
    return _json(directory / "constants.json")


def constants_material(directory: Path) -> TransverseIsotropic:
    """The transverse-isotropic fit a homogenize stage wrote."""
    path = directory / "constants.json"
    return TransverseIsotropic.from_mapping(read_constants(directory), where=str(path))


def read_chart(directory: Path) -> dict[str, np.ndarray]:
    """``chart.csv`` of a chart stage: column -> array."""
    from ..homogenize.chart import parse_csv

    path = directory / "chart.csv"
    if not path.is_file():
        raise ConfigError(f"{path}: missing (did the chart stage run?)")
    return parse_csv(path.read_text())


def read_cell_info(directory: Path) -> dict:
    """``cell.json`` of a cell stage: the design, the achieved density, the geometry."""
    return _json(Path(directory) / "cell.json")


def read_cell_design(directory: Path) -> dict:
    """The validated design a cell stage built (``cell.json``'s ``design``), as a dict."""
    return dict(read_cell_info(directory).get("design", {}))


def read_print_model(chart_dir: Path, cell_dir: Path | None = None, homogenize_dir: Path | None = None):
    """The print model of a chart stage, calibrated on the homogenised cell when both are given.

    Returns a :class:`~metasheet.homogenize.printmodel.PrintModel`. The chart must sweep the
    cell's own family (a strut-foam chart cannot describe a Polyfoam cell): ConfigError otherwise.
    """
    from ..homogenize.chart import FAMILY_AXES
    from ..homogenize.printmodel import model_from_chart

    model = model_from_chart(read_chart(chart_dir))
    if cell_dir is None or homogenize_dir is None:
        return model
    design = read_cell_design(cell_dir)
    family = design.get("kind", "foam")
    if family != model.family:
        raise ConfigError(f"chart.design: a {model.family} chart cannot describe the cell stage's {family} cell; "
                          f"give the chart the cell's design")
    if family == "foam":
        settings = {"target_density": float(design["relative_density"]), "stretch": float(design.get("metric", {}).get("stretch", 1.0))}
    else:
        settings = {k: float(design[k]) for k in FAMILY_AXES[family]}
    return model.calibrated(settings, read_constants(homogenize_dir))


# --------------------------------------------------------------------------- material

@dataclass(frozen=True)
class MaterialFile:
    """``material.json``: the sheets' ``material``, mass ``density`` [t/mm^3], ``source`` and
    the material ``model`` the robot builds its tensor with (:mod:`metasheet.mechanics.material_model`)."""

    material: TransverseIsotropic
    density: float
    source: str
    model: str = "ours"
    ci95: dict | None = None  # homogenize's 95 % half-widths of the constants, when it had realisations


def write_material(path: Path, material: TransverseIsotropic, *, density: float, source: str,
                   model: str = "ours", ci95: dict | None = None, choice: dict | None = None) -> None:
    """``material.json``: constants, units, derived nu_lt and alpha, stiffness and compliance
    (of the five constants), the material ``model`` and the tensor the robot uses under it
    (``model_stiffness``); under "authors" also the constants that tensor really has; ``choice``:
    why ``source = "auto"`` took this source."""
    check_model(model)
    units = {k: ("-" if k.startswith("nu") else "MPa") for k in CONSTANT_NAMES}
    extra = {"authors_effective_constants": authors_effective(material).to_dict()} if model == "authors" else {}
    write_json_atomic(path, {
        "model": model,
        "model_stiffness": model_stiffness(material, model),
        **extra,
        "source": source,
        "constants": material.to_dict(),
        "units": {**units, "density": "t/mm^3"},
        "nu_lt": material.nu_lt,
        "alpha_percent": material.alpha,
        "density": density,
        "voigt_order": ["11", "22", "33", "23", "13", "12"],
        "longitudinal_axis": "local 3",
        "stiffness": material.stiffness(),
        "compliance": material.compliance(),
        **({"ci95": ci95} if ci95 else {}),
        **({"choice": choice} if choice else {}),
    })


def read_material(directory: Path) -> MaterialFile:
    """``material.json`` of a material stage's output directory."""
    path = directory / "material.json"
    data = _json(path)
    m = TransverseIsotropic.from_mapping(_field(data, "constants", path), where=f"{path}: constants")
    model = check_model(str(_field(data, "model", path)), f"{path}: model")
    return MaterialFile(m, float(_field(data, "density", path)), str(data.get("source", "")), model, data.get("ci95"))


# ---------------------------------------------------------------------------- orient

def write_sheet(path: Path, sheet: SheetMesh, cell_data: dict[str, np.ndarray]) -> None:
    """A sheet VTU: the tets, point data ``attach`` and the given per-element ``cell_data``."""
    import meshio

    mesh = meshio.Mesh(
        sheet.points, [("tetra", sheet.tets)],
        point_data={"attach": sheet.attach.astype(np.int32)},
        cell_data={k: [np.asarray(v)] for k, v in cell_data.items()},
    )
    meshio.write(path, mesh, file_format="vtu")


@dataclass(frozen=True)
class SheetFile:
    """One sheet VTU: the ``mesh``, ``fibers`` (m, 3), ``constants`` (m, 5) in
    :data:`~metasheet.mechanics.material.CONSTANT_NAMES` order or None, and every cell field."""

    mesh: SheetMesh
    fibers: np.ndarray
    constants: np.ndarray | None
    cell_data: dict


def read_sheet(path: Path, arm_angles_deg=(0.0, 120.0, 240.0)) -> SheetFile:
    """A sheet VTU written by :func:`write_sheet` (arm directions from sheet.json)."""
    if not Path(path).is_file():
        raise ConfigError(f"{path}: missing (did the orient stage run?)")
    m = read_mesh(path)
    tets = np.asarray(m.cells_dict.get("tetra", np.zeros((0, 4))), dtype=np.int64)
    if len(tets) == 0:
        raise ConfigError(f"{path}: no tetra cells")
    cd = {k: np.asarray(v[0]) for k, v in m.cell_data.items()}
    if "fiber" not in cd or "attach" not in m.point_data:
        raise ConfigError(f"{path}: needs cell data 'fiber' and point data 'attach' (the orient stage's sheet)")
    consts = np.column_stack([cd[k] for k in CONSTANT_NAMES]) if all(k in cd for k in CONSTANT_NAMES) else None
    mesh = SheetMesh(np.asarray(m.points, float), tets, np.asarray(m.point_data["attach"]).astype(int).ravel(),
                     np.radians(np.asarray(arm_angles_deg, float)))
    return SheetFile(mesh, np.asarray(cd["fiber"], float), consts, cd)


@dataclass(frozen=True)
class OrientFile:
    """The orient stage's artefact: both sheets (with fibres and per-element constants) and
    ``info`` (sheet.json: geometry, fibre law, material, grading)."""

    normal: SheetFile
    mirrored: SheetFile
    info: dict
    directory: Path

    def sheets(self, *, need_constants: bool = True) -> SheetPair:
        """The pair the robot builder takes; ``need_constants``: both VTUs must carry the five
        per-element constants (an error naming the file otherwise, never a default)."""
        if need_constants:
            for f, name in ((self.normal, SHEET_FILES["normal"]), (self.mirrored, SHEET_FILES["mirrored"])):
                if f.constants is None:
                    raise ConfigError(f"{self.directory / name}: no per-element constants "
                                      f"({', '.join(CONSTANT_NAMES)}): rerun the orient stage")
        return SheetPair(self.normal.mesh, self.mirrored.mesh, self.normal.fibers, self.mirrored.fibers,
                         self.normal.constants, self.mirrored.constants, self.element)

    @property
    def element(self) -> str:
        """The robot's element on these sheets ("p1" for outputs written before it was recorded)."""
        return str(self.info.get("element", "p1"))

    @property
    def graded(self) -> bool:
        return bool(self.info.get("graded", False))

    @property
    def fiber_settings(self) -> dict:
        """Keyword arguments of :func:`metasheet.sheet.fibers.spiral_fibers` the sheets were made with."""
        fib = _field(self.info, "fibers", self.directory / "sheet.json")
        return {k: fib[k] for k in ("law", "pitch_deg", "tilt_deg", "r_ref") if k in fib}

    @property
    def fibre_field(self) -> dict | None:
        """``sheet.json``'s ``fibers.fibre_field`` (the ``[orient] fibre_field`` with its
        ``r_max`` resolved), or None: the law's spiral alone."""
        return _field(self.info, "fibers", self.directory / "sheet.json").get("fibre_field")

    def fibers_at(self, points, mirrored: bool = False) -> np.ndarray:
        """(q, 3) unit fibres the sheets were made with, at ``points`` (q, 3) [mm] of sheet A's
        frame (``mirrored``: sheet B's): the law's spiral, corrected by ``fibre_field``. The one
        place a re-mesh or a print map turns orient's fibre field into fibres."""
        from ..sheet.fibers import spiral_fibers

        fs, rec = self.fiber_settings, self.fibre_field
        if rec is None:
            return spiral_fibers(points, mirrored=mirrored, **fs)
        from ..sheet.fibre_field import PolarBSpline, field_at

        basis = PolarBSpline(n_radial=int(rec["n_radial"]), n_angular=int(rec["n_angular"]),
                             degree=int(rec["degree"]), r_max=float(rec["r_max"]), symmetric=bool(rec["symmetric"]))
        return field_at(points, lambda q: spiral_fibers(q, mirrored=False, **fs), basis,
                        np.asarray(rec["coefficients"], float), mirrored)

    @property
    def scene(self) -> "RobotScene":
        """The robot scene the orient stage chose (``sheet.json``'s ``scene``: a preset of
        :mod:`metasheet.robot.scenes`); sheet.json without one (older runs): ``metasheet``."""
        from ..robot.scenes import get_preset

        rec = self.info.get("scene") or {"name": "metasheet"}
        preset = get_preset(rec.get("name", "metasheet"), key=f"{self.directory / 'sheet.json'}: scene.name")
        mass = rec.get("sheet_mass_g", preset.sheet_mass_g)
        return RobotScene(preset.rod_length, preset.rest_angle, preset.horn_length, preset.angle_min,
                          preset.angle_max, servo_radius=preset.servo_radius, servo_depth=preset.servo_depth,
                          sheet_mass_g=None if mass is None else float(mass), gravity=tuple(preset.gravity),
                          scene=preset.name)

    @property
    def sheet_params(self) -> SheetParams:
        """The sheet geometry the orient stage meshed."""
        g = dict(_field(self.info, "geometry", self.directory / "sheet.json"))
        g["tip_box"] = tuple(g["tip_box"])
        return SheetParams(**g)


def read_orient(directory: Path) -> OrientFile:
    """``sheet.json``, ``sheet.vtu`` and ``sheet_mirrored.vtu`` of an orient stage."""
    info = _json(directory / "sheet.json")
    ang = info.get("arm_angles_deg", [0.0, 120.0, 240.0])
    return OrientFile(read_sheet(directory / SHEET_FILES["normal"], ang),
                      read_sheet(directory / SHEET_FILES["mirrored"], ang), info, directory)


# ----------------------------------------------------------------------------- robot

def write_jacobian(path: Path, data: dict) -> None:
    """``jacobian.json``: per material the Jacobian, compliance and singular values, and
    ``geometry`` (the robot's scene: servo geometry, rod length, counts)."""
    path.write_text(json.dumps(data, indent=1, sort_keys=True))


def _opt(v):
    return None if v is None else float(v)


def read_robot_scene(directory: Path) -> RobotScene:
    """The scene recorded in a robot stage's ``jacobian.json`` (``geometry``)."""
    path = directory / "jacobian.json"
    geo = _field(_json(path), "geometry", path)
    sg = _field(geo, "servo_geometry", path)
    try:
        return RobotScene(float(geo["rod_length_mm"]), _opt(sg["rest_angle_deg"]), float(sg["horn_length_mm"]),
                          float(sg["angle_min_deg"]), float(sg["angle_max_deg"]),
                          servo_radius=_opt(sg.get("servo_radius_mm")), servo_depth=_opt(sg.get("servo_depth_mm")),
                          sheet_mass_g=_opt(geo.get("sheet_mass_g")),
                          gravity=tuple(float(g) for g in geo.get("gravity_mm_s2", (0.0, 0.0, -GRAVITY))),
                          scene=str(geo.get("scene", "metasheet")))
    except KeyError as exc:
        raise ConfigError(f"{path}: geometry lacks {exc.args[0]!r}: rerun the robot stage") from exc


def write_rest_vtu(path: Path, robot, state) -> None:
    """``rest.vtu``: both sheets at ``state`` (world frame, quadratic cells for a p2 robot);
    cell data ``sheet`` (0 = A,
    1 = B), point data ``attach`` (0 free, k + 1 horn of motor k, 99 effector) and
    ``displacement`` from the unloaded rest [mm]."""
    import meshio

    from ..sheet.elements import meshio_cells

    c = robot.coupling
    tags = np.zeros(len(c.rest), dtype=np.int32)
    tags[c.effector_nodes] = 99
    for k, s in enumerate(c.servos):
        tags[s.nodes] = k + 1
    n_a = robot.info.get("n_tets_per_sheet", [len(robot.body.tets)])[0]
    sheet = (np.arange(len(robot.body.tets)) >= n_a).astype(np.int32)
    meshio.write(path, meshio.Mesh(
        state.x, [meshio_cells(robot.body.tets)],
        point_data={"attach": tags, "displacement": state.x - c.rest},
        cell_data={"sheet": [sheet]}), binary=True)


# --------------------------------------------------------------------------- studies

def read_summary(directory: Path, name: str | None) -> dict | None:
    """A stage's summary: ``<name>.json`` when it writes one (``name`` None: never), else its
    manifest's ``summary``."""
    f = directory / f"{name}.json"
    if name is not None and f.exists():
        return _json(f)
    man = read_manifest(directory)
    return man.get("summary") if man else None
