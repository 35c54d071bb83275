"""LAMMPS input decks written from an engine-neutral Setup (generators/dem.py).

The deck is saved as the run's ``in.lammps``: ``lmp -in in.lammps`` in the raw folder repeats the run.
Numbers are written with 12 significant digits. Fix order (gravity, walls, damping, then the plane
constraint last) is the order LAMMPS adds their forces in.

Contact model (one definition, :func:`contact_model`, for particle pairs, per-species overrides and
walls): LAMMPS ``pair_style granular`` with ``hooke kn e damping tsuji`` (linear normal spring and
dashpot, constant kn = Contact.kn), ``tangential linear_history kt 0.0 mu`` (a tangential spring with
Coulomb friction and no tangential dashpot, as YADE's ViscElMat) and
``rolling sds kr gammar mur`` (rolling resistance). ``damping tsuji`` maps its input through Tsuji's
polynomial; the restitution given is inverted through it (contact.lammps_tsuji_input) so that a linear
contact has the configured one.
"""

from __future__ import annotations

import math

import numpy as np

from generators import contact as cm
from generators import dem

CONTACT_MODEL = ("linear spring-dashpot, Coulomb friction, rolling resistance "
                 "(LAMMPS granular hooke/tsuji/linear_history/sds)")
DATA = "data.lammps"
STATIC = "static.dump"
FRAMES = "frames.dump"
PACKING = "packing.dump"
PERTURBATION = "perturbation_{axis}.txt"
AXES = "xyz"


def fmt(value) -> str:
    return f"{value:.12g}" if isinstance(value, float) else str(value)


def contact_model(c: dem.Contact, density: float, nominal_radius: float, dim: int) -> str:
    """The granular model arguments of ``c``: normal, tangential and rolling parts.

    Rolling damping: critical-fraction damping of the rolling spring of a mean particle,
    gammar = 2 zeta sqrt(kr m / 2) r^2 with zeta from the restitution.
    """
    kt = c.kt_over_kn * c.kn
    mass = cm.particle_mass(density, nominal_radius, dim)
    zeta = cm.damping_ratio(c.restitution)
    gammar = 2.0 * zeta * math.sqrt(kt * mass / 2.0) * nominal_radius**2
    return (f"hooke {fmt(c.kn)} {fmt(cm.lammps_tsuji_input(c.restitution))} damping tsuji "
            f"tangential linear_history {fmt(kt)} 0.0 {fmt(c.friction)} "
            f"rolling sds {fmt(kt)} {fmt(gammar)} {fmt(c.rolling_friction)}")


def nominal_mass(setup: dem.Setup) -> float:
    return cm.particle_mass(setup.density, setup.nominal_radius, setup.dim)


def write_data(path, setup: dem.Setup, title: str) -> None:
    """An `atom_style sphere` data file (density column 1: masses are set by the deck), with a
    Velocities section where the setup starts particles moving; its box is the Setup's domain grown to
    hold every particle."""
    p = setup.particles
    # the box holds every particle (a pour may start above the domain it must stay in once settled;
    # the escape check uses the Setup's bounds)
    lower = np.minimum(np.asarray(setup.lower, float), (p.x - p.radius[:, None]).min(axis=0))
    upper = np.maximum(np.asarray(setup.upper, float), (p.x + p.radius[:, None]).max(axis=0))
    lines = [f"LAMMPS data file: {title}", "", f"{len(p.x)} atoms", f"{setup.n_species} atom types", "",
             f"{lower[0]:.10g} {upper[0]:.10g} xlo xhi", f"{lower[1]:.10g} {upper[1]:.10g} ylo yhi",
             "-0.5 0.5 zlo zhi" if setup.dim == 2 else f"{lower[2]:.10g} {upper[2]:.10g} zlo zhi",
             "", "Atoms # sphere", ""]
    z = np.zeros(len(p.x)) if setup.dim == 2 else p.x[:, 2]
    lines += [f"{i + 1} {int(t) + 1} {2 * r:.10g} 1 {x:.10g} {y:.10g} {zz:.10g}"
              for i, ((x, y), zz, r, t) in enumerate(zip(p.x[:, :2], z, p.radius, p.species, strict=True))]
    if setup.velocity is not None and np.any(setup.velocity):
        v = np.zeros((len(p.x), 3))
        v[:, : setup.dim] = setup.velocity
        lines += ["", "Velocities", ""]
        lines += [f"{i + 1} {fmt(float(a))} {fmt(float(b))} {fmt(float(c))} 0 0 0" for i, (a, b, c) in enumerate(v)]
    path.write_text("\n".join(lines) + "\n")


