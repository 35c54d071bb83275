"""Scene definitions (engine-agnostic) and the engine driver that runs each scene."""

from __future__ import annotations

import importlib
from types import ModuleType

# scene -> (scene definition module, engine driver module with settle() and simulate())
DRIVERS = {
    "slide": ("generators.scenes.slide", "generators.lammps.slide"),
    "meteorite": ("generators.scenes.meteorite", "generators.lammps.meteorite"),
    "shear": ("generators.scenes.shear", "generators.yade.shear"),
}


def _check(scene: str) -> None:
    if scene not in DRIVERS:
        raise ValueError(f"unknown scene {scene!r}; known: {', '.join(DRIVERS)}")


def definition(scene: str) -> ModuleType:
    _check(scene)
    return importlib.import_module(DRIVERS[scene][0])


def driver(scene: str) -> ModuleType:
    _check(scene)
    return importlib.import_module(DRIVERS[scene][1])


def packings(scene: str, cfg: dict) -> list[dict]:
    """The packing parameter sets (each settled once by the prepare stage) of a scene's config."""
    module = definition(scene)
    if hasattr(module, "packings"):
        return module.packings(cfg)
    return [module.packing_params(cfg, i) for i in range(cfg["n_packings"])]
