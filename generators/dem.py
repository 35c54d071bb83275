"""The engine-neutral description of a DEM run: what a scene asks an engine driver to simulate.

A scene turns a config section (prepare) or a sweep row and its settled packing (simulate) into a
:class:`Setup`; every engine driver (generators/lammps, generators/yade) runs any Setup whose features
it supports and says by name which one it lacks. Nothing here knows a scene or an engine.

Units are SI. ``D`` is the scene's dimension (2: discs of unit thickness, 3: spheres).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Particles:
    """Particles of a scene: centres [N, D], radii [N], species ids [N], and named boolean groups
    [N] a scene keeps with its packing (e.g. the shear box's moving lower half)."""

    x: np.ndarray
    radius: np.ndarray
    species: np.ndarray
    groups: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dim(self) -> int:
        return int(np.shape(self.x)[1])

    def subset(self, keep: np.ndarray) -> Particles:
        return Particles(self.x[keep], self.radius[keep], self.species[keep],
                         {k: v[keep] for k, v in self.groups.items()})

    def concat(self, other: Particles) -> Particles:
        names = set(self.groups) | set(other.groups)
        groups = {k: np.concatenate([self.groups.get(k, np.zeros(len(self.radius), bool)),
                                     other.groups.get(k, np.zeros(len(other.radius), bool))]) for k in sorted(names)}
        return Particles(np.concatenate([self.x, other.x]), np.concatenate([self.radius, other.radius]),
                         np.concatenate([self.species, other.species]), groups)


@dataclass(frozen=True)
class Contact:
    """Linear spring-dashpot contact with Coulomb friction and rolling resistance (generators/contact.py).

    ``kn`` is the normal stiffness (N/m) of engines with a constant stiffness; engines that derive it
    per contact from the radii use ``young`` (each driver documents its law).
    """

    young: float
    kn: float
    kt_over_kn: float
    restitution: float
    friction: float
    rolling_friction: float = 0.0


@dataclass(frozen=True)
class PlanarWall:
    """A fixed planar wall normal to ``axis`` at ``lower`` and/or ``upper`` (None: no wall there),
    with the setup's default contact."""

    axis: int
    lower: float | None
    upper: float | None


@dataclass(frozen=True)
class Motion:
    """Kinematic particles of ``group`` (a name in Particles.groups) moved at constant ``velocity``;
    ``from_record``: held still through the run-up and moving from the first recorded frame on."""

    group: str
    velocity: tuple[float, ...]
    from_record: bool = False


@dataclass(frozen=True)
class Platen:
    """Kinematic particles of ``group`` moved as one rigid body along ``axis`` only (no rotation, no
    other translation) by Newton's law: total ``mass`` (kg; gravity acts on it), the contact forces
    on its particles and an external ``force`` (N along ``axis``, negative: towards -axis), constant
    after ``ramp`` steps.
    A load platen: its particles are kinematic in the data (their positions come from the engine)."""

    group: str
    mass: float
    force: float
    axis: int = 2
    ramp: int = 0                # steps over which the external force rises linearly from 0 (0: at once)


@dataclass(frozen=True)
class Settle:
    """Settle under gravity with damping until the moving particles are slow, or until ``max_time``.

    ``damping`` is viscous (1/s, force -damping * m_mean * v) or Cundall's local non-viscous
    coefficient (dimensionless), as ``damping_kind`` says. Every ``check_every`` seconds the run stops
    once the moving particles' RMS speed is below ``speed``.
    """

    damping: float
    damping_kind: str            # "viscous" | "local"
    check_every: float           # s
    max_time: float              # s
    speed: float                 # m/s


@dataclass(frozen=True)
class RecordingSchedule:
    """Run ``start`` steps unrecorded, then record ``frames`` frames ``every`` steps apart
    (frame 0 at step ``start``)."""

    start: int
    every: int
    frames: int


@dataclass(frozen=True)
class Perturbation:
    """A displacement of the particles right after frame ``frame`` of a RecordingSchedule is recorded: every
    particle moves by its row of ``displacement`` [N, D] (m; kinematic particles' rows are zero), and the run
    goes on from there with the velocities, rotations and contact history it had (a DEM ensemble member,
    generators/ensemble.py). Frames 0..frame are the unperturbed run's."""

    frame: int
    displacement: np.ndarray


@dataclass(frozen=True)
class Setup:
    """One DEM run, engine-neutral.

    ``contact`` holds for every contact unless a species of the pair is in ``species_contacts``
    (e.g. a weakened layer: the trigger). Particles of a ``kinematic`` species are never integrated;
    they stay put unless a :class:`Motion` moves their group. ``velocity`` [N, D] is the initial
    velocity. ``lower``/``upper`` bound the domain: a particle outside has escaped (a blow-up).
    ``max_energy_gain`` (None: no check, e.g. when a motion supplies energy) bounds the growth of
    kinetic plus gravitational energy of the moving particles, in units of M g d.
    """

    name: str                    # the sim id or packing key, for messages
    particles: Particles
    nominal_radius: float        # m, the scene's mean radius: rolling damping, settling damping, neighbour skin
    kinematic_species: tuple[int, ...]
    n_species: int
    density: float
    gravity: float
    contact: Contact
    dt: float
    dt_limit: float
    lower: np.ndarray
    upper: np.ndarray
    max_overlap: float
    schedule: Settle | RecordingSchedule
    species_contacts: dict[int, Contact] = field(default_factory=dict)
    walls: tuple[PlanarWall, ...] = ()
    motions: tuple[Motion, ...] = ()
    velocity: np.ndarray | None = None
    max_energy_gain: float | None = None
    tilt: float = 0.0                        # rad: gravity tilted towards +x (an incline of this angle)
    box_lower: np.ndarray | None = None      # the data's box (H5MD); default lower/upper
    box_upper: np.ndarray | None = None
    platen: Platen | None = None
    force_groups: tuple[str, ...] = ()       # groups whose summed contact force each frame reports (Frames), the
    force_samples: int = 1                   # mean over this many equally spaced steps of the frame interval,
                                             # the last at the frame (a divisor of RecordingSchedule.every)
    perturbation: Perturbation | None = None  # displace the particles after a recorded frame (RecordingSchedule only)

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.lower if self.box_lower is None else self.box_lower,
                self.upper if self.box_upper is None else self.box_upper)

    def group(self, name: str) -> np.ndarray:
        if name not in self.particles.groups:
            raise ValueError(f"{self.name}: no particle group {name!r}; groups: {sorted(self.particles.groups)}")
        return self.particles.groups[name]

    @property
    def dim(self) -> int:
        return self.particles.dim

    @property
    def kinematic(self) -> np.ndarray:
        return np.isin(self.particles.species, self.kinematic_species)


