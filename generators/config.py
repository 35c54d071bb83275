"""Load, fill and validate the pipeline configuration.

The validated config is the single source of defaults. It is package data, found without any path
outside the package: ``generators/defaults/default.yaml`` (top-level keys, public benchmarks) and
``generators/scenes/<scene>.yaml`` (one section per registered scene, holding only what differs from
``generators/scenes/base.yaml``, the keys every scene shares with the same default), validated against
``generators/defaults/schema.yaml`` with each scene's fragment ``generators/scenes/<scene>.schema.yaml``.
A scene's section is base.yaml with the scene's YAML laid over it (the scale presets too), as if every key
were written in the scene's file. Every section carries its scale presets under ``scales``; the chosen
preset only fills keys the user left unset (command-line overrides always win) and ``scales`` is removed
before validation.
"""

from __future__ import annotations

import copy
import functools
import math
import re
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from generators import config_checks, engines, property_sensitivity, scenes, user_data
from generators.errors import ConfigError, did_you_mean

DEFAULTS = resources.files("generators").joinpath("defaults")
SCENES_DIR = resources.files("generators").joinpath("scenes")
SCENE_BASE = "base.yaml"            # beside the scenes' YAMLs: the keys they share (scene_base)


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
    """``node`` with ``$ref`` resolved and the members of an ``allOf`` merged into it (properties and
    required lists united, the node's own keys first)."""
    while "$ref" in node:
        node = _resolve(node["$ref"], root)
    if "allOf" not in node:
        return node
    merged = {k: v for k, v in node.items() if k != "allOf"}
    for member in node["allOf"]:
        for key, value in _flatten(member, root).items():
            if key == "required":
                merged[key] = merged.get(key, []) + value
            elif key == "properties":
                merged[key] = {**value, **merged.get(key, {})}
            else:
                merged.setdefault(key, value)
    return merged


def _object_form(node: dict, root: dict) -> dict:
    """``node``, or where it is a choice of forms (``oneOf``: null or a mapping, say) its one mapping form."""
    if "properties" in node:
        return node
    forms = [_flatten(form, root) for form in node.get("oneOf", node.get("anyOf", []))]
    mappings = [form for form in forms if "properties" in form]
    return mappings[0] if len(mappings) == 1 else node


def _schema_at(schema: dict, path: list[Any], root: dict) -> dict:
    node = schema
    for part in path:
        node = _flatten(node, root)
        if isinstance(part, int):
            node = node.get("items", {})
        else:
            form = _object_form(node, root)
            extra = form.get("additionalProperties")
            node = form.get("properties", {}).get(part, extra if isinstance(extra, dict) else {})
    return _flatten(node, root)


def _leaves(error: jsonschema.ValidationError) -> list[jsonschema.ValidationError]:
    """The errors to report for ``error``: where it is a choice of forms (``oneOf``, ``anyOf``) and the value has
    the type of exactly one form, the errors inside that form (``finetune.lr = 2.0``, not the whole mapping
    against every form); otherwise ``error`` itself."""
    if error.validator not in ("oneOf", "anyOf") or not error.context:
        return [error]
    forms: dict[int, list[jsonschema.ValidationError]] = {}
    for sub in error.context:
        forms.setdefault(sub.relative_schema_path[0], []).append(sub)
    mistyped = {i for i, subs in forms.items()
                if any(s.validator in ("type", "const", "enum") and not s.relative_path for s in subs)}
    fitting = [i for i in forms if i not in mistyped]
    if len(fitting) != 1:
        return [error]
    return [leaf for sub in forms[fitting[0]] for leaf in _leaves(sub)]


def _resolve(ref: str, root: dict) -> dict:
    node: Any = root
    for part in ref.lstrip("#/").split("/"):
        node = node[part]
    return node


