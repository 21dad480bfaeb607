# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # The Python API end to end
#
# This tutorial drives the quick pipeline from Python, reads what it wrote, and uses two
# library functions on the result. It is a notebook kept as a text file
# (`docs/tutorials/python_api.py`, jupytext's percent format), and the documentation build
# executes it, so every output below comes from the current code. It runs in about a minute
# and writes only into a temporary folder.
#
# To run it yourself, open the file in Jupyter with jupytext, or paste the cells into
# Python, from a checkout installed with `pip install -e .`.

# %% tags=["hide_input"]
# not shown on the site: tqdm's notebook progress bars want ipywidgets, which the docs do not need
import warnings

warnings.filterwarnings("ignore", message="IProgress not found")

# %% [markdown]
# ## Load a pipeline
#
# The Python API is at the top level of the package: `metasheet.load_pipeline` reads and
# validates a pipeline (a file, or its tables as a dict), `metasheet.run` runs it, and the
# readers (`read_constants`, `read_jacobian`, `read_study`) give its results as typed values.
# Importing metasheet first, before
# numpy, pins numpy and the BLAS to one code path, as `metasheet run` does (see
# [Guarantees](../../concepts/guarantees/)).

# %%
import json
import tempfile
from pathlib import Path

import metasheet

ROOT = Path(metasheet.__file__).resolve().parents[1]  # the checkout (pip install -e .)
pipeline = metasheet.load_pipeline(ROOT / "pipelines" / "quick.toml")
print(pipeline.name, "runs", " -> ".join(pipeline.order))

# %% [markdown]
# Each stage's table is validated into a parameter model, with the defaults filled in. These
# parameters, the files they name and the upstream outputs make up the stage's cache key.

# %%
print(pipeline.params["orient"])

# %% [markdown]
# ## Run it into a temporary folder
#
# `out` plays the part of `metasheet run --out DIR`: the stages write into
# `DIR/<pipeline name>/<stage>/`. The run returns a `metasheet.Run`: its folder and one
# outcome per stage (`overrides=["cell.seed=7"]` would change a key as `--set` does).

# %%
workdir = tempfile.TemporaryDirectory(prefix="metasheet-tutorial-")
out_root = Path(workdir.name)
run = metasheet.run(pipeline, out=out_root)
for o in run.stages:
    print(f"{o.name:11s} {o.status:7s} {o.wall_time:6.1f} s  {o.directory.relative_to(out_root)}")

# %% [markdown]
# ## The homogenised constants
#
# `metasheet.read_constants` reads `homogenize/constants.json`: the five transverse-isotropic
# constants [MPa, -], the full (6, 6) stiffness `C` in Voigt order 11, 22, 33, 23, 13, 12, the
# axis l, and (in `.data`) everything else the stage wrote, such as the fit's relative misfit.

# %%
quick = run.folder
constants = metasheet.read_constants(quick)
for key, value in constants.to_dict().items():
    print(f"{key:6s} {value:8.4f} {constants.data['units'][key]}")
print(f"relative density {constants.relative_density:.3f}, misfit {constants.data['misfit']:.1%}, "
      f"soft axis l = {constants.axis}, solver {constants.data['solver']}")

# %% [markdown]
# The library makes the same fit: `TransverseIsotropic.fit` returns the closest
# transverse-isotropic material to a (6, 6) tensor, with its axis and relative misfit. The
# stage fits about the cell's design axis (x). Without an axis, the fit searches for the best
# one and lands next to it:

# %%
import numpy as np

from metasheet.mechanics.material import TransverseIsotropic

fit = TransverseIsotropic.fit(constants.C)
print(fit.material)
print("axis", np.round(fit.axis, 3), f"misfit {fit.misfit:.1%}")

# %% [markdown]
# ## The robot's Jacobian
#
# `robot/jacobian.json` describes the 6-DOF robot built from those sheets, for several
# materials: the pipeline's foam, the paper's published constants, silicone, and each foam
# under the authors' material model. `metasheet.read_jacobian(folder, material)` gives one
# case: the Jacobian `J` (rows x, y, z [mm/rad] and rx, ry, rz [rad/rad]) and its singular
# values. A singular value near zero is a direction the motors cannot drive.

# %%
names = ["foam", "published", "silicone"]
jacobians = {name: metasheet.read_jacobian(quick, name) for name in names}
for name, j in jacobians.items():
    sv = ", ".join(f"{s:.3g}" for s in j.singular_values)
    print(f"{name:10s} singular values {sv};  rod roll {j.rod_rotation_deg_per_deg:+.3f} deg per motor deg")

# %% [markdown]
# The foam's smallest singular value is of the same order as its largest, while silicone's is
# more than a thousand times smaller: on isotropic silicone the rod's roll about its own axis,
# the sixth degree of freedom, cannot be driven. Side by side:

# %%
# %matplotlib inline
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(7, 3))
for k, name in enumerate(names):
    sv = jacobians[name].singular_values
    ax.bar(np.arange(1, 7) + 0.27 * (k - 1), sv, width=0.27, label=name)
ax.set_yscale("log")
ax.set_xlabel("singular value number")
ax.set_ylabel("singular value")
ax.set_title("Jacobian singular values at rest (quick pipeline)")
ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5))
plt.tight_layout()
plt.show()

# %% [markdown]
# ## The stage's own picture
#
# Every stage draws its pictures off screen. The robot stage's picture shows both materials
# with all motors moved by the same angle. The foam sheets turn the rod; the silicone ones
# do not.

# %%
from IPython.display import Image

Image(filename=str(quick / "robot" / "robot.png"), width=720)

# %% [markdown]
# ## The manifest
#
# Each stage folder has a `manifest.json`: the cache key, the parameters, the hashes of
# inputs and outputs, versions, timings and the code paths the stage computed with (see
# [Caching and manifests](../../concepts/caching/)).

# %%
manifest = json.loads((quick / "robot" / "manifest.json").read_text())
print("key", manifest["key"][:16], "...")
print("outputs", sorted(manifest["outputs"]))
print("inputs from", sorted(manifest["inputs"]))

# %% [markdown]
# A second run finds every stage up to date:

# %%
print({o.name: o.status for o in metasheet.run(pipeline, out=out_root).stages})

# %%
workdir.cleanup()  # the temporary folder and everything the run wrote
