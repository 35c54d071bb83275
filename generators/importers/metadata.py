"""What an import needs beyond what its source holds: the items a user gives (options of `graphdem import` or the
keys of a small YAML/JSON metadata file), the metadata.json of the GNS and LagrangeBench datasets, and a source
file's digest for the provenance.

Items, each an option and a metadata key of the same name (options win over the file's keys):

* ``radius`` (m), ``density`` (kg/m^3) or ``mass`` (kg): a number for every particle, or one per particle type
  (``--radius 1=0.01 --radius 2=0.02``; in the file a mapping ``{1: 0.01, 2: 0.02}``); mass and density are one
  item (give one of them); a kinematic type without one gets mass 0 (infinite, as H5MD sims mark it);
* ``kinematic_types``: the particle types whose positions are prescribed (never predicted);
* ``box``: ``[[lo, hi], ...]``, one pair per axis (m);
* ``dt`` (s per step: a LAMMPS time step, a GNS frame, a LagrangeBench solver step) or ``frame_interval`` (s
  between recorded frames, which must then be evenly spaced in steps);
* ``dim``: 2 or 3.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: every item and the option that gives it (the metadata file's key is the item's name)
ITEMS = {"radius": "--radius", "density": "--density", "mass": "--mass", "kinematic_types": "--kinematic-types",
         "box": "--box", "dt": "--dt", "frame_interval": "--frame-interval", "dim": "--dim"}
PER_TYPE = ("radius", "density", "mass")
SPLITS = ("train", "valid", "test")     # a GNS or LagrangeBench dataset folder's split files, in this order
#: items that stand for one thing: an option giving one of a group replaces the metadata file's whole group
GROUPS = (("density", "mass"), ("dt", "frame_interval"))


class ImportRefused(ValueError):
    """A source that is not turned into sims, or an item it lacks; the message names the file or the item and how
    to give it."""


def how_to_give(key: str) -> str:
    """How a user gives ``key``: its option, or its key in a metadata file."""
    return f"give {ITEMS[key]} or the key {key!r} of a metadata file (--meta FILE)"


def _number(value, key: str, where: str, zero: bool = False) -> float:
    """A finite number, positive (or >= 0 where ``zero``)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ImportRefused(f"{where}: {key} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number) or number < 0 or (number == 0 and not zero):
        raise ImportRefused(f"{where}: {key} must be a {'non-negative' if zero else 'positive'} finite number, got "
                            f"{value!r}")
    return number


def type_id(value, key: str, where: str) -> int:
    """A particle type: a whole number >= 0 (in a YAML or JSON mapping, a key like ``"2"`` too)."""
    try:
        number = int(str(value).strip())
    except ValueError:
        number = -1
    if number < 0 or isinstance(value, bool | float):
        raise ImportRefused(f"{where}: {key}: particle type {value!r} must be a whole number >= 0")
    return number


def _per_type(value, key: str, where: str) -> float | dict[int, float]:
    if isinstance(value, dict):
        if not value:
            raise ImportRefused(f"{where}: {key} is an empty mapping; give a number or one per particle type")
        return {type_id(t, key, where): _number(v, key, where, zero=key == "mass") for t, v in value.items()}
    return _number(value, key, where, zero=key == "mass")


def _box(value, where: str) -> list[list[float]]:
    try:
        box = np.asarray(value, float)
    except (TypeError, ValueError):
        box = np.zeros(0)
    if box.ndim != 2 or box.shape[0] not in (2, 3) or box.shape[1] != 2 or not np.all(np.isfinite(box)) \
            or not np.all(box[:, 1] > box[:, 0]):
        raise ImportRefused(f"{where}: box must be 2 or 3 finite [lo, hi] pairs with lo < hi, got {value!r}")
    return box.tolist()


def normalise(key: str, value, where: str):
    """``value`` of the item ``key`` checked and in its one form (``where`` names its origin in errors)."""
    if key in PER_TYPE:
        return _per_type(value, key, where)
    if key == "kinematic_types":
        values = value if isinstance(value, list | tuple) else [value]
        return sorted({type_id(v, key, where) for v in values})
    if key == "box":
        return _box(value, where)
    if key == "dim":
        if value not in (2, 3) or isinstance(value, bool):
            raise ImportRefused(f"{where}: dim must be 2 or 3, got {value!r}")
        return int(value)
    return _number(value, key, where)


def option_value(key: str, texts: list[str]):
    """A per-type option's texts (``R``, or ``TYPE=R`` repeated) as a number or a {type: number} mapping."""
    option = ITEMS[key]
    if len(texts) == 1 and "=" not in texts[0]:
        return _parsed(texts[0], option)
    values = {}
    for text in texts:
        kind, sep, number = text.partition("=")
        if not sep:
            raise ImportRefused(f"{option} {text!r}: give one number for every particle, or TYPE=VALUE per type "
                                f"(repeated), not both")
        values[type_id(kind, key, option)] = _parsed(number, option)
    return values


def _parsed(text: str, option: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ImportRefused(f"{option} {text!r}: not a number") from None


def read_meta_file(path: Path) -> dict:
    """A metadata file (JSON for ``.json``, else YAML) as {item: value}, every key an item and checked."""
    import yaml
    try:
        text = path.read_text()
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, yaml.YAMLError) as exc:
        raise ImportRefused(f"{path}: not a readable {'JSON' if path.suffix == '.json' else 'YAML'} metadata "
                            f"file: {exc}".replace("\n", " ")) from exc
    if not isinstance(data, dict):
        raise ImportRefused(f"{path}: a metadata file holds a mapping of items ({', '.join(ITEMS)}), got "
                            f"{type(data).__name__}")
    unknown = sorted(str(k) for k in data if k not in ITEMS)
    if unknown:
        raise ImportRefused(f"{path}: unknown key(s) {unknown}; allowed: {', '.join(ITEMS)}")
    return {key: normalise(key, value, f"{path}: key {key!r}") for key, value in data.items()}


@dataclass(frozen=True)
class Given:
    """The items a user gave and where each came from (an option, or a metadata file's key)."""

    values: dict = field(default_factory=dict)
    origin: dict = field(default_factory=dict)

    def __contains__(self, key: str) -> bool:
        return key in self.values

    def get(self, key: str):
        """The item's value, None when not given."""
        return self.values.get(key)

    def where(self, key: str) -> str:
        """Where the item came from, for messages: ``--radius`` or ``meta.yaml key 'radius'``."""
        return self.origin.get(key, ITEMS[key])

    def record(self) -> dict:
        """The items and their origins as JSON-ready values (per-type mappings keyed by the type as text)."""
        def plain(value):
            return {str(k): v for k, v in value.items()} if isinstance(value, dict) else value
        return {key: {"value": plain(value), "from": self.origin[key]} for key, value in self.values.items()}


def given(options: dict, meta: Path | None = None) -> Given:
    """The items of ``options`` (item -> value or None; per-type ones as :func:`option_value` returns them) over
    those of the metadata file ``meta``."""
    from_file = read_meta_file(Path(meta)) if meta is not None else {}
    for group in GROUPS:
        if any(options.get(key) is not None for key in group):
            from_file = {k: v for k, v in from_file.items() if k not in group}
    values, origin = {}, {}
    for key in ITEMS:
        if options.get(key) is not None:
            values[key], origin[key] = normalise(key, options[key], ITEMS[key]), ITEMS[key]
        elif key in from_file:
            values[key], origin[key] = from_file[key], f"{meta} key {key!r}"
    if "density" in values and "mass" in values:
        raise ImportRefused(f"{origin['density']} and {origin['mass']}: give the mass or the density of the "
                            f"particles, not both")
    return Given(values, origin)


def per_particle(key: str, value, species: np.ndarray, where: str, kinematic: np.ndarray | None = None
                 ) -> np.ndarray:
    """``value`` (a number, or {type: number}) for each particle by its type. A type without one is refused by
    name, unless ``kinematic`` marks all its particles (then 0: the mass of a kinematic particle)."""
    species = np.asarray(species)
    if not isinstance(value, dict):
        return np.full(species.shape, float(value))
    out = np.zeros(species.shape)
    lacking = []
    for kind in np.unique(species).tolist():
        chosen = species == kind
        if kind in value:
            out[chosen] = value[kind]
        elif kinematic is None or not np.all(kinematic[chosen]):
            lacking.append(kind)
    if lacking:
        raise ImportRefused(f"{where}: no {key} for particle type(s) {lacking} (given for {sorted(value)}): give "
                            f"one per type, e.g. {ITEMS[key]} {lacking[0]}=VALUE, or the metadata key {key!r}")
    return out


def volume(radius: np.ndarray, dim: int) -> np.ndarray:
    """A particle's volume: a sphere's in 3D, a disc's of unit thickness (1 m) in 2D, as the project's 2D sims."""
    radius = np.asarray(radius, float)
    return np.pi * radius**2 if dim == 2 else 4.0 / 3.0 * np.pi * radius**3


def sha256(path: Path) -> str:
    """The hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(2**20), b""):
            digest.update(block)
    return digest.hexdigest()


def dataset_metadata(path: Path) -> dict:
    """A GNS or LagrangeBench ``metadata.json`` as a mapping; GNS's newer files split it by purpose, of which the
    ``train`` entry (else ``rollout``) describes the data."""
    try:
        meta = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ImportRefused(f"{path}: not a readable JSON metadata file: {exc}") from exc
    if not isinstance(meta, dict):
        raise ImportRefused(f"{path}: expected a JSON object (bounds, dt, dim, ...), got {type(meta).__name__}")
    for purpose in ("train", "rollout"):
        if isinstance(meta.get(purpose), dict):
            return meta[purpose]
    return meta


def dataset_files(src: Path, suffix: str, what: str) -> tuple[list[tuple[str | None, Path]], Path, dict]:
    """A GNS or LagrangeBench source: its split files (a dataset folder: ``train``, ``valid``, ``test`` with
    ``suffix``; a file: itself, no split), where its metadata.json is (in the folder, or beside the file) and what
    that holds ({} where there is none)."""
    src = Path(src)
    if src.is_dir():
        found = [(split, src / f"{split}{suffix}") for split in SPLITS if (src / f"{split}{suffix}").is_file()]
        if not found:
            raise ImportRefused(f"{src}: no {', '.join(s + suffix for s in SPLITS)}; a {what} dataset folder holds "
                                f"those and metadata.json (or give one {suffix} file)")
        meta_path = src / "metadata.json"
    else:
        found, meta_path = [(None, src)], src.parent / "metadata.json"
    return found, meta_path, dataset_metadata(meta_path) if meta_path.is_file() else {}


def held_number(meta: dict, key: str, path: Path) -> float | None:
    """The positive number ``key`` of a dataset's metadata, None when absent."""
    return None if meta.get(key) is None else _number(meta[key], key, str(path))


def held_box(meta: dict, path: Path, dim: int) -> np.ndarray | None:
    """The metadata's ``bounds`` ([[lo, hi], ...]; rows past ``dim`` dropped, as LagrangeBench's loaders do), None
    when absent."""
    if meta.get("bounds") is None:
        return None
    try:
        bounds = np.asarray(meta["bounds"], float)[:dim]
    except (TypeError, ValueError):
        bounds = np.zeros(0)
    if bounds.shape != (dim, 2):
        raise ImportRefused(f"{path}: 'bounds' must hold {dim} [lo, hi] pairs (the data has dim {dim}), got "
                            f"{meta['bounds']!r}")
    return np.asarray(_box(bounds, f"{path}: 'bounds'"))


def check_dim(meta: dict, path: Path, dim: int, items: Given, where: str) -> None:
    """Refuse data whose dimension is not the metadata's ``dim`` or the given one."""
    for said, origin in ((meta.get("dim"), f"{path} says dim {meta.get('dim')!r}"),
                         (items.get("dim"), f"{items.where('dim')} says dim {items.get('dim')}")):
        if said is not None and said != dim:
            raise ImportRefused(f"{where}: positions have {dim} coordinates per particle, but {origin}")