def _describe(error: jsonschema.ValidationError, schema: dict, always: bool = False,
              prefix: tuple[str, ...] = ()) -> str:
    """One line naming the key (``prefix`` is where the validated part sits in the config) and what is allowed;
    empty for an unevaluatedProperties error that only echoes a failure of a known key below it (that failure
    has its own line), unless ``always``."""
    path = list(error.absolute_path)
    named = [*prefix, *path]
    where = ".".join(str(p) for p in named) or "<top level>"
    if error.validator in ("additionalProperties", "unevaluatedProperties"):
        node = _object_form(_schema_at(schema, path, schema), schema)
        allowed = sorted(node.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed))
        if not extra and not always:
            return ""
        hints = "".join(did_you_mean(k, allowed) for k in extra)
        return (
            f"unknown config key {', '.join(repr(where + '.' + k if named else k) for k in extra)}{hints}; "
            f"allowed keys{' under ' + where if named else ''}: {', '.join(allowed)}"
        )
    if error.validator == "required":
        return f"config key {where!r} is missing {error.message.split(' is a required')[0]}"
    node = _schema_at(schema, path, schema)
    allowed = {k: node[k] for k in (
        "type", "enum", "pattern", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum",
        "minItems", "maxItems") if k in node}
    if "items" in node and isinstance(node["items"], dict):
        items = node["items"]
        while "$ref" in items:
            items = _resolve(items["$ref"], schema)
        allowed["items"] = {k: v for k, v in items.items() if k != "description"}
    if "oneOf" in node:                 # a choice of forms, e.g. a number or `auto`: name each
        allowed = " or ".join(_form(option, schema) for option in node["oneOf"])
        return f"config key {where!r} = {error.instance!r} is not allowed; allowed: {allowed}"
    return f"config key {where!r} = {error.instance!r} is not allowed: {_type_words(error) or error.message}; " \
        f"allowed: {allowed}"


#: a JSON Schema type in words
_TYPES = {"integer": "an integer", "number": "a number", "string": "a string", "boolean": "true or false",
          "array": "a list", "object": "a mapping", "null": "null"}


def _type_words(error: jsonschema.ValidationError) -> str:
    """For a type error, what the key must be, in words (``it must be an integer (10, not 10.0)``); else empty."""
    if error.validator != "type":
        return ""
    types = [error.validator_value] if isinstance(error.validator_value, str) else list(error.validator_value)
    words = " or ".join(_TYPES.get(t, t) for t in types)
    value = error.instance
    hint = (f" ({int(value)}, not {value!r})" if "integer" in types and isinstance(value, float) and value.is_integer()
            else "")
    return f"it must be {words}{hint}"


def _form(option: dict, root: dict) -> str:
    """One form of a choice, as a line of an error message: the constant, the keys of a mapping, or the rule."""
    option = _flatten(option, root)
    if "const" in option:
        return str(option["const"])
    if option == {"type": "null"}:
        return "null"
    if set(option) <= {"type", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"} and "type" in option:
        bounds = {"minimum": ">=", "maximum": "<=", "exclusiveMinimum": ">", "exclusiveMaximum": "<"}
        limits = [f"{sign} {option[key]}" for key, sign in bounds.items() if key in option]
        return _TYPES.get(option["type"], str(option["type"])) + (f" {' and '.join(limits)}" if limits else "")
    if "properties" in option:
        required = list(option.get("required", []))
        optional = [key for key in option["properties"] if key not in required]
        return (f"a mapping of {', '.join(required)}" + (f" (optionally {', '.join(optional)})" if optional else "")
                + " (each key's own rule in the schema)")
    return str(option)


BENCHMARKS = ("slide_samer", "slide_small")


# libyaml's parser where PyYAML was built with it (the same safe constructor, about 10x faster: the workflow parses
# the defaults every time it plans), the pure-Python one otherwise.
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _yaml(node) -> Any:
    return yaml.load(node.read_text(), Loader=_SAFE_LOADER)


@functools.cache
def _scene_base() -> dict:
    return _yaml(SCENES_DIR.joinpath(SCENE_BASE))


def scene_base() -> dict:
    """The keys every scene's section shares with the same default (``generators/scenes/base.yaml``, its
    ``scales`` included), a fresh copy."""
    return copy.deepcopy(_scene_base())


def scene_own(name: str) -> dict:
    """What scene ``name``'s YAML sets itself (``generators/scenes/<name>.yaml``), without the base."""
    return _yaml(SCENES_DIR.joinpath(f"{name}.yaml"))


@functools.cache
def _defaults() -> dict:
    config = _yaml(DEFAULTS.joinpath("default.yaml"))
    for name in scenes.names():
        config[name] = deep_update(_scene_base(), scene_own(name))
    return config


@functools.cache
def schema() -> dict:
    """The root schema with every registered scene's fragment under ``properties.<scene>`` and the registered
    engines (generators/engines.py) as the choices of each scene's ``engine`` and of a DEM contender's."""
    root = _yaml(DEFAULTS.joinpath("schema.yaml"))
    root["$defs"]["dem_scene"]["properties"]["engine"]["enum"] = engines.names()
    root["$defs"]["performance"]["properties"]["dem"]["additionalProperties"]["properties"]["engine"]["enum"] = \
        engines.names()
    for name in scenes.names():
        root["properties"][name] = _yaml(SCENES_DIR.joinpath(f"{name}.schema.yaml"))
        root["required"].append(name)
    return root


def defaults() -> dict:
    """The embedded default config (every section with its scale presets), a fresh copy."""
    return copy.deepcopy(_defaults())


def _check_finite(node: Any, where: str = "") -> None:
    """Refuse NaN and infinities anywhere (they compare false against every schema bound, so pass it); ``where``:
    the key path of ``node``."""
    for key, value in config_checks.leaves(node, where):
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"config key {key!r} = {value!r} is not allowed: every number must be finite")


