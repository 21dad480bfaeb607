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
# `metasheet.pipeline` is the pipeline layer's public face: `load_pipeline` reads and
# validates a pipeline file, and `run_pipeline` runs it. Importing metasheet first, before
# numpy, pins numpy and the BLAS to one code path, as `metasheet run` does (see
# [Guarantees](../../concepts/guarantees/)).

# %%
import json
import tempfile
from pathlib import Path

import metasheet
from metasheet.pipeline import load_pipeline, run_pipeline

ROOT = Path(metasheet.__file__).resolve().parents[1]  # the checkout (pip install -e .)
pipeline = load_pipeline(ROOT / "pipelines" / "quick.toml")
print(pipeline.name, "runs", " -> ".join(pipeline.order))

# %% [markdown]
# Each stage's table is validated into a parameter model, with the defaults filled in. These
# parameters, the files they name and the upstream outputs make up the stage's cache key.

# %%
print(pipeline.params["orient"])

# %% [markdown]
# ## Run it into a temporary folder
#
# `out_root` plays the part of `metasheet run --out DIR`: the stages write into
# `DIR/<pipeline name>/<stage>/`. The run returns one `StageOutcome` per stage.

# %%
workdir = tempfile.TemporaryDirectory(prefix="metasheet-tutorial-")
out_root = Path(workdir.name)
outcomes = run_pipeline(pipeline, out_root=out_root)
for o in outcomes:
    print(f"{o.name:11s} {o.status:7s} {o.wall_time:6.1f} s  {o.directory.relative_to(out_root)}")

# %% [markdown]
# ## The homogenised constants
#
# `homogenize/constants.json` holds the five transverse-isotropic constants [MPa], the full
# (6, 6) stiffness `C` in Voigt order 11, 22, 33, 23, 13, 12, and the fit's relative misfit.

# %%
quick = out_root / pipeline.name
constants = json.loads((quick / "homogenize" / "constants.json").read_text())
for key in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l"):
    print(f"{key:6s} {constants[key]:8.4f} {constants['units'][key]}")
print(f"relative density {constants['relative_density']:.3f}, misfit {constants['misfit']:.1%}, "
      f"soft axis l = {constants['axis']}, solver {constants['solver']}")

# %% [markdown]
# The library makes the same fit: `TransverseIsotropic.fit` returns the closest
# transverse-isotropic material to a (6, 6) tensor, with its axis and relative misfit. The
# stage fits about the cell's design axis (x). Without an axis, the fit searches for the best
# one and lands next to it:

# %%
import numpy as np

from metasheet.material import TransverseIsotropic

fit = TransverseIsotropic.fit(np.array(constants["C"]))
print(fit.material)
print("axis", np.round(fit.axis, 3), f"misfit {fit.misfit:.1%}")

# %% [markdown]
# ## The robot's Jacobian
#
# `robot/jacobian.json` describes the 6-DOF robot built from those sheets, for several
# materials: the pipeline's foam, the paper's published constants, silicone, and each foam
# under the authors' material model. For each material it holds the rest pose, the Jacobian
# per degree of motor travel and its singular values. A singular value near zero is a
# direction the motors cannot drive.

# %%
robot = json.loads((quick / "robot" / "jacobian.json").read_text())
print(robot["frame"])
for name, case in robot["materials"].items():
    sv = ", ".join(f"{s:.3g}" for s in case["singular_values"])
    print(f"{name:18s} singular values {sv};  rod roll {case['rod_rotation_deg_per_deg']:+.3f} deg per motor deg")

# %% [markdown]
# The foam's smallest singular value is of the same order as its largest, while silicone's is
# more than a thousand times smaller: on isotropic silicone the rod's roll about its own axis,
# the sixth degree of freedom, cannot be driven. Side by side:

# %%
# %matplotlib inline
import matplotlib.pyplot as plt

names = ["foam", "published", "silicone"]
fig, ax = plt.subplots(figsize=(7, 3))
for k, name in enumerate(names):
    sv = robot["materials"][name]["singular_values"]
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
print({o.name: o.status for o in run_pipeline(pipeline, out_root=out_root)})

# %%
workdir.cleanup()  # the temporary folder and everything the run wrote
