"""The LAMMPS driver: runs any scene's Setup (generators/dem.py) that LAMMPS supports.

``settle`` writes the deck of a Settle schedule and returns the settled particles; ``run_recording`` writes
the deck of a RecordingSchedule and returns the recorded frames; ``read_raw`` reads a recorded run's
folder again (convert). Supported: 2D discs of unit thickness (``fix enforce2d``) and 3D spheres,
kinematic species (fixed, or moved at constant velocity by a Motion: ``fix move linear``), planar
walls, per-species contact overrides, initial velocities, gravity tilted for an incline, viscous
settling damping, a perturbation after a recorded frame (a DEM ensemble member: the window's run split around
``displace_atoms``). Each run is one ``lmp`` process, or ``ranks`` MPI ranks of the same deck under
``mpirun`` (runner.py).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from generators import blowup, dem
from generators.lammps import deck, io, runner
from generators.record import EngineRun

CONTACT_MODEL = deck.CONTACT_MODEL
PARALLEL = "ranks"          # more cores: MPI ranks of the same deck under mpirun (generators/engines.py)
ERRORS = (runner.LammpsError, runner.MpiMismatch, io.LammpsOutputError)


def ranks_problem(ranks: int) -> str | None:
    """Why ``ranks`` MPI ranks cannot run here (no mpirun on PATH, no network namespace for it), said after the
    config key; None where they can."""
    if ranks == 1 or runner.mpirun_path() is not None:
        return runner.isolation_problem(ranks)
    return (f"runs LAMMPS under `mpirun -np {ranks}`, and mpirun is not on PATH (Debian's openmpi-bin, installed "
            f"with lammps; or set {runner.MPIRUN_ENV} to it); allowed without it: 1")


def _engine_run(run: EngineRun, log: Path, window_runs: int = 1) -> EngineRun:
    """The run with LAMMPS' own loop time of its last ``window_runs`` runs (the recorded window: two where a
    perturbation splits it), of the runs before them (the run-up) and its step count."""
    loops = io.loop_times(log)
    return dataclasses.replace(run, window_seconds=sum(t for t, _ in loops[-window_runs:]) if loops else None,
                               runup_seconds=sum(t for t, _ in loops[:-window_runs]) if loops else None,
                               steps=sum(n for _, n in loops))


def _blowup(setup: dem.Setup, exc: runner.LammpsError, start: int, every: int) -> blowup.BlowUp:
    """A LAMMPS error as a named blow-up: the frame it happened at and the cause in words."""
    cause = str(exc)
    if "Lost atoms" in cause:
        cause = f"particles left the domain ({cause})"
    elif "Non-numeric" in cause or "nan" in cause.lower():
        cause = f"non-finite values ({cause})"
    if exc.step < start:
        cause += (f", after DEM step {exc.step} (its last thermo output), in the run-up before the first "
                  f"recorded frame")
    return blowup.BlowUp(setup.name, max(0, exc.step - start) // every, cause)


def _one_thread(setup: dem.Setup, threads: int) -> None:
    if threads != 1:
        raise dem.UnsupportedSetup(f"{setup.name}: threads = {threads}; LAMMPS runs one thread per MPI rank here "
                                   "(threads = 1): use ranks for more cores")


def settle(setup: dem.Setup, workdir: Path, ranks: int = 1, threads: int = 1) -> tuple[dem.Particles, EngineRun]:
    """Settle ``setup`` (a Settle schedule) in ``workdir`` on ``ranks`` MPI ranks; the particles at rest, in
    setup order."""
    _one_thread(setup, threads)
    workdir = Path(workdir)
    deck.write_data(workdir / deck.DATA, setup, f"graphdem {setup.name} loose packing")
    run = runner.run(deck.settle_deck(setup), workdir, ranks=ranks)
    (_, table), = io.read_dump(workdir / deck.PACKING)
    (workdir / deck.PACKING).unlink()
    x = table[list(deck.AXES[: setup.dim])].to_numpy(float)
    p = setup.particles
    return dem.Particles(x, table["radius"].to_numpy(float), table["type"].to_numpy() - 1, p.groups), \
        _engine_run(run, workdir / "log.lammps")


def run_recording(setup: dem.Setup, workdir: Path, ranks: int = 1, threads: int = 1) -> tuple[dem.Frames, EngineRun]:
    """Run ``setup`` (a RecordingSchedule) in ``workdir`` on ``ranks`` MPI ranks; blow-ups reported by LAMMPS
    raise BlowUp."""
    _one_thread(setup, threads)
    workdir = Path(workdir)
    schedule = setup.schedule
    deck.write_data(workdir / deck.DATA, setup, f"graphdem {setup.name}")
    window_runs = 1
    if dem.checked_perturbation(setup) is not None:
        deck.write_perturbation(workdir, setup)
        window_runs = 2
    try:
        run = runner.run(deck.record_deck(setup), workdir, ranks=ranks)
    except runner.LammpsError as exc:
        raise _blowup(setup, exc, schedule.start, schedule.every) from exc
    raw = read_raw(workdir, setup.dt)
    # a perturbation's step is in both runs' tables: the first, before the displacement, is the frame's
    thermo = io.read_thermo(workdir / "log.lammps", runs=window_runs)
    thermo = thermo.drop_duplicates("Step", keep="first").set_index("Step")
    missing = sorted(set(raw["step"].tolist()) - set(thermo.index.astype(int).tolist()))
    if missing:
        raise io.LammpsOutputError(f"{setup.name}: no thermo output at recorded steps {missing[:3]}")
    kinetic = (thermo["c_ke"] + thermo["c_erot"]).loc[raw["step"]].to_numpy()
    columns = [f"c_force[{k + 1}]" for k in range(setup.dim)]
    force = thermo[columns].loc[raw["step"]].to_numpy() if all(c in thermo for c in columns) else None
    group_force = {}
    for name in setup.force_groups:
        columns = deck.group_force_columns(setup, name)
        if not all(c in thermo for c in columns):
            raise io.LammpsOutputError(f"{setup.name}: no thermo columns {columns} of force group {name!r}")
        group_force[name] = thermo[columns].loc[raw["step"]].to_numpy(float)
    frames = dem.Frames(position=raw["position"], step=raw["step"], time=raw["time"], mass=raw["mass"],
                        radius=raw["radius"], kinetic_energy=kinetic, kinematic_force=force, group_force=group_force)
    return frames, _engine_run(run, workdir / "log.lammps", window_runs)


def read_raw(raw_dir: Path, dt: float) -> dict:
    """Positions [T, N, D] of every particle (the dumped ones, moving or moved by a Motion, from the frames
    dump; fixed ones from the data file), physical times (step x dt) and the static fields."""
    raw_dir = Path(raw_dir)
    (_, static), = io.read_dump(raw_dir / deck.STATIC)
    frames = io.read_dump(raw_dir / deck.FRAMES)
    coords = [c for c in deck.AXES if c in frames[0][1].columns]
    data = _data_positions(raw_dir / deck.DATA)[:, : len(coords)]
    ids = static["id"].to_numpy()
    index = {int(i): k for k, i in enumerate(ids)}
    position = np.repeat(data[None, ids - 1], len(frames), axis=0)
    steps = []
    for f, (step, table) in enumerate(frames):
        position[f, [index[int(i)] for i in table["id"]]] = table[coords].to_numpy(float)
        steps.append(step)
    dumped = set(frames[0][1]["id"].astype(int))
    if any(set(t["id"].astype(int)) != dumped for _, t in frames):
        raise io.LammpsOutputError(f"{raw_dir}: the frames do not all hold the same particles")
    species = static["type"].to_numpy() - 1
    step = np.asarray(steps)
    return {"position": position, "step": step, "time": step * dt, "species": species,
            "radius": static["radius"].to_numpy(float), "mass": static["mass"].to_numpy(float),
            "recorded": np.array([int(i) in dumped for i in ids])}


def _data_positions(path: Path) -> np.ndarray:
    """[N, 3] centres of a data file's Atoms section, by atom id."""
    lines = Path(path).read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("Atoms")) + 2
    rows = []
    for line in lines[start:]:
        if not line.strip():
            if rows:
                break
            continue
        rows.append(line.split())
    table = np.array(rows, float)
    return table[np.argsort(table[:, 0])][:, 4:7]