#: config keys of a scene's section that were renamed, as (the path below the section, old name, new name): a config
#: that still sets the old name is refused with the new one, not as an unknown key
RENAMED_KEYS = (
    ((), "stress_readout", "shear_stress_readout"),
    (("evaluate",), "property_test", "property_sensitivity"),
)


def _check_renamed(config: dict) -> None:
    """Refuse a renamed key of a scene's section (:data:`RENAMED_KEYS`), naming the key it was renamed to."""
    for name in scenes.names():
        for path, old, new in RENAMED_KEYS:
            node = config.get(name)
            for part in path:
                node = node.get(part) if isinstance(node, dict) else None
            if isinstance(node, dict) and old in node:
                where = ".".join((name, *path))
                raise ConfigError(f"config key '{where}.{old}' was renamed '{where}.{new}'")


def validate(config: dict) -> dict:
    """Validate a fully filled config against the schema; raise ConfigError naming the key."""
    _check_finite(config)
    config_checks.check_integers(config)
    _check_renamed(config)
    _raise_errors(_validator(None), config)
    _check_semantics(config)
    return config


def validate_part(value: Any, ref: str, where: str) -> Any:
    """Validate one part of a config (``value``, found at the key path ``where``, e.g. ``train.finetune``)
    against the schema node ``ref`` (``#/$defs/train/properties/finetune``), for the callers that receive a
    part without the whole config; raise ConfigError naming the key, as :func:`validate` does."""
    _check_finite(value, where)
    _raise_errors(_validator(ref), value, tuple(where.split(".")))
    return value


#: JSON Schema's validator with exact integers: an integer key refuses 10.0 (the standard counts it an integer, and the
#: stages after the check would meet a float where they count)
_VALIDATOR = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine(
        "integer", lambda _checker, value: isinstance(value, int) and not isinstance(value, bool)))


_VALIDATORS: dict[str | None, tuple[dict, jsonschema.Draft202012Validator]] = {}


def _validator(ref: str | None) -> jsonschema.Draft202012Validator:
    """The validator of the whole schema (``ref`` None) or of its node ``ref``, built once per schema: a schema
    built anew (an engine or scene registered since, ``schema.cache_clear()``) gets a new validator."""
    root = schema()
    cached = _VALIDATORS.get(ref)
    if cached is None or cached[0] is not root:
        cached = (root, _VALIDATOR(root if ref is None else {"$defs": root["$defs"], "$ref": ref}))
        _VALIDATORS[ref] = cached
    return cached[1]


def _raise_errors(validator: jsonschema.Draft202012Validator, value: Any, prefix: tuple[str, ...] = ()) -> None:
    root = validator.schema
    errors = sorted((leaf for e in validator.iter_errors(value) for leaf in _leaves(e)),
                    key=lambda e: [str(p) for p in e.absolute_path])
    lines = [line for line in (_describe(e, root, prefix=prefix) for e in errors) if line]
    if errors:
        first = _describe(errors[0], root, True, prefix)
        raise ConfigError("invalid configuration:\n  " + "\n  ".join(dict.fromkeys(lines or [first])))


