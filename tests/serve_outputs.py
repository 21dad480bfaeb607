"""A small pipeline output tree for the serve tests: coarse orient sheets, the paper's foam,
and the robot stage's scene, written without running the (slow) robot stage."""

import contextlib
import json

import meshio
import numpy as np

from metasheet.published import paper
from metasheet.conventions import GRAVITY
from metasheet.pipeline.artefacts import write_jacobian, write_material
from metasheet.sheet.fibers import spiral_fibers
from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

PIPELINE = '[pipeline]\nname = "tiny"\nstages = ["material", "orient", "robot"]\n'


def write_outputs(root, mesh_size: float = 15.0, pipeline: str = PIPELINE):
    """``root/tiny.toml`` and its outputs ``root/out/tiny/{orient,material,robot}``; returns
    (pipeline file, output root)."""
    toml = root / "tiny.toml"
    toml.write_text(pipeline)
    base = root / "out" / "tiny"
    orient, material, robot = (base / n for n in ("orient", "material", "robot"))
    for d in (orient, material, robot):
        d.mkdir(parents=True)
    s = tripod_sheet(SheetParams(mesh_size=mesh_size))
    consts = {k: np.full(len(s.tets), v) for k, v in paper.PAPER_FOAM.to_dict().items()}
    for name, sh, mir in (("sheet.vtu", s, False), ("sheet_mirrored.vtu", mirror_sheet(s), True)):
        fib = spiral_fibers(sh.centroids(), mirrored=mir)
        meshio.write(orient / name, meshio.Mesh(sh.points, [("tetra", sh.tets)], point_data={"attach": sh.attach},
                                                cell_data={"fiber": [fib], **{k: [v] for k, v in consts.items()}}))
    (orient / "sheet.json").write_text(json.dumps({"arm_angles_deg": [0.0, 120.0, 240.0], "element": "p1",
                                                   "geometry": SheetParams(mesh_size=mesh_size).to_dict(),
                                                   "fibers": {}}))  # the default spiral, as above
    write_material(material / "material.json", paper.PAPER_FOAM, density=paper.FOAM_DENSITY, source="config")
    write_jacobian(robot / "jacobian.json", {"geometry": {
        "rod_length_mm": paper.ROD_LENGTH, "scene": "metasheet", "sheet_mass_g": None,
        "gravity_mm_s2": [0.0, 0.0, -GRAVITY],
        "servo_geometry": {"rest_angle_deg": paper.REST_ANGLE, "horn_length_mm": paper.HORN_LENGTH,
                           "angle_min_deg": paper.ANGLE_MIN, "angle_max_deg": paper.ANGLE_MAX}}})
    return toml, root / "out"


REDUCE_PIPELINE = '[pipeline]\nname = "tiny"\nstages = ["material", "orient", "robot", "reduce"]\n'


def write_reduce(root, out, *, snapshots: int = 8, box_deg: float = 8.0, held_out: int = 1):
    """Run the reduce stage itself on ``out/tiny`` (its robot recipe, training and
    certificate; ~5 s on the 15 mm sheets): ``out/tiny/reduce/{basis.npz,reduce.json}``."""
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import reduce as stage

    base = out / "tiny"
    work = base / "reduce"
    work.mkdir()
    # one training round: these tests serve a basis, they do not certify one (tests/test_reduce_adapt.py
    # does; the defaults' second round made this 5 s fixture 55 s)
    params = stage.ReduceParams(snapshots=snapshots, box_deg=box_deg, held_out=held_out, resume=False, adapt_rounds=1)
    inputs = {name: base / name for name in ("orient", "material", "robot")}
    return stage.run(StageContext("reduce", params, work, inputs, root))


@contextlib.contextmanager
def live_page(session, outputs, model: str):
    """A :class:`metasheet.serve.app.Page` on a real (browserless) viser server on a free
    loopback port, closed and stopped afterwards."""
    import socket

    import viser

    from metasheet.serve.app import Page

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    page = Page(server, session, outputs, strain_limit=0.3, model=model)
    try:
        yield page
    finally:
        page.close()
        server.stop()