def _types(species: tuple[int, ...] | list[int]) -> str:
    return " ".join(str(s + 1) for s in species)


def setup_lines(setup: dem.Setup) -> list[str]:
    """Everything up to the schedule: box, particles, groups, contact model, integration, gravity, walls."""
    dim = setup.dim
    if dim not in (2, 3):
        raise dem.UnsupportedSetup(f"{setup.name}: dimension {dim}; LAMMPS runs 2 or 3")
    kinematic = [s for s in range(setup.n_species) if s in setup.kinematic_species]
    moving = [s for s in range(setup.n_species) if s not in setup.kinematic_species]
    model = contact_model(setup.contact, setup.density, setup.nominal_radius, dim)
    # a perturbation's per-atom files need LAMMPS' map of atoms by id (a lookup: the dynamics are the same)
    mapped = ["atom_modify     map array"] if setup.perturbation is not None else []
    lines = [f"dimension       {dim}", "units           si", "atom_style      sphere", *mapped,
             f"boundary        f f {'p' if dim == 2 else 'f'}", "comm_modify     vel yes", f"read_data       {DATA}",
             f"set             group all {'density/disc' if dim == 2 else 'density'} {fmt(float(setup.density))}"]
    if kinematic:
        lines.append(f"group           kinematic type {_types(kinematic)}")
    lines += [f"group           moving type {_types(moving)}", "", "pair_style      granular",
              f"pair_coeff      * * {model}"]
    for species, override in sorted(setup.species_contacts.items()):
        lines.append(f"pair_coeff      * {species + 1} "
                     f"{contact_model(override, setup.density, setup.nominal_radius, dim)}")
    exclude = "".join(f" exclude type {a + 1} {b + 1}" for i, a in enumerate(kinematic) for b in kinematic[i:])
    s, c = math.sin(setup.tilt), math.cos(setup.tilt)
    down = f"{fmt(s)} {fmt(-c)} 0" if dim == 2 else f"{fmt(s)} 0 {fmt(-c)}"
    lines += [f"neighbor        {fmt(0.5 * setup.nominal_radius)} bin",
              f"neigh_modify    delay 0 every 1 check yes{exclude}", "",
              f"fix             integrate moving nve/sphere{' disc' if dim == 2 else ''}",
              f"fix             gravity moving gravity {fmt(float(setup.gravity))} vector {down}"]
    for k, wall in enumerate(setup.walls):
        bounds = " ".join("NULL" if b is None else fmt(float(b)) for b in (wall.lower, wall.upper))
        lines.append(f"fix             wall{k} all wall/gran granular {model} {AXES[wall.axis]}plane {bounds}")
    for k, motion in enumerate(setup.motions):
        lines += motion_lines(setup, k, motion)
        if not motion.from_record:
            lines.append(move_line(k, motion))
    for k, name in enumerate(setup.force_groups):
        if setup.platen is None or name != setup.platen.group:
            lines += group_lines(setup, name, f"force{k}")
    if setup.platen is not None:
        lines += platen_lines(setup)
    return lines


def group_lines(setup: dem.Setup, group: str, name: str) -> list[str]:
    """A LAMMPS group ``name`` of the Setup's group ``group``, by atom id (200 per line)."""
    ids = np.flatnonzero(setup.group(group)) + 1
    return [f"group           {name} id {' '.join(str(i) for i in ids[j:j + 200])}" for j in range(0, len(ids), 200)]


def motion_lines(setup: dem.Setup, k: int, motion: dem.Motion) -> list[str]:
    """A Motion's group ``motion<k>`` (its atoms by id); :func:`move_line` moves it."""
    if not np.all(setup.kinematic[setup.group(motion.group)]):
        raise dem.UnsupportedSetup(f"{setup.name}: motion of group {motion.group!r} moves particles that are not "
                                   "of a kinematic species")
    return group_lines(setup, motion.group, f"motion{k}")


def move_line(k: int, motion: dem.Motion) -> str:
    """A Motion's group moved at constant velocity by `fix move` from the step it is defined on."""
    v = list(motion.velocity) + [0.0] * (3 - len(motion.velocity))
    return f"fix             motion{k} motion{k} move linear {' '.join(fmt(float(x)) for x in v)}"