def _check_semantics(config: dict) -> None:
    launch = config["launch"]
    if launch["launcher"] == "plain" and launch["processes"] > 1:
        raise ConfigError(f"config key 'launch.processes' = {launch['processes']} needs 'launch.launcher' = "
                          f"'torchrun' (plain starts one process)")
    for name, scene in scenes.registry().items():
        cfg = config[name]
        lo, hi = cfg["radius"]
        if lo > hi:
            raise ConfigError(f"config key '{name}.radius' = {cfg['radius']} must be [min, max] with min <= max")
        if abs(sum(cfg["split"]) - 1.0) > 1e-6:
            raise ConfigError(f"config key '{name}.split' = {cfg['split']} must sum to 1")
        _check_size(name, scene, cfg, config["limits"]["particles"])
        _check_contenders(name, cfg)
        _check_ranks(name, cfg["ranks"])
        if cfg["engine"] not in scene.engines:
            raise ConfigError(f"config key '{name}.engine' = {cfg['engine']!r}: the {name} scene runs in "
                              f"{', '.join(scene.engines)} for now")
        scene.check(cfg)
        property_sensitivity.values(name, cfg)
        _check_edge_features(name, cfg["model"])
        config_checks.check_section(name, scene, cfg, schema()["$defs"]["dem_scene"]["properties"]["n_sims"]["maximum"])
    config_checks.check_seeds(config, [*scenes.names(), *BENCHMARKS, "user"])
    _check_user(config)
    for name in BENCHMARKS:
        bench = config[name]
        _check_edge_features(name, bench["model"])
        if min(bench["protocols"]) < bench["model"]["history"]:
            raise ConfigError(f"config key '{name}.protocols' = {bench['protocols']}: a protocol gives K frames and "
                              f"the model reads the last '{name}.model.history' = {bench['model']['history']} of "
                              f"them, so every K must be at least that")


def _check_user(config: dict) -> None:
    """The ``user`` section's split and model, and every ``user_data`` entry (generators/user_data.py), which is
    left as its mapping of results name -> folder (a plain path becomes one entry named by its basename)."""
    user = config["user"]
    if abs(sum(user["split"]) - 1.0) > 1e-6:
        raise ConfigError(f"config key 'user.split' = {user['split']} must sum to 1")
    _check_edge_features("user", user["model"])
    config["user_data"] = user_data.check(config["user_data"], [*scenes.names(), *BENCHMARKS], user["split"])


def _check_edge_features(name: str, model: dict) -> None:
    """The edge feature ``gap`` reads the particle radius, so the model must take it as a node property."""
    if "gap" in (model.get("edge_features") or []) and "radius" not in model["properties"]:
        raise ConfigError(f"config key '{name}.model.edge_features' lists gap, which needs the particle radius: "
                          f"'{name}.model.properties' must list radius (it lists {model['properties']})")


def _check_size(name: str, scene, cfg: dict, limit: int) -> None:
    """Refuse a section whose estimated particle count (from its geometry and radii) exceeds ``limit``."""
    n, keys = config_checks.keys_read(scene.particle_estimate, cfg, name)
    if n > limit:
        mib = n * cfg["frames"] * scene.dim * 2 * 8 / 2 ** 20     # positions and velocities, float64
        raise ConfigError(
            f"config section '{name}': radius {cfg['radius']} gives about {n:,} particles per sim (estimated from the "
            f"geometry and radii: {keys}; {mib:,.0f} MiB of positions and velocities per recorded sim), above "
            f"'limits.particles' = {limit:,}; raise that key to run it anyway, or use larger radii")


def _check_ranks(name: str, ranks: int) -> None:
    """More ranks than one must be runnable by every engine taking MPI ranks (refused here, before anything
    runs; generators/engines.py)."""
    problem = engines.ranks_problem(ranks)
    if problem:
        raise ConfigError(f"config key '{name}.ranks' = {ranks} {problem}")


