"""Load, fill and validate the pipeline configuration.

The validated config is the single source of defaults: ``workflow/config/default.yaml`` holds
every physical default and, under ``scales``, the sizes of each scale preset. A preset only fills
keys the user left unset, so command-line overrides always win.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import jsonschema
import yaml

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_CONFIG = ROOT / "workflow" / "config" / "default.yaml"
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"


class ConfigError(ValueError):
    """A configuration key is unknown, of the wrong type or out of range."""


def deep_update(base: dict, override: dict) -> dict:
    """Recursively merge ``override`` into a copy of ``base`` (override wins)."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_update(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def fill_missing(config: dict, preset: dict) -> dict:
    """Copy of ``config`` with keys from ``preset`` added only where ``config`` lacks them."""
    out = copy.deepcopy(config)
    for key, value in preset.items():
        if key not in out:
            out[key] = copy.deepcopy(value)
        elif isinstance(value, dict) and isinstance(out[key], dict):
            out[key] = fill_missing(out[key], value)
    return out


def _flatten(node: dict, root: dict) -> dict:
    """``node`` with ``$ref`` resolved and the members of an ``allOf`` merged into one schema."""
    while "$ref" in node:
        node = _resolve(node["$ref"], root)
    if "allOf" in node:
        merged: dict = {}
        for member in node["allOf"]:
            for key, value in _flatten(member, root).items():
                merged[key] = merged.get(key, []) + value if key == "required" else value
        node = merged
    return node


def _schema_at(schema: dict, path: list[Any], root: dict) -> dict:
    node = schema
    for part in path:
        node = _flatten(node, root)
        if isinstance(part, int):
            node = node.get("items", {})
        else:
            node = node.get("properties", {}).get(part, {})
    return _flatten(node, root)


def _resolve(ref: str, root: dict) -> dict:
    node: Any = root
    for part in ref.lstrip("#/").split("/"):
        node = node[part]
    return node


def _describe(error: jsonschema.ValidationError, schema: dict) -> str:
    path = list(error.absolute_path)
    where = ".".join(str(p) for p in path) or "<top level>"
    if error.validator == "additionalProperties":
        allowed = sorted(_schema_at(schema, path, schema).get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed))
        return (
            f"unknown config key {', '.join(repr(where + '.' + k if path else k) for k in extra)}; "
            f"allowed keys{' under ' + where if path else ''}: {', '.join(allowed)}"
        )
    if error.validator == "required":
        return f"config key {where!r} is missing {error.message.split(' is a required')[0]}"
    node = _schema_at(schema, path, schema)
    allowed = {k: node[k] for k in (
        "type", "enum", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum",
        "minItems", "maxItems") if k in node}
    if "items" in node and isinstance(node["items"], dict):
        items = node["items"]
        while "$ref" in items:
            items = _resolve(items["$ref"], schema)
        allowed["items"] = {k: v for k, v in items.items() if k != "description"}
    return f"config key {where!r} = {error.instance!r} is not allowed: {error.message}; allowed: {allowed}"


SCENES = ("slide", "meteorite", "shear")
BENCHMARKS = ("slide_samer", "slide_small")


def validate(config: dict) -> dict:
    """Validate a fully filled config against the schema; raise ConfigError naming the key."""
    schema = yaml.safe_load(SCHEMA.read_text())
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    if errors:
        raise ConfigError("invalid configuration:\n  " + "\n  ".join(
            _describe(e, schema) for e in errors))
    _check_semantics(config)
    return config


def _check_semantics(config: dict) -> None:
    for scene in SCENES:
        cfg = config.get(scene)
        if not cfg:
            continue
        lo, hi = cfg["radius"]
        if lo > hi:
            raise ConfigError(f"config key '{scene}.radius' = {cfg['radius']} must be [min, max] with min <= max")
        if abs(sum(cfg["split"]) - 1.0) > 1e-6:
            raise ConfigError(f"config key '{scene}.split' = {cfg['split']} must sum to 1")
        for key, rng in cfg["sweep"].items():
            if isinstance(rng, list) and len(rng) == 2 and key != "displacements" and rng[0] > rng[1]:
                raise ConfigError(f"config key '{scene}.sweep.{key}' = {rng} must be [min, max] with min <= max")
    for name in BENCHMARKS:
        bench = config.get(name)
        if bench and min(bench["protocols"]) < bench["model"]["history"]:
            raise ConfigError(f"config key '{name}.protocols' = {bench['protocols']}: a protocol gives K frames and "
                              f"the model reads the last '{name}.model.history' = {bench['model']['history']} of "
                              f"them, so every K must be at least that")
    meteorite = config.get("meteorite")
    if meteorite and meteorite["contact_frame"] >= meteorite["model"]["history"]:
        raise ConfigError(f"config key 'meteorite.contact_frame' = {meteorite['contact_frame']} must be below "
                          f"'meteorite.model.history' = {meteorite['model']['history']}: the impact point x0 is taken "
                          "at first contact, which must lie in the history both truth and prediction share")
    shear = config.get("shear")
    if shear and shear["wall_radius"] * (shear["wall_spacing"] / 2**0.5 - 1.0) >= shear["radius"][0]:
        raise ConfigError(f"config keys 'shear.wall_radius' = {shear['wall_radius']} and 'shear.wall_spacing' = "
                          f"{shear['wall_spacing']} leave holes in the box walls wider than the smallest soil sphere "
                          f"({shear['radius'][0]} m): lower the spacing or raise the wall radius")


_FLOAT = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def coerce_numbers(value: Any) -> Any:
    """Turn numeric strings into numbers.

    YAML 1.1 (PyYAML, and so Snakemake's ``--config``) reads ``5.0e9`` as a string; a user who
    writes ``--config slide='{young: 5.0e9}'`` means a number.
    """
    if isinstance(value, dict):
        return {k: coerce_numbers(v) for k, v in value.items()}
    if isinstance(value, list):
        return [coerce_numbers(v) for v in value]
    if isinstance(value, str) and _FLOAT.match(value.strip()):
        number = float(value)
        return int(number) if number.is_integer() and "." not in value and "e" not in value.lower() else number
    return value


def resolve(config: dict) -> dict:
    """Fill the chosen scale preset into ``config`` (user keys win) and validate the result."""
    config = coerce_numbers(config)
    scale = config.get("scale", "default")
    presets = config.get("scales", {})
    if scale not in presets:
        raise ConfigError(f"config key 'scale' = {scale!r} is not allowed; allowed: {sorted(presets)}")
    filled = fill_missing(config, presets[scale])
    return validate(filled)


def load(overrides: dict | None = None, path: Path = DEFAULT_CONFIG) -> dict:
    """The embedded default config with ``overrides`` merged in, resolved and validated."""
    base = yaml.safe_load(Path(path).read_text())
    return resolve(deep_update(base, overrides or {}))
