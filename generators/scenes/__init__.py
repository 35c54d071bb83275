"""The scene registry: every module of this package that defines ``SCENE`` (a generators.scene.Scene).

Adding a scene means adding ``<name>.py`` (its Scene), ``<name>.yaml`` (its config section with its
scale presets, holding what differs from ``base.yaml``, the keys every scene shares) and
``<name>.schema.yaml`` (its schema fragment) here; every stage iterates :func:`registry`.
"""

from __future__ import annotations

import functools
import importlib
import pkgutil

from generators.errors import did_you_mean
from generators.scene import Scene


@functools.cache
def registry() -> dict[str, Scene]:
    """name -> Scene of every scene module, sorted by name."""
    found = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{__name__}.{info.name}")
        scene = getattr(module, "SCENE", None)
        if isinstance(scene, Scene):
            if scene.name != info.name:
                raise ValueError(f"generators/scenes/{info.name}.py defines a scene named {scene.name!r}; "
                                 "a scene's module is named after it")
            found[scene.name] = scene
    return found


def names() -> list[str]:
    return list(registry())


def get(name: str) -> Scene:
    scenes = registry()
    if name not in scenes:
        raise ValueError(f"unknown scene {name!r}{did_you_mean(name, list(scenes))}; known: {', '.join(scenes)}")
    return scenes[name]