def platen_lines(setup: dem.Setup) -> list[str]:
    """A Platen as group ``platen``: each of its N atoms has mass M / N and the same force along the axis,
    the average of their contact forces plus F / N (`fix aveforce`; F ramped over Platen.ramp steps) plus
    their weight (fix gravity, after it), and none across
    it (`fix setforce`); `fix nve` moves them without rotation, so the group translates rigidly along the
    axis. fix aveforce's vector, summed before it changes the forces, is the platen's contact force."""
    platen = setup.platen
    if setup.dim != 3:
        raise dem.UnsupportedSetup(f"{setup.name}: the LAMMPS driver runs a platen in 3D scenes only")
    mask = setup.group(platen.group)
    if not np.all(setup.kinematic[mask]):
        raise dem.UnsupportedSetup(f"{setup.name}: platen group {platen.group!r} holds particles that are not of a "
                                   "kinematic species")
    n = int(mask.sum())
    s, c = math.sin(setup.tilt), math.cos(setup.tilt)
    along = ["NULL" if a == platen.axis else "0.0" for a in range(3)]
    load = ["NULL"] * 3
    load[platen.axis] = "v_platen_load"
    r = int(platen.ramp)
    ramp = f"*(step/{r}*(step<{r})+(step>={r}))" if r > 0 else ""
    return [*group_lines(setup, platen.group, "platen"),
            f"set             group platen mass {fmt(float(platen.mass) / n)}",
            f'variable        platen_load equal "{fmt(float(platen.force) / n)}{ramp}"',
            "fix             platen_integrate platen nve",
            f"fix             platen_load platen aveforce {' '.join(load)}",
            f"fix             platen_gravity platen gravity {fmt(float(setup.gravity))} vector {fmt(s)} 0 {fmt(-c)}",
            f"fix             platen_across platen setforce {' '.join(along)}"]


def settle_deck(setup: dem.Setup) -> str:
    """Settle under gravity with viscous damping, checking the moving particles' RMS speed every
    ``check_every`` seconds; write the settled positions to packing.dump."""
    s = setup.schedule
    if s.damping_kind != "viscous":
        raise dem.UnsupportedSetup(f"{setup.name}: settling damping {s.damping_kind!r}; the LAMMPS driver damps "
                                   "with a viscous force (damping_kind 'viscous')")
    chunk = max(1, int(round(s.check_every / setup.dt)))
    max_chunks = max(1, int(math.ceil(s.max_time / (chunk * setup.dt))))
    coords = " ".join(AXES[: setup.dim])
    lines = setup_lines(setup) + [
        f"fix             damping moving viscous {fmt(s.damping * nominal_mass(setup))}",
        *(["fix             plane all enforce2d"] if setup.dim == 2 else []),
        f"timestep        {fmt(setup.dt)}", "",
        "compute         ke moving ke",
        "variable        rms_speed equal sqrt(2.0*c_ke/mass(moving))",
        "thermo_style    custom step time c_ke v_rms_speed", f"thermo          {chunk}", "",
        "label           settle", f"variable        chunk_index loop {max_chunks}", f"run             {chunk}",
        f'if              "${{rms_speed}} < {fmt(float(s.speed))}" then "jump SELF settled"',
        "next            chunk_index", "jump            SELF settle", "label           settled",
        'print           "SETTLED step $(step) rms_speed ${rms_speed}"',
        f"write_dump      all custom {PACKING} id type radius {coords} modify sort id format float %.10g"]
    return "\n".join(lines) + "\n"


def force_lines(setup: dem.Setup) -> list[str]:
    """Thermo output of the moving particles' kinetic energy and, where there are kinematic particles, the
    total contact force on them (c_force[1..D])."""
    if not setup.kinematic.any():
        return ["thermo_style    custom step time c_ke c_erot"]
    axes = AXES[: setup.dim]
    lines = [f"compute         force kinematic reduce sum {' '.join('f' + a for a in axes)}"]
    columns = [f"c_force[{k + 1}]" for k in range(setup.dim)]
    inputs = []
    for name in setup.force_groups:
        inputs += _group_force_inputs(setup, name)
        if setup.platen is None or name != setup.platen.group:
            k = setup.force_groups.index(name)
            lines.append(f"compute         force{k} force{k} reduce sum {' '.join('f' + a for a in axes)}")
    if inputs:
        every, samples = setup.schedule.every, setup.force_samples
        if every % samples or (samples > 1 and setup.schedule.start < every):
            raise dem.UnsupportedSetup(f"{setup.name}: {samples} force samples in a frame interval of {every} steps "
                                       f"(not a divisor), or before a run-up of {setup.schedule.start} steps")
        lines.append(f"fix             groupforce all ave/time {every // samples} {samples} {every} {' '.join(inputs)}")
        columns += [f"f_groupforce[{k + 1}]" for k in range(len(inputs))]
    return lines + ["thermo_style    custom step time c_ke c_erot " + " ".join(columns)]


