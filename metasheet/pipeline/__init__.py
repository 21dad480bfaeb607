"""The pipeline layer: configs, the stage registry, caching, manifests, stage artefacts.
The only layer doing file I/O.

The public names below load their module on first use (the stages import the library).
"""

from importlib import import_module

_PUBLIC = {
    "Pipeline": "config", "load_pipeline": "config",
    "run_pipeline": "runner",
    "Params": "registry", "Stage": "registry", "StageContext": "registry", "register": "registry",
    "read_orient": "artefacts", "read_material": "artefacts", "read_robot_scene": "artefacts",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
