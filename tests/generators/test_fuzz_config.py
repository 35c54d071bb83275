"""Config fuzz: random values for the keys of every scene's and benchmark's section (and the top-level keys).

A seeded generator mutates one key of a valid config at a time: wrong types, floats for integers, values out of
range, NaN and infinities, negative, zero, huge and tiny values, empty and shortened lists, and values set
against a related key (a history as long as the recorded frames, evaluation frames beyond the window, a split
that leaves a split empty, steps that overflow). Each mutated config is either refused by ``config.load`` with a
ConfigError naming the mutated key, or every derivation the workflow makes from it before its first job runs
without an exception: the sweep table, the packings and their LAMMPS decks, the recorded runs' Setups and decks
of a few rows (those of the stability and performance stages' DEM steps too), the training windows and
evaluation frames, the DEM ensemble's perturbation frame, the property-sensitivity values and the seeds.
"""

from __future__ import annotations

import copy
import functools
import math
import random
import re
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from generators import config, contact, dem, property_sensitivity, scenes, sweep
from generators.lammps import deck
from surrogate.samples import sample_index

N_CONFIGS = 500
SCALES = ("ci", "ci", "ci", "default", "paper")
MAX_INT32 = 2 ** 31 - 1            # LAMMPS' run, thermo, dump and loop counts
COUNTS = re.compile(r"^(run|thermo|dump|variable\s+\S+\s+loop|fix\s+\S+\s+\S+\s+ave/time)\b")


@functools.cache
def _resolved(scale: str) -> dict:
    return config.load({"scale": scale})


def _schema_node(path: tuple) -> dict:
    root = config.schema()
    return config._schema_at(root, list(path), root)


def _leaf_paths(node, path: tuple = ()) -> list[tuple]:
    """Every key path of ``node`` (mappings walked; a list is one key, its items keys of their own)."""
    if isinstance(node, dict):
        out = [path] if path else []
        return out + [p for key, value in node.items() for p in _leaf_paths(value, (*path, key))]
    if isinstance(node, list):
        return [path] + [(*path, i) for i, value in enumerate(node) if not isinstance(value, (dict, list))]
    return [path]


def _absent_keys(resolved: dict, path: tuple) -> list[tuple]:
    """The schema's optional keys of the mapping at ``path`` that the resolved config leaves out."""
    node = resolved
    for part in path:
        node = node[part]
    schema = config._object_form(_schema_node(path), config.schema())
    return [(*path, key) for key in schema.get("properties", {}) if isinstance(node, dict) and key not in node]


@functools.cache
def _candidates(scale: str) -> list[tuple]:
    resolved = _resolved(scale)
    paths = [p for p in _leaf_paths(resolved) if p]
    mappings = [p for p in paths if isinstance(_get(resolved, p), dict)]
    return paths + [p for m in mappings for p in _absent_keys(resolved, m)]


def _get(node, path: tuple):
    for part in path:
        node = node[part] if isinstance(node, (dict, list)) and (isinstance(node, list) or part in node) else None
    return node


def _section(resolved: dict, path: tuple) -> dict:
    return resolved[path[0]] if isinstance(resolved.get(path[0]), dict) else {}


def _related(resolved: dict, path: tuple) -> list:
    """Values set against the section's other keys: its recorded frames, history, and their difference."""
    section = _section(resolved, path)
    frames = section.get("frames", 20)
    history = section.get("model", {}).get("history", 2)
    return [frames, frames - 1, frames + 1, history, history - 1, frames - history, frames - history + 1, 3]