def _group_force_inputs(setup: dem.Setup, name: str) -> list[str]:
    """The per-step values of force group ``name``'s contact force: a platen's from its fix aveforce (the sum
    before the fix changes it), any other group's from a reduce compute."""
    if setup.platen is not None and name == setup.platen.group:
        return [f"f_platen_load[{a + 1}]" for a in range(setup.dim)]
    return [f"c_force{setup.force_groups.index(name)}[{a + 1}]" for a in range(setup.dim)]


def group_force_columns(setup: dem.Setup, name: str) -> list[str]:
    """The thermo columns of force group ``name``'s contact force, each the mean over Setup.force_samples
    equally spaced steps of the frame interval ending at the frame (`fix ave/time`)."""
    k = setup.force_groups.index(name)
    return [f"f_groupforce[{k * setup.dim + a + 1}]" for a in range(setup.dim)]


def record_deck(setup: dem.Setup) -> str:
    """Static fields once; run to frame 0; then the positions of the moving particles and of those a Motion
    moves every frame, and the moving particles' kinetic energy (translational and rotational) in the
    thermo output."""
    r = setup.schedule
    if r.start % r.every:
        raise dem.UnsupportedSetup(f"{setup.name}: recording starts at step {r.start}, not a multiple of the "
                                   f"frame interval {r.every} steps; LAMMPS dumps only on multiples of it")
    coords = " ".join(AXES[: setup.dim])
    lines = setup_lines(setup) + [
        *(["fix             plane all enforce2d"] if setup.dim == 2 else []),
        f"timestep        {fmt(setup.dt)}", "",
        "compute         ke moving ke", "compute         erot moving erotate/sphere",
        *force_lines(setup), f"thermo          {r.every}", "",
        f"write_dump      all custom {STATIC} id type radius mass modify sort id format float %.10g"]
    if r.start:
        lines.append(f"run             {r.start}")
    lines += [move_line(k, m) for k, m in enumerate(setup.motions) if m.from_record]
    recorded = "moving"
    if setup.motions or setup.platen is not None:        # moving kinematic particles are recorded too
        recorded = "recorded"
        moved = [f"motion{k}" for k in range(len(setup.motions))] + (["platen"] if setup.platen is not None else [])
        lines.append(f"group           recorded union moving {' '.join(moved)}")
    lines += [f"dump            frames {recorded} custom {r.every} {FRAMES} id {coords}",
              "dump_modify     frames sort id format float %.10g", *window_lines(setup)]
    return "\n".join(lines) + "\n"


def window_lines(setup: dem.Setup) -> list[str]:
    """The recorded window: one run of every x (frames - 1) steps or, with a Perturbation, a run to its frame,
    the displacement of the moving particles (`displace_atoms` by the per-atom values of the perturbation files,
    :func:`write_perturbation`) and a run to the end. The split step is dumped once (LAMMPS writes no snapshot
    twice at a step) and its thermo row is printed by both runs, the second after the displacement."""
    r = setup.schedule
    p = dem.checked_perturbation(setup)
    if p is None:
        return [f"run             {r.every * (r.frames - 1)}"]
    axes = AXES[: setup.dim]
    moves = " ".join([f"v_perturb_{a}" for a in axes] + ["0"] * (3 - setup.dim))
    return [f"run             {r.every * p.frame}",
            *(f"variable        perturb_{a} atomfile {PERTURBATION.format(axis=a)}" for a in axes),
            f"displace_atoms  moving move {moves} units box",
            f"run             {r.every * (r.frames - 1 - p.frame)}"]


def write_perturbation(workdir, setup: dem.Setup) -> None:
    """The Perturbation's displacement of each moving particle along each axis, one `atomfile` per axis (atom id
    and value in m, to 17 digits: read back exactly)."""
    p = dem.checked_perturbation(setup)
    ids = np.flatnonzero(~setup.kinematic)
    for a, axis in enumerate(AXES[: setup.dim]):
        lines = [f"# graphdem: displacement along {axis} (m) after frame {p.frame}", str(len(ids))]
        lines += [f"{i + 1} {float(p.displacement[i, a]):.17g}" for i in ids]
        (workdir / PERTURBATION.format(axis=axis)).write_text("\n".join(lines) + "\n")
