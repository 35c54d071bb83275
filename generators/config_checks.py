"""Cross-key checks of a resolved config: the constraints the later stages need, checked when the config is read.

The schema checks each key alone; these check what keys allow together, so that no value fails after the sims ran:

- the recorded window: ``frames`` holds a history and the frames training predicts after it
  (``model.history`` + ``model.bundle``), and at least one of the taus of ``evaluate.frames`` lies among the
  predicted frames (1 .. frames - history);
- the split: the sweep's size and ``split`` leave every split (train, valid, test) a sim, by the rule that
  assigns them (generators/sweep.py, ``split_counts``), and the sweep holds at most as many sims as ``n_sims``
  may;
- the DEM step: every step a run takes (the data's, the stability stage's and the performance stage's DEM
  contenders') is positive and within the stable limit where it is given explicitly, and each run's steps fit
  LAMMPS' 32-bit counts (``run``, ``thermo``, ``dump``, the settling's loop), YADE's being wider;
- the restitution: one LAMMPS' damping reaches (generators/contact.py);
- the seeds: each training seed (``train.seed`` and the next ``seeds`` - 1) within numpy's range.

Each refusal is a ConfigError naming the keys involved and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from generators import contact, sweep
from generators.errors import ConfigError

#: LAMMPS' counts of steps (run N, thermo N, dump every N, a loop's N) are 32-bit signed integers
MAX_STEPS = 2 ** 31 - 1
#: the largest seed numpy's legacy generators (and so every seed here) take
MAX_SEED = 2 ** 32 - 1
#: steps a frame interval may round up by (a scene rounds steps per frame to a multiple of its force samples)
ROUNDING_STEPS = 16


class Reads(dict):
    """A mapping that records the key paths read from it (nested mappings too), as ``section.key.sub``."""

    def __init__(self, values: dict, where: str, read: list[str] | None = None):
        super().__init__(values)
        self.where, self.read = where, [] if read is None else read

    def __getitem__(self, key):
        path = f"{self.where}.{key}"
        if path not in self.read:
            self.read.append(path)
        value = super().__getitem__(key)
        return Reads(value, path, self.read) if isinstance(value, dict) else value

    def get(self, key, default=None):
        return self[key] if key in self else default


def keys_read(function, cfg: dict, where: str) -> tuple[Any, str]:
    """``function(cfg)`` and the keys of ``cfg`` it read, as "'where.key' = value" items of a message."""
    reads = Reads(cfg, where)
    result = function(reads)
    named = []
    for path in reads.read:
        value: Any = cfg
        for part in path.split(".")[1:]:
            value = value[part]
        if not isinstance(value, dict):
            named.append(f"'{path}' = {value!r}")
    return result, ", ".join(named)


def check_section(name: str, scene, cfg: dict, max_sims: int) -> None:
    """Every cross-key check of the scene section ``name`` (``max_sims``: the most sims a sweep may hold)."""
    check_window(name, cfg)
    check_split(name, scene, cfg, max_sims)
    check_restitution(name, cfg)
    check_steps(name, scene, cfg)


def check_window(name: str, cfg: dict) -> None:
    """The recorded frames hold the history and the frames predicted after it; some tau lies among them."""
    frames, history = cfg["frames"], cfg["model"]["history"]
    bundle = cfg["model"].get("bundle", 1)
    if frames < history + bundle:
        bundled = f" and '{name}.model.bundle' = {bundle}" if "bundle" in cfg["model"] else ""
        raise ConfigError(f"config keys '{name}.frames' = {frames}, '{name}.model.history' = {history}{bundled}: a "
                          f"training sample is a history of {history} frames and the {bundle} frame(s) predicted "
                          f"after it, so '{name}.frames' must be at least {history + bundle}")
    taus, predicted = cfg["evaluate"]["frames"], frames - history
    if taus is not None and not any(1 <= tau <= predicted for tau in taus):
        raise ConfigError(f"config key '{name}.evaluate.frames' = {taus}: no tau within the {predicted} predicted "
                          f"frames ('{name}.frames' = {frames} less '{name}.model.history' = {history}); allowed: "
                          f"taus among 1..{predicted}, or null (every predicted frame)")


def check_split(name: str, scene, cfg: dict, limit: int) -> None:
    """Every split gets a sim of the sweep (generators/sweep.py's rule), and the sweep holds at most ``limit``."""
    n, size = keys_read(scene.sweep_size, cfg, name)
    if n > limit:
        raise ConfigError(f"config section '{name}': the sweep holds {n:,} sims ({size}), above {limit:,} (the "
                          f"most 'n_sims' allows); sweep fewer values")
    counts = sweep.split_counts(n, cfg["split"])
    empty = [split for split, count in zip(sweep.SPLITS, counts, strict=True) if count < 1]
    if empty:
        raise ConfigError(f"config key '{name}.split' = {cfg['split']} leaves the {' and '.join(empty)} split empty "
                          f"for the sweep's {n} sims ({size}): {dict(zip(sweep.SPLITS, counts, strict=True))}; every "
                          f"split needs a sim: give each a fraction > 0 and sweep at least 3 sims")


def check_restitution(name: str, cfg: dict) -> None:
    """A restitution LAMMPS' damping (Tsuji's polynomial) reaches on a linear contact."""
    try:
        contact.lammps_tsuji_input(cfg["restitution"])
    except ValueError as exc:
        raise ConfigError(f"config key '{name}.restitution' = {cfg['restitution']} is not allowed: {exc}") from None


def _stable_limit(name: str, dim: int, cfg: dict) -> tuple[float, str]:
    """The stable limit of the stiffest contact of the sweep (its largest modulus), and the keys it comes from."""
    youngs = [cfg["young"]] if "young" in cfg else list(cfg["sweep"]["young"])
    keys = f"'{name}.radius' = {cfg['radius']}, '{name}.density' = {cfg['density']} and " + (
        f"'{name}.young' = {cfg['young']}" if "young" in cfg else f"'{name}.sweep.young' = {cfg['sweep']['young']}")
    try:
        limit = contact.time_step({**cfg, "young": max(youngs), "dt": None, "dt_safety": 1.0}, name, dim)[1]
    except (ArithmeticError, ValueError):
        limit = math.nan
    if not (math.isfinite(limit) and limit > 0):
        raise ConfigError(f"config keys {keys} give no finite positive stable time step; allowed: physical sizes")
    return limit, keys


def _steps(name: str, cfg: dict, limit: float) -> list[tuple[float, str]]:
    """Every DEM step a run of the section takes, each with the keys that set it: the data's, the stability stage's
    factors of the stable limit and the performance stage's DEM contenders (evaluation/performance.py)."""
    if cfg["dt"] is not None:
        if cfg["dt"] > limit:
            raise ConfigError(f"config key '{name}.dt' = {cfg['dt']} exceeds the stable limit {limit:.4g} s; allowed: "
                              f"dt <= {limit:.4g}, or null (dt_safety x the limit)")
        out = [(cfg["dt"], f"'{name}.dt' = {cfg['dt']}")]
    else:
        out = [(cfg["dt_safety"] * limit, f"'{name}.dt_safety' = {cfg['dt_safety']}")]
    factors = cfg["stability"]["dem_dt_factors"]
    out.append((min(factors) * limit, f"'{name}.stability.dem_dt_factors' = {factors}"))
    if cfg["dt"] is None:
        for contender, changes in cfg["performance"]["dem"].items():
            scaled = limit / math.sqrt(changes.get("stiffness_factor", 1.0))
            safety = changes.get("dt_safety", cfg["dt_safety"] * changes.get("dt_factor", 1.0))
            keys = [f"'{name}.performance.dem.{contender}.{key}' = {value}" for key, value in changes.items()]
            out.append((safety * scaled, ", ".join(keys) or f"'{name}.performance.dem.{contender}' = {{}}"))
    return out


def _recording(name: str, scene, cfg: dict) -> tuple[float, float, str]:
    """(frame interval, run-up before frame 0, the keys they come from) of the section's recorded runs: its
    ``frame_interval``, or where a motion sets the interval, the scene's longest (``Scene.motion_interval``, e.g.
    the largest ``sweep.displacements`` over the slowest shear spread over the frames); the run-up
    ``record_start`` or ``load_time``."""
    frames = cfg["frames"]
    if "frame_interval" in cfg:
        interval, keys = cfg["frame_interval"], [f"'{name}.frame_interval' = {cfg['frame_interval']}"]
    else:
        interval, read = keys_read(scene.motion_interval, cfg, name)
        keys = [read]
    runup = next((key for key in ("record_start", "load_time") if key in cfg), None)
    if runup is not None:
        keys.append(f"'{name}.{runup}' = {cfg[runup]}")
    return interval, cfg.get(runup, 0.0) if runup else 0.0, ", ".join([*keys, f"'{name}.frames' = {frames}"])


def check_steps(name: str, scene, cfg: dict) -> None:
    """Each run's steps (per frame, in the run, and the settling's) fit LAMMPS' 32-bit counts at every step."""
    limit, material = _stable_limit(name, scene.dim, cfg)
    interval, runup, timing = _recording(name, scene, cfg)
    steps = _steps(name, cfg, limit)
    for dt, source in steps:
        per_frame = interval / dt if dt > 0 else math.inf
        total = runup / dt + (per_frame + ROUNDING_STEPS) * (cfg["frames"] + 1) if dt > 0 else math.inf
        if not total <= MAX_STEPS:
            raise ConfigError(
                f"config keys {timing} and the DEM step {dt:.4g} s ({source}, of the stable limit {limit:.4g} s of "
                f"{material}) give about {total:.4g} steps in a recorded run ({per_frame:.4g} per frame); a run's "
                f"steps must fit LAMMPS' 32-bit counts (at most {MAX_STEPS}): record a shorter window or take a "
                "larger step")
    dt, source = steps[0]
    settle = (cfg["settle_time"] + cfg["settle_check"]) / dt
    if not settle <= MAX_STEPS:
        raise ConfigError(
            f"config keys '{name}.settle_time' = {cfg['settle_time']} and '{name}.settle_check' = "
            f"{cfg['settle_check']} at the DEM step {dt:.4g} s ({source}, of the stable limit {limit:.4g} s of "
            f"{material}) give about {settle:.4g} settling steps; they must fit LAMMPS' 32-bit counts (at most "
            f"{MAX_STEPS}): settle for less time or take a larger step")


def check_seeds(config: dict, sections: list[str]) -> None:
    """Each training seed (``train.seed`` and the next ``seeds`` - 1) is one numpy takes (at most 2**32 - 1)."""
    for name in sections:
        last = config[name]["train"]["seed"] + config["seeds"] - 1
        if last > MAX_SEED:
            raise ConfigError(f"config keys '{name}.train.seed' = {config[name]['train']['seed']} and 'seeds' = "
                              f"{config['seeds']} give training seeds up to {last}; allowed: seeds up to {MAX_SEED}")


def leaves(node: Any, where: str = "") -> Iterator[tuple[str, Any]]:
    """Every value of a config tree that is neither a mapping nor a list, with its dotted key (``a.b[2]``)."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from leaves(value, f"{where}.{key}" if where else str(key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from leaves(value, f"{where}[{i}]")
    else:
        yield where, node


def check_integers(node: Any, where: str = "") -> None:
    """Refuse an integer beyond 64 bits anywhere (numpy and HDF5 hold none): a huge number is written as a float."""
    for key, value in leaves(node, where):
        if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 2 ** 63 - 1:
            raise ConfigError(f"config key {key!r} = {value} is not allowed: an integer must lie within 64 bits "
                              f"(|n| <= {2 ** 63 - 1}); write a huge number as a float, e.g. {float(value):.6g}")
