"""The Scene protocol: everything the pipeline knows about one DEM scene, in one module.

A scene module ``generators/scenes/<name>.py`` defines ``SCENE``, an instance of a :class:`Scene`
subclass; its config section (with its scale presets) is ``generators/scenes/<name>.yaml`` laid over
``generators/scenes/base.yaml`` (the keys every scene shares with the same default), and its schema
fragment ``generators/scenes/<name>.schema.yaml``. The registry (generators/scenes) finds them; every
stage iterates the registry and no other file names a scene.

What a scene provides:

- identity: ``name``, ``dim``, ``species`` (id -> name), ``kinematic_species``; ``engines`` it runs on is
  every registered engine (generators/engines.py), no scene names one;
- the sweep: :meth:`sweep_size` and :meth:`draw` (the swept values of sim ``i``; every other physical
  key of the section goes into each sweep row), :meth:`packings` (whose parameters are the keys
  :meth:`settle_setup` reads, derived by :meth:`packing_params`);
- engine-neutral descriptions (generators/dem.py): :meth:`settle_setup` (prepare),
  :meth:`simulate_setup` (simulate), and :meth:`settled` (what the scene keeps of a settled pour);
- data: :meth:`h5md_parameters`, :meth:`properties` (per-particle properties f_i) and
  :meth:`observables` (per-frame values, e.g. forces) of a sim;
- checks: :meth:`check` (config semantics, raising ConfigError with the key's name);
- metrics: ``metrics``, a class with ``for_trajectory(traj, body_displacement)``, ``names``,
  ``pair_names``, ``units``, ``__call__(position)`` and ``compare(predicted, truth)``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np

from generators import dem, engines
from generators.errors import ConfigError
from generators.packing import packing_key

# How an engine runs, not what it computes: never in a sweep row, a packing's key or the sweep stage's
# parameters, so a change to them reruns nothing (ranks: MPI ranks of a LAMMPS run).
EXECUTION_KEYS = ("ranks",)
# Surrogate settings (the Graph-DEM model, its training and scoring, and a scene's stress readout): a
# change to them retrains or rescores, it never reruns the sweep or an engine.
SURROGATE_KEYS = ("model", "train", "runtime", "evaluate", "performance", "stability", "shear_stress_readout")
# Keys of a scene section that never enter a sweep row: sweep and sizes, surrogate settings, how an engine
# runs, and the settling of the packing (which only the packing key carries).
NOT_IN_ROWS = frozenset({"seed", "split", "sweep", "n_sims", "n_packings", "connectivity_radius", "settle_time",
                         "settle_damping", "settle_speed", "settle_check", "scales", *SURROGATE_KEYS,
                         *EXECUTION_KEYS})
# Keys no settled packing depends on (the sweep, sizes, surrogate settings and how an engine runs).
NOT_IN_PACKINGS = frozenset({"split", "sweep", "n_sims", "n_packings", "connectivity_radius", "scales",
                             *SURROGATE_KEYS, *EXECUTION_KEYS})


class _Reader(dict):
    """A dict that remembers which keys were read (how a scene's packing parameters are derived)."""

    def __init__(self, values: dict):
        super().__init__(values)
        self.read: set[str] = set()

    def __getitem__(self, key):
        self.read.add(key)
        return super().__getitem__(key)

    def get(self, key, default=None):
        if key in self:
            self.read.add(key)
        return super().get(key, default)


class Scene(ABC):
    """One DEM scene; subclasses set the class attributes and implement the abstract methods."""

    name: ClassVar[str]
    dim: ClassVar[int]
    species: ClassVar[dict[int, str]]
    kinematic_species: ClassVar[tuple[int, ...]]
    metrics: ClassVar[type]
    # Keys of the section that only the config check reads (e.g. how long a record must be): never in a row.
    check_keys: ClassVar[tuple[str, ...]] = ()

    # ---- sweep ---------------------------------------------------------------------------------

    def packing_params(self, cfg: dict, index: int | None = None, **fixed) -> dict:
        """The parameters of one settled packing: exactly the keys of the section (plus ``fixed`` values,
        the seed and ``index``) that :meth:`settle_setup` reads. Derived, not listed: a key the settling
        starts to read becomes part of the packing's content key by itself."""
        full = {**{k: v for k, v in cfg.items() if k not in NOT_IN_PACKINGS}, **fixed, "seed": int(cfg["seed"])}
        if index is not None:
            full["packing_index"] = int(index)
        reader = _Reader(full)
        self.settled(reader, self.settle_setup(reader).particles, "packing")
        return {k: full[k] for k in full if k in reader.read}

    def packings(self, cfg: dict) -> list[dict]:
        """Every packing the sweep uses (each settled once by the prepare stage); default:
        ``n_packings`` packings of the same parameters and different seeds."""
        return [self.packing_params(cfg, i) for i in range(cfg["n_packings"])]

    def packing_keys_of(self, cfg: dict) -> list[str]:
        return [packing_key(p) for p in self.packings(cfg)]

    @abstractmethod
    def sweep_size(self, cfg: dict) -> int:
        """Number of sims of the sweep."""

    @abstractmethod
    def draw(self, cfg: dict, index: int, rng: np.random.Generator, packings: list[str]) -> dict:
        """The swept values of sim ``index`` and its ``packing`` key; ``rng`` is the sim's own generator
        (seeded by (seed, index), its first draw already taken for the sim's seed)."""

    def finish_sweep(self, rows: list[dict], cfg: dict) -> None:
        """Columns that depend on the whole sweep (added in place); default: none."""
        return None

    def row_params(self, cfg: dict) -> dict:
        """The physical parameters every sweep row carries: the section less NOT_IN_ROWS and the scene's
        ``check_keys``."""
        return {k: v for k, v in cfg.items() if k not in NOT_IN_ROWS and k not in self.check_keys}

    # ---- descriptions --------------------------------------------------------------------------

    @abstractmethod
    def settle_setup(self, params: dict) -> dem.Setup:
        """The loose packing of ``params`` (a packing's parameters) to settle under gravity."""

    def settled(self, params: dict, particles: dem.Particles, where: str) -> dem.Particles:
        """What the scene keeps of a settled pour (default: all of it)."""
        return particles

    @abstractmethod
    def simulate_setup(self, row: dict, packing: dem.Particles) -> dem.Setup:
        """The recorded run of sweep row ``row`` from its settled packing."""

    def contact(self, p: dict, kn: float, friction: float | None = None,
                rolling_friction: float | None = None) -> dem.Contact:
        """The section's contact model at normal stiffness ``kn`` (friction overridable, e.g. a weakened layer)."""
        return dem.Contact(young=p["young"], kn=kn, kt_over_kn=p["kt_over_kn"], restitution=p["restitution"],
                           friction=p["friction"] if friction is None else friction,
                           rolling_friction=p.get("rolling_friction", 0.0) if rolling_friction is None
                           else rolling_friction)

    def setup(self, p: dict, name: str, particles: dem.Particles, step: tuple[float, float, float], bounds,
              schedule, **extra) -> dem.Setup:
        """A Setup of this scene from section or row ``p``: ``step`` is (dt, stable limit, kn), ``bounds``
        (lower, upper) the domain, ``schedule(dt)`` the Settle or RecordingSchedule; ``extra`` the other Setup
        fields."""
        dt, limit, kn = step
        return dem.Setup(
            name=name, particles=particles, nominal_radius=0.5 * (p["radius"][0] + p["radius"][1]),
            kinematic_species=self.kinematic_species, n_species=len(self.species), density=p["density"],
            gravity=p["gravity"], contact=self.contact(p, kn), dt=dt, dt_limit=limit,
            lower=np.asarray(bounds[0], float), upper=np.asarray(bounds[1], float), max_overlap=p["max_overlap"],
            schedule=schedule(dt), **extra)

    @staticmethod
    def settling(p: dict, damping_kind: str):
        """The schedule factory (dt -> Settle) of the section's settle_damping, settle_time, settle_speed and
        settle_check."""
        return lambda dt: dem.Settle(damping=p["settle_damping"], damping_kind=damping_kind,
                                     check_every=p["settle_check"],
                                     max_time=p["settle_time"], speed=p["settle_speed"])

    # ---- data ----------------------------------------------------------------------------------

    def motion_interval(self, cfg: dict) -> float:
        """The longest frame interval (s) of the sweep where a motion sets it, in a scene whose section has no
        ``frame_interval`` (the config checks' step count)."""
        raise NotImplementedError(f"the {self.name} scene has no frame_interval key and no motion_interval")

    def h5md_parameters(self, row: dict, setup: dem.Setup) -> dict[str, Any]:
        """Scene parameters stored in the sim's H5MD /parameters besides the sweep row."""
        return {}

    def properties(self, row: dict) -> dict[str, float]:
        """Per-particle properties f_i of a sim (name -> value of every particle); default: none."""
        return {}

    def observables(self, row: dict, setup: dem.Setup, frames: dem.Frames) -> dict[str, np.ndarray]:
        """Per-frame observables of a sim (name -> [T]) for the H5MD file's /observables, from the engine's
        frames; default: none (kinetic energy is stored for every scene by convert). Each has its SI unit in
        :attr:`observable_units`."""
        return {}

    #: the SI unit of each of :meth:`observables` (the H5MD ``unit`` attribute of its value)
    observable_units: ClassVar[dict[str, str]] = {}

    #: properties the dataset normalises in log space
    log_scaled_properties: ClassVar[tuple[str, ...]] = ()

    # ---- checks --------------------------------------------------------------------------------

    @abstractmethod
    def particle_estimate(self, cfg: dict) -> int:
        """About how many particles one sim of the resolved section ``cfg`` holds, from the geometry and the
        radii alone (no packing is built): checked against ``limits.particles`` before anything runs."""

    def check(self, cfg: dict) -> None:
        """Semantic checks of the resolved section (the schema has checked types and ranges); default: none."""
        return None

    def physics(self, trajectories: list, out_csv, out_png, cfg: dict):
        """The scene's check of its DEM data against published physics (the physics stage): a table
        written to ``out_csv`` and a plot to ``out_png``; ``cfg`` is the scene's resolved config section.
        Scenes without one refuse by name (:func:`has_physics` tells which have one)."""
        raise ValueError(f"the {self.name} scene has no physics check")

    @property
    def has_physics(self) -> bool:
        """Whether the scene overrides :meth:`physics` with a check of its own."""
        return type(self).physics is not Scene.physics

    @property
    def engines(self) -> tuple[str, ...]:
        """The engines that run the scene: every registered one (generators/engines.py). A driver refuses by name
        (dem.UnsupportedSetup) a feature of the scene's Setups it cannot run; no scene names an engine."""
        return tuple(engines.NAMES)

    @property
    def kinematic_names(self) -> list[str]:
        return [self.species[s] for s in self.kinematic_species]


def lattice_spacing(r_max: float) -> float:
    """The spacing of every scene's loose packing lattice: 1.02 maximum diameters, so nothing overlaps."""
    return 2.0 * r_max * 1.02


def lattice_count(measure: float, r_max: float, dim: int) -> float:
    """Sites of the loose packings' lattice (triangular in 2D, cubic in 3D) in a region of area (2D) or
    volume (3D) ``measure``."""
    s = lattice_spacing(r_max)
    return measure / (s * s * math.sqrt(3) / 2 if dim == 2 else s ** 3)


def check_range(section: str, key: str, value) -> None:
    """Refuse a [min, max] pair whose min exceeds its max (``key`` below the config section ``section``)."""
    if isinstance(value, list) and len(value) == 2 and value[0] > value[1]:
        raise ConfigError(f"config key '{section}.{key}' = {value} must be [min, max] with min <= max")


def trajectory_parameters(traj, names: tuple[str, ...], scene: str) -> list[float]:
    """The H5MD /parameters ``names`` a scene's metrics need, as floats; refused by name where missing."""
    missing = [k for k in names if k not in traj.parameters]
    if missing:
        raise ValueError(f"{scene} metrics need the parameters {missing} in the H5MD file's parameters; "
                         f"files written by `graphdem convert` for the {scene} scene carry them")
    return [float(traj.parameters[k]) for k in names]