def _mutations(value, node: dict, resolved: dict, path: tuple) -> list:
    out: list = ["text", None, True, [], {}, math.nan, math.inf, -math.inf, -1, 0, 10 ** 30, 2 ** 63, 2 ** 32,
                 1e300, -1e300, 1e-300, 0.5]
    if isinstance(value, bool):
        out += [1, "true"]
    elif isinstance(value, int):
        out += [float(value), value + 0.5, -value, value * 10 ** 6, value + 1, max(0, value - 1),
                *_related(resolved, path)]
    elif isinstance(value, float):
        out += [-value, value * 1e6, value * 1e-6, value * 1e12, value * 1e-12, int(value) if value < 1e15 else 1]
    elif isinstance(value, list):
        out += [value[:1], value[::-1], value * 3, [value[0]] if value else [1], [*value, value[-1]] if value else [0],
                [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.98, 0.01, 0.01], [1e-300, 1e300],
                [v for v in _related(resolved, path) if v > 0][:3], list(range(1, 60))]
    for bound in ("minimum", "exclusiveMinimum"):
        if isinstance(node.get(bound), (int, float)):
            out += [node[bound] - 1, node[bound], node[bound] - 0.5]
    for bound in ("maximum", "exclusiveMaximum"):
        if isinstance(node.get(bound), (int, float)):
            out += [node[bound] + 1, node[bound], node[bound] + 0.5]
    return out


def _override(path: tuple, value, resolved: dict) -> dict:
    """The config override setting ``path`` to ``value`` (an item of a list: the whole list with it changed)."""
    if isinstance(path[-1], int):
        items = copy.deepcopy(_get(resolved, path[:-1]))
        items[path[-1]] = value
        path, value = path[:-1], items
    for part in reversed(path):
        value = {part: value}
    return value


def _dotted(path: tuple) -> str:
    return ".".join(str(p) for p in path if not isinstance(p, int))


def _names(message: str, path: tuple) -> bool:
    """Whether ``message`` names the key at ``path`` (an item of a list: the list)."""
    key = _dotted(path)
    return re.search(r"(?<![\w.])'?" + re.escape(key) + r"(?![\w])", message) is not None


def draws(seed: int = 84, n: int = N_CONFIGS) -> list[tuple[str, tuple, object]]:
    """``n`` (scale, key path, value) mutations, the same for the same seed."""
    rng = random.Random(seed)
    out = []
    for _ in range(n):
        scale = rng.choice(SCALES)
        resolved = _resolved(scale)
        path = rng.choice(_candidates(scale))
        node = _schema_node(path)
        out.append((scale, path, rng.choice(_mutations(_get(resolved, path), node, resolved, path))))
    return out


# ---- the derivations a run makes from its config before the first job ---------------------------------


def _check_deck(text: str, where: str) -> None:
    """Every count of a LAMMPS deck (run, thermo, dump, loop, ave/time) is an integer LAMMPS accepts."""
    for line in text.splitlines():
        if COUNTS.match(line):
            for token in line.split():
                assert not token.isdigit() or int(token) <= MAX_INT32, f"{where}: {line!r}"


def _variants(section: dict, row: dict, dim: int) -> list[dict]:
    """The row as the dataset runs it, and the one of the smallest step among the stability stage's DEM test
    (dt = factor x the stable limit, generators/stability.py) and the performance stage's DEM contenders (the rule
    of evaluation/performance.py's dem_row: dt_safety, or the data's times dt_factor, at the modulus times
    stiffness_factor; only without an explicit dt, which that stage refuses)."""
    others = [{**row, "dt": None, "dt_safety": float(f)} for f in section["stability"]["dem_dt_factors"]]
    if row.get("dt") is None:
        others += [{**row, "dt_safety": v.get("dt_safety", row["dt_safety"] * v.get("dt_factor", 1.0)),
                    "young": row["young"] * v.get("stiffness_factor", 1.0)}
                   for v in section["performance"]["dem"].values()]
    return [row, min(others, key=lambda r: contact.time_step(r, row["id"], dim)[0])]


