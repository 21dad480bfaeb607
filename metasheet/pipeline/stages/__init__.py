"""Every module in this package is a stage; importing the package registers them all.

The registry's order (which breaks ties in the run order) is the canonical
pipeline order below; modules not named there follow alphabetically.
"""

import importlib
import pkgutil

CANONICAL = (
    "material", "cell", "homogenize", "chart", "orient", "printmap", "robot", "reduce", "sheet", "printed", "scalemap",
    "workspace", "ranges", "anisotropy", "maze", "report",
)


def _import_all() -> None:
    found = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
    for name in [n for n in CANONICAL if n in found] + [n for n in found if n not in CANONICAL]:
        importlib.import_module(f"{__name__}.{name}")


_import_all()