def _check_contenders(name: str, cfg: dict) -> None:
    """performance.main and .reference must name configured contenders (surrogate and DEM)."""
    perf = cfg.get("performance")
    if perf is None:
        return
    for key, kind in (("main", "surrogate"), ("reference", "dem")):
        if perf[key] not in perf[kind]:
            raise ConfigError(f"config key '{name}.performance.{key}' = {perf[key]!r} is not a {kind} contender "
                              f"('{name}.performance.{kind}.{perf[key]}' is not set); allowed: {sorted(perf[kind])} "
                              f"(the keys of '{name}.performance.{kind}')")
    for contender, changes in perf["dem"].items():
        if changes.get("engine", cfg["engine"]) not in scenes.get(name).engines:
            raise ConfigError(f"config key '{name}.performance.dem.{contender}.engine' = {changes['engine']!r}: the "
                              f"{name} scene runs in {', '.join(scenes.get(name).engines)}")
        if "dt_safety" in changes and "dt_factor" in changes:
            raise ConfigError(f"config key '{name}.performance.dem.{contender}': give "
                              f"'{name}.performance.dem.{contender}.dt_safety' (a fraction of the stable limit) or "
                              f"'{name}.performance.dem.{contender}.dt_factor' (a multiple of the data's step), "
                              "not both")


_FLOAT = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def coerce_scalars(value: Any) -> Any:
    """Turn numeric strings into numbers, ``true``/``false`` (any case) into booleans, and ``null`` / ``~`` into
    None.

    YAML 1.1 (PyYAML, and so Snakemake's ``--config``) reads ``5.0e9`` as a string, and Snakemake reads
    every scalar inside ``--config slide='{...}'`` as a string; a user who writes
    ``--config slide='{young: 5.0e9}'`` means a number, ``overwrite_scale=true`` a boolean, and
    ``--config slide='{train: {ema_decay: null}}'`` no value (no config key takes the text "null").
    """
    if isinstance(value, dict):
        return {k: coerce_scalars(v) for k, v in value.items()}
    if isinstance(value, list):
        return [coerce_scalars(v) for v in value]
    if isinstance(value, str) and value.strip().lower() in ("true", "false"):
        return value.strip().lower() == "true"
    if isinstance(value, str) and value.strip().lower() in ("null", "~"):
        return None
    if isinstance(value, str) and _FLOAT.match(value.strip()):
        number = float(value)
        return int(number) if number.is_integer() and "." not in value and "e" not in value.lower() else number
    return value


def resolve(config: dict) -> dict:
    """Fill the chosen scale preset of every section into ``config`` (user keys win), drop the presets,
    and validate the result."""
    config = coerce_scalars(config)
    scale = config.get("scale", "default")
    if scale not in ("ci", "default", "paper"):
        raise ConfigError(f"config key 'scale' = {scale!r} is not allowed; allowed: ['ci', 'default', 'paper']")
    filled = {}
    for key, value in config.items():
        if isinstance(value, dict) and "scales" in value:
            presets = value["scales"]
            if not isinstance(presets, dict) or scale not in presets:
                raise ConfigError(f"config key '{key}.scales' has no preset {scale!r}; presets: "
                                  f"{sorted(presets) if isinstance(presets, dict) else presets}")
            value = fill_missing({k: v for k, v in value.items() if k != "scales"}, presets[scale])
        filled[key] = drop_null_contenders(value)
    return validate(filled)


def drop_null_contenders(section: Any) -> Any:
    """``section`` without the performance contenders set to null: ``--config
    "slide={performance: {dem: {dt_5pct: null}}}"`` leaves that contender out of the performance stage (the
    configured ones are merged in, so null is the way to remove one)."""
    perf = section.get("performance") if isinstance(section, dict) else None
    if not isinstance(perf, dict):
        return section
    kept = {kind: {name: changes for name, changes in perf[kind].items() if changes is not None}
            for kind in ("dem", "surrogate") if isinstance(perf.get(kind), dict)}
    return {**section, "performance": {**perf, **kept}}


def load(overrides: dict | None = None, path: Path | None = None) -> dict:
    """The embedded default config (or the YAML file ``path``) with ``overrides`` merged in, resolved
    and validated."""
    base = defaults() if path is None else yaml.load(Path(path).read_text(), Loader=_SAFE_LOADER)
    return resolve(deep_update(base, overrides or {}))
