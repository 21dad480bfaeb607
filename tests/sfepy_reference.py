"""Independent reference: SfePy's homogenisation of the same voxel mesh, in a subprocess.

Used by ``tests/test_homogenize_sfepy.py`` and ``benchmarks/bench_homogenize.py``.
SfePy builds its own (non-periodic) hexahedral mesh of the solid voxels, ties opposite
faces with its periodic boundary conditions (EPBCs) and computes
``D_IJ = (1/|Y|) int (Pi_I + chi_I) : D : (Pi_J + chi_J)`` with its own assembly, solver
and quadrature, so agreement checks our assembly, periodicity, load cases and energy
form independently.

Traps handled (``../shared/reference/SOLVERS.md``):

- one subprocess per problem: SfePy's plane-matching cache (``periodic_cache``) is keyed
  by array shapes only, so a second problem in one process can reuse a wrong matching;
  our matching functions below do not use it either;
- no "Corners" region (empty when the solid misses the box corners): one interior
  vertex is fixed instead, which removes the translations exactly as our pinned node;
- opposite faces must carry the same vertices: :func:`faces_match` checks it and the
  caller chooses a cell whose boundary voxel slices coincide (then the non-periodic
  mesh with its EPBCs is exactly our periodic mesh);
- the box volume is passed as 1 and divided out here (SfePy formats a given volume
  with ``%e``, i.e. 7 significant digits, which would spoil a 1e-6 comparison);
- SfePy's Voigt order is 11, 22, 33, 12, 13, 23 (engineering shear): permuted here.

Run as a script only by :func:`sfepy_stiffness` (``python sfepy_reference.py job.npz out.npz``).
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: our Voigt index (11, 22, 33, 23, 13, 12) -> SfePy's index (11, 22, 33, 12, 13, 23)
TO_SFEPY = np.array([0, 1, 2, 5, 4, 3])


def sfepy_available() -> bool:
    return importlib.util.find_spec("sfepy") is not None


def faces_match(keep: np.ndarray) -> bool:
    """True when the first and last voxel slices along every axis coincide.

    Then the vertices of the solid on opposite faces of the non-periodic mesh (and on
    the four images of every edge and the eight of every corner) coincide too.
    """
    return all(np.array_equal(np.take(keep, 0, axis=a), np.take(keep, -1, axis=a)) for a in range(3))


def sfepy_stiffness(phases, size, stiffness: dict, *, ls: str = "ls.auto_direct",
                    timeout: float = 900.0) -> tuple[np.ndarray, dict]:
    """SfePy's effective stiffness of a voxel cell (run in a fresh Python process).

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k = phase k; every solid voxel is kept (remove
        non-percolating islands before, as :func:`~metasheet.homogenize.homogenize_voxels` does).
    size : (3,) box edge lengths [mm].
    stiffness : phase -> (6, 6) Voigt stiffness in OUR order [MPa].
    ls : SfePy's linear solver: "ls.auto_direct" (MUMPS, UMFPACK or SuperLU, whichever
        is installed) or "ls.cholesky" (scikit-sparse CHOLMOD, as our direct route).
    timeout : seconds before the subprocess is killed.

    Returns
    -------
    C : (6, 6) [MPa] in our Voigt order; info : {"seconds": SfePy's homogenisation
    (mesh set-up, assembly, factorisation, six solves, coefficients), "wall": the whole
    subprocess including imports, "n_dof": its field's dofs (before the periodic ties and
    the fixed vertex remove some), "solver": SfePy's linear solver}.
    """
    with tempfile.TemporaryDirectory(prefix="sfepy_hom_") as tmp:
        job, out = Path(tmp) / "job.npz", Path(tmp) / "out.npz"
        keys = sorted(stiffness)
        np.savez(job, phases=np.asarray(phases), size=np.asarray(size, float), keys=np.array(keys), ls=ls,
                 D=np.array([np.asarray(stiffness[k])[np.ix_(TO_SFEPY, TO_SFEPY)] for k in keys]))
        t = time.perf_counter()
        proc = subprocess.run([sys.executable, __file__, str(job), str(out)], capture_output=True, text=True,
                              timeout=timeout, cwd=tmp, env={**os.environ, "PYTHONHASHSEED": "0"})
        wall = time.perf_counter() - t
        if proc.returncode != 0 or not out.exists():
            raise RuntimeError(f"SfePy subprocess failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        res = np.load(out)
        inv = np.argsort(TO_SFEPY)
        C = np.asarray(res["D"])[np.ix_(inv, inv)]
        return C, {"seconds": float(res["seconds"]), "wall": wall, "n_dof": int(res["n_dof"]),
                   "solver": str(res["solver"])}


def _mesh(phases, size):
    """Non-periodic hex mesh (SfePy's 3_8 order) of the solid voxels: coors, conn, mat_ids."""
    shape = np.array(phases.shape)
    h = np.asarray(size, float) / shape
    ijk = np.argwhere(phases > 0)
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    c = ijk[:, None, :] + corners[None]
    g = shape + 1
    flat = (c[..., 0] * g[1] + c[..., 1]) * g[2] + c[..., 2]
    used, conn = np.unique(flat, return_inverse=True)
    coors = np.stack(np.unravel_index(used, tuple(g)), axis=1) * h
    mat_ids = phases[tuple(ijk.T)].astype(np.int32)
    return coors, conn.reshape(-1, 8).astype(np.int32), mat_ids


def _matcher(axis):
    """Match vertices of two opposite faces by their other two coordinates (no cache)."""

    def match(coors1, coors2, get_saved=False):
        if coors1.shape != coors2.shape:
            raise ValueError(f"opposite faces normal to axis {axis} have different vertex counts "
                             f"{coors1.shape[0]} != {coors2.shape[0]}")
        other = [a for a in range(coors1.shape[1]) if a != axis]
        i1 = np.lexsort(coors1[:, other].T)
        i2 = np.lexsort(coors2[:, other].T)
        if not np.allclose(coors1[i1][:, other], coors2[i2][:, other], atol=1e-9):
            raise ValueError(f"cannot match the faces normal to axis {axis}")
        return i1, i2

    return match


def _run(job_path: str, out_path: str) -> None:
    from sfepy.base.base import Struct
    from sfepy.base.conf import ProblemConf, get_standard_keywords
    from sfepy.discrete.fem import Mesh
    import sfepy.homogenization.coefs_base as cb
    from sfepy.homogenization.homogen_app import HomogenizationApp

    job = np.load(job_path)
    phases, size = job["phases"], job["size"]
    coors, conn, mat_ids = _mesh(phases, size)
    mesh_file = str(Path(out_path).parent / "cell.vtk")
    Mesh.from_data("cell", coors, None, [conn], [mat_ids], ["3_8"]).write(mesh_file, io="auto")
    eps = 1e-6 * float(np.min(size / np.array(phases.shape)))
    # an interior vertex (not on any face) to fix: removes the translations
    inner = np.all((coors > eps) & (coors < size - eps), axis=1)
    fix = int(np.flatnonzero(inner)[0])
    x, y, z = size
    regions = {
        "Y": "all",
        "Left": (f"vertices in (x < {eps:.17g})", "facet"),
        "Right": (f"vertices in (x > {x - eps:.17g})", "facet"),
        "Near": (f"vertices in (y < {eps:.17g})", "facet"),
        "Far": (f"vertices in (y > {y - eps:.17g})", "facet"),
        "Bottom": (f"vertices in (z < {eps:.17g})", "facet"),
        "Top": (f"vertices in (z > {z - eps:.17g})", "facet"),
        "Fix": (f"vertex {fix}", "vertex"),
    }
    D = {}
    for k, Dk in zip(job["keys"], job["D"]):
        regions[f"Y{k}"] = f"cells of group {int(k)}"
        D[f"Y{k}"] = Dk
    conf = {
        "filename_mesh": mesh_file,
        "regions": regions,
        "materials": {"mat": ({"D": D},)},
        "fields": {"corrector": ("real", 3, "Y", 1)},
        "variables": {
            "u": ("unknown field", "corrector", 0),
            "v": ("test field", "corrector", "u"),
            "Pi": ("parameter field", "corrector", "u"),
            "Pi1": ("parameter field", "corrector", "(set-to-None)"),
            "Pi2": ("parameter field", "corrector", "(set-to-None)"),
        },
        "functions": {f"match_{a}": (_matcher(i),) for i, a in enumerate("xyz")},
        "ebcs": {"fixed_u": ("Fix", {"u.all": 0.0})},
        "epbcs": {
            "periodic_x": (["Left", "Right"], {"u.all": "u.all"}, "match_x"),
            "periodic_y": (["Near", "Far"], {"u.all": "u.all"}, "match_y"),
            "periodic_z": (["Bottom", "Top"], {"u.all": "u.all"}, "match_z"),
        },
        # order 2 on hexahedra = 2 x 2 x 2 Gauss points: exact for trilinear box elements
        "integrals": {"i": 2},
        "options": {"coefs": "coefs", "requirements": "requirements", "ls": "ls",
                    "volume": {"value": 1.0}, "output_dir": str(Path(out_path).parent / "output"),
                    "coefs_filename": "coefs",
                    # in-process: its worker pool would pickle the matching closures (and
                    # our route runs in one process too, so the timings compare like with like)
                    "multiprocessing": False},
        "coefs": {
            "D": {"requires": ["pis", "corrs_rs"], "expression": "dw_lin_elastic.i.Y(mat.D, Pi1, Pi2)",
                  "set_variables": [("Pi1", ("pis", "corrs_rs"), "u"), ("Pi2", ("pis", "corrs_rs"), "u")],
                  "class": cb.CoefSymSym},
            "filenames": {},
        },
        "requirements": {
            "pis": {"variables": ["u"], "class": cb.ShapeDimDim},
            "corrs_rs": {"requires": ["pis"], "ebcs": ["fixed_u"],
                         "epbcs": ["periodic_x", "periodic_y", "periodic_z"],
                         "equations": {"balance": "dw_lin_elastic.i.Y(mat.D, v, u)"
                                                  " = - dw_lin_elastic.i.Y(mat.D, v, Pi)"},
                         "set_variables": [("Pi", "pis", "u")], "class": cb.CorrDimDim, "is_linear": True},
        },
        "solvers": {"ls": (str(job["ls"]), {"use_presolve": True}),
                    "newton": ("nls.newton", {"i_max": 1, "eps_a": 1e-4})},
    }
    required, other = get_standard_keywords()
    required.remove("equations")
    pconf = ProblemConf.from_dict(conf, sys.modules[__name__], required, other, verbose=False)
    # the app copies its conf file to output_dir and resolves paths against it: give it one
    pconf._filename = str(Path(out_path).parent / "conf_in.py")
    Path(pconf._filename).write_text("# generated by sfepy_reference.py\n")
    options = Struct(output_filename_trunk=None, save_ebc=False, save_ebc_nodes=False, save_regions=False,
                     save_regions_as_groups=False, solve_not=False)
    t = time.perf_counter()
    app = HomogenizationApp(pconf, options, "homogen:")
    coefs = app()
    seconds = time.perf_counter() - t
    ls = app.problem.get_ls() if hasattr(app.problem, "get_ls") else None
    solver = type(ls).__name__ if ls is not None else str(job["ls"])
    n_dof = app.problem.fields["corrector"].n_nod * 3
    np.savez(out_path, D=np.asarray(coefs.D) / float(np.prod(size)), seconds=seconds, n_dof=n_dof,
             solver=solver)


if __name__ == "__main__":  # SfePy's homogenisation must not run on import (SOLVERS.md)
    _run(sys.argv[1], sys.argv[2])
