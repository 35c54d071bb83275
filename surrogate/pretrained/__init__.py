"""Pretrained Graph-DEM checkpoints shipped with the package, one per scene at its default scale.

Each ``<scene>.pt`` is a checkpoint as the train stage writes it (weights and metadata: the dataset statistics and
model config), whose metadata adds ``pretrained``: the scene, the runtime switches its test metrics were measured
with, the config hash, the code version and the data it was trained on. Its model card ``<scene>.md`` gives the
test metrics beside constant velocity and the DEM ensemble; ``<scene>_example.h5`` is its first test sim (H5MD), a
trajectory to roll it out on without running the DEM. All three are written by ``graphdem publish`` from a workflow
run's results (workflow/rules/publish.smk); docs/pretrained.md says how they were made.
``graphdem.load_simulator("slide")`` loads one by its scene's name.
"""

from __future__ import annotations

from pathlib import Path

from generators.errors import did_you_mean

FOLDER = Path(__file__).resolve().parent


def names() -> list[str]:
    """The scenes that have a pretrained checkpoint here, sorted."""
    return sorted(p.stem for p in FOLDER.glob("*.pt"))


def is_name(spec: str | Path) -> bool:
    """Whether ``spec`` reads as a pretrained model's name (a bare word: no folder, no suffix), not a path."""
    text = str(spec)
    return bool(text) and "/" not in text and "\\" not in text and "." not in text


def path(name: str) -> Path:
    """The checkpoint of the pretrained model ``name``; an unknown name is refused with the names there are."""
    known = names()
    if name not in known:
        raise FileNotFoundError(f"no pretrained model {name!r}{did_you_mean(name, known)}; the pretrained models: "
                                f"{', '.join(known) or 'none'} (or give the path of a checkpoint, e.g. "
                                f"results/{name}/model/best.pt)")
    return FOLDER / f"{name}.pt"


def card(name: str) -> Path:
    """The model card (Markdown) of the pretrained model ``name``."""
    return path(name).with_suffix(".md")


def example(name: str) -> Path:
    """The example sim (H5MD, one of the test sims it was scored on) of the pretrained model ``name``."""
    return path(name).with_name(f"{name}_example.h5")