def _scene_derivations(name: str, section: dict) -> None:
    scene = scenes.get(name)
    table = sweep.build(name, section)
    assert set(table["split"]) == set(sweep.SPLITS), "a split is empty"
    params = {key: p for key, p in zip(scene.packing_keys_of(section), scene.packings(section), strict=True)}
    history, bundle = section["model"]["history"], section["model"].get("bundle", 1)
    sample_index([SimpleNamespace(n_frames=section["frames"], path=name)], history, bundle)
    predicted = section["frames"] - history
    taus = section["evaluate"]["frames"]
    assert predicted >= 1 and (taus is None or any(1 <= t <= predicted for t in taus)), "no tau in the window"
    property_sensitivity.values(name, section)
    rows = table.to_dict("records")
    picks = {0, int(np.argmax([r["young"] for r in rows]))}
    for i in sorted(picks):
        row = {k: v for k, v in rows[i].items() if k != "split"}
        p = params[row["packing"]]
        settle = scene.settle_setup(p)
        _check_deck(deck.settle_deck(settle), f"{name} packing")
        packing = scene.settled(p, settle.particles, "fuzz")
        for variant in _variants(section, row, scene.dim):
            setup = scene.simulate_setup(variant, packing)
            member = dem.Perturbation(history - 1, np.zeros_like(setup.particles.x))
            dem.checked_perturbation(dem.Setup(**{**setup.__dict__, "perturbation": member}))
            _check_deck(deck.record_deck(setup), row["id"])


def _exact_type(cfg: dict, path: tuple) -> None:
    """The jobs count with an integer key's value (epochs, batch sizes, frames): it is an int, not a float."""
    value, node = _get(cfg, path), _schema_node(path)
    types = node.get("type", [])
    if "integer" in ([types] if isinstance(types, str) else types) and "number" not in types:
        assert not isinstance(value, float), f"{_dotted(path)} = {value!r} reaches the jobs as a float"


def _derivations(cfg: dict, names: list[str], path: tuple) -> None:
    _exact_type(cfg, path)
    for name in names:
        if name in scenes.names():
            _scene_derivations(name, cfg[name])
        for seed in range(cfg[name]["train"]["seed"], cfg[name]["train"]["seed"] + cfg["seeds"]):
            np.random.RandomState(seed)
            torch.manual_seed(seed)
    torch.manual_seed(torch.initial_seed())


def outcome(scale: str, path: tuple, value) -> str:
    """named (a ConfigError naming the key), unnamed (one that does not), late (a derivation fails) or ok."""
    resolved = _resolved(scale)
    try:
        cfg = config.load({"scale": scale, **_override(path, value, resolved)})
    except config.ConfigError as exc:
        return "named" if _names(str(exc), path) else f"unnamed: {exc}"
    except Exception as exc:  # noqa: BLE001 - a traceback is the failure being counted
        return f"traceback: {type(exc).__name__}: {exc}"
    sections = [*scenes.names(), *config.BENCHMARKS]
    names = [path[0]] if path[0] in sections else sections
    try:
        _derivations(cfg, names, path)
    except Exception as exc:  # noqa: BLE001
        return f"late: {type(exc).__name__}: {exc}"
    return "ok"


def test_fuzzed_configs_are_refused_by_name_or_derive_without_error():
    results = [(scale, path, value, outcome(scale, path, value)) for scale, path, value in draws()]
    failures = [f"{scale} {_dotted(path) or path} = {value!r}: {result}" for scale, path, value, result in results
                if result not in ("named", "ok")]
    assert len(results) >= 500
    assert {r for *_, r in results} >= {"named", "ok"}
    assert failures == []


def test_the_draws_cover_every_section_and_are_seeded():
    first = draws(n=N_CONFIGS)
    assert first == draws(n=N_CONFIGS)
    sections = {path[0] for _, path, _ in first}
    assert sections >= {*scenes.names(), *config.BENCHMARKS}


@pytest.mark.parametrize("key", ["n_sims", "frames"])
def test_a_float_for_an_integer_key_is_named(key):
    assert outcome("ci", ("slide", key), 10.0) == "named"