@dataclass(frozen=True)
class Frames:
    """What a driver's recorded run returns, in the particle order of the Setup."""

    position: np.ndarray         # [T, N, D]
    step: np.ndarray             # [T]
    time: np.ndarray             # [T] s
    mass: np.ndarray             # [N] kg (0 for kinematic particles of infinite mass, where an engine says so)
    radius: np.ndarray           # [N] m, as the engine stored them
    kinetic_energy: np.ndarray | None = None   # [T] J of the moving particles, where the engine reports it
    kinematic_force: np.ndarray | None = None  # [T, D] N: total contact force on the kinematic particles
    group_force: dict[str, np.ndarray] = field(default_factory=dict)   # group -> [T, D] N, the contact force
                                                                        # on Setup.force_groups at each frame


class UnsupportedSetup(ValueError):
    """An engine driver cannot run a feature of a Setup; the message names the feature and the engine."""


def checked_perturbation(setup: Setup) -> Perturbation | None:
    """The Setup's Perturbation, refused by name where no engine can apply it: a frame that is not followed by
    another of the RecordingSchedule, a displacement of another shape than the particles', or one that moves a
    kinematic particle."""
    p = setup.perturbation
    if p is None:
        return None
    frames = setup.schedule.frames if isinstance(setup.schedule, RecordingSchedule) else 0
    if not 0 <= p.frame < frames - 1:
        raise UnsupportedSetup(f"{setup.name}: a perturbation after frame {p.frame}; it must come after one of "
                               f"frames 0..{frames - 2} of a recorded run of {frames} frames")
    if np.shape(p.displacement) != np.shape(setup.particles.x):
        raise UnsupportedSetup(f"{setup.name}: a perturbation of shape {np.shape(p.displacement)} for particles of "
                               f"shape {np.shape(setup.particles.x)}")
    if np.any(np.asarray(p.displacement)[setup.kinematic]):
        raise UnsupportedSetup(f"{setup.name}: a perturbation that moves kinematic particles")
    return p
