"""The ``cell`` stage: outputs, determinism, surfaces, pictures (issue 3, item 8)."""

import hashlib
import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.registry import StageContext, stages
from metasheet.pipeline.stages.cell import CellParams, run

ROOT = Path(__file__).resolve().parents[1]


def _run(tmp_path, name="run", **params):
    out = tmp_path / name
    out.mkdir()
    summary = run(StageContext("cell", CellParams(**params), out, {}, ROOT))
    return out, summary


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_stage_is_registered():
    st = stages()["cell"]
    assert st.params is CellParams and "voxels.npz" in st.outputs


def test_voxels_and_json_without_surface(tmp_path):
    out, summary = _run(tmp_path, design="cells/quick_foam.toml", surface=False, picture=False)
    assert sorted(p.name for p in out.iterdir()) == ["cell.json", "voxels.npz"]
    with np.load(out / "voxels.npz") as z:
        assert z["phases"].dtype == np.uint8 and z["phases"].shape == (32, 32, 32)
        assert z["size"].tolist() == [6.0, 6.0, 6.0] and z["axis"].tolist() == [0.0, 0.0, 1.0]
        rho = float(np.count_nonzero(z["phases"])) / z["phases"].size
    info = json.loads((out / "cell.json").read_text())
    assert info["relative_density"] == pytest.approx(rho)
    assert abs(rho - 0.15) <= 0.005
    assert info["materials"] == {"1": {"E": 12.0, "nu": 0.3}}
    assert info["strut_radius_mm"] > 0 and info["connectivity"]["ok"]
    assert info["design"]["seeds"]["count"] == 12
    assert summary["percolates"] is True


def test_same_seed_gives_the_same_bytes(tmp_path):
    a, _ = _run(tmp_path, "a", design="cells/quick_foam.toml", surface=False, picture=False)
    b, _ = _run(tmp_path, "b", design="cells/quick_foam.toml", surface=False, picture=False)
    c, _ = _run(tmp_path, "c", design="cells/quick_foam.toml", surface=False, picture=False, seed=5)
    assert _sha(a / "voxels.npz") == _sha(b / "voxels.npz")
    assert _sha(a / "cell.json") == _sha(b / "cell.json")
    assert _sha(a / "voxels.npz") != _sha(c / "voxels.npz")


def test_surface_and_picture(tmp_path):
    import matplotlib.image as mpimg
    import trimesh

    out, _ = _run(tmp_path, design="cells/quick_foam.toml")
    mesh = trimesh.load(out / "cell.stl")
    assert mesh.is_watertight and mesh.volume > 0
    info = json.loads((out / "cell.json").read_text())
    assert info["surface"]["manifold"]
    # the surface encloses the voxels' volume (3 % at n = 64; this cell is 32^3)
    assert mesh.volume / 216.0 == pytest.approx(info["relative_density"], rel=0.05)
    img = mpimg.imread(out / "cell.png")
    assert img.shape[0] > 400 and img.std() > 0.05  # written and not blank
    assert len(np.unique((img[..., :3] * 255).astype(int).reshape(-1, 3), axis=0)) > 100


@pytest.mark.parametrize("design", ["laminate", "solid"])
def test_layered_and_solid_cells_give_a_box_surface(tmp_path, design):
    out, _ = _run(tmp_path, design=f"cells/{design}.toml", resolution=16)
    import trimesh

    mesh = trimesh.load(out / "cell.stl")
    assert mesh.is_watertight and mesh.volume == pytest.approx(1000.0)
    info = json.loads((out / "cell.json").read_text())
    assert info["relative_density"] == 1.0
    expected = {"1", "2"} if design == "laminate" else {"1"}
    assert set(info["materials"]) == expected
    assert (out / "cell.png").stat().st_size > 1000


def test_tet_mesh(tmp_path):
    import meshio

    out, _ = _run(tmp_path, design="cells/quick_foam.toml", picture=False, tet_mesh=True, tet_size=0.25)
    m = meshio.read(out / "cell.vtu")
    assert len(m.cells_dict["tetra"]) > 1000
    info = json.loads((out / "cell.json").read_text())["tet_mesh"]
    assert info["max_mismatch_mm"] < 1e-9 * 6.0 and info["components"] == 1


def test_too_coarse_a_tet_mesh_is_refused(tmp_path):
    from metasheet.errors import MeshError

    with pytest.raises(MeshError, match="cell.tet_size: 0.4 mm: .* pieces"):
        _run(tmp_path, design="cells/quick_foam.toml", picture=False, tet_mesh=True, tet_size=0.4)


def test_laminate_refuses_a_tet_mesh(tmp_path):
    with pytest.raises(ConfigError, match="cell.tet_mesh"):
        _run(tmp_path, design="cells/laminate.toml", tet_mesh=True, picture=False)


def test_bad_design_path_and_overrides_name_the_field(tmp_path):
    with pytest.raises(ConfigError, match="cell.design: 'cells/nope.toml'"):
        _run(tmp_path, "a", design="cells/nope.toml")
    with pytest.raises(Exception, match="resolution"):
        CellParams(design="cells/quick_foam.toml", resolution=8)


def test_cell_stage_in_a_pipeline(tmp_path):
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "cells").mkdir()
    shutil.copy(ROOT / "cells" / "quick_foam.toml", tmp_path / "cells")
    (tmp_path / "pipelines").mkdir()
    pipe = tmp_path / "pipelines" / "t.toml"
    pipe.write_text(
        '[pipeline]\nname = "t"\nstages = ["cell"]\n\n[cell]\ndesign = "cells/quick_foam.toml"\n'
        "surface = false\npicture = false\n"
    )
    outcomes = run_pipeline(load_pipeline(pipe), out_root=tmp_path / "outputs")
    assert [o.status for o in outcomes] == ["ran"]
    assert (tmp_path / "outputs" / "t" / "cell" / "voxels.npz").is_file()
    again = run_pipeline(load_pipeline(pipe), out_root=tmp_path / "outputs")
    assert [o.status for o in again] == ["cached"]
    # editing the design file invalidates the cache
    text = (tmp_path / "cells" / "quick_foam.toml").read_text().replace("seed = 2", "seed = 4")
    (tmp_path / "cells" / "quick_foam.toml").write_text(text)
    assert [o.status for o in run_pipeline(load_pipeline(pipe), out_root=tmp_path / "outputs")] == ["ran"]
    assert tomllib.loads(text)["seeds"]["seed"] == 4
