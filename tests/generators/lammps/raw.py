"""LAMMPS output written by hand, in the formats a real run leaves (`dump custom`, an `atom_style sphere` data
file, a log's thermo table), for the tests of the readers without running LAMMPS."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from generators.lammps import deck


def snapshot(step: int, columns: str, rows) -> str:
    """One `dump custom` snapshot of ``rows`` (one per atom, in the order given) under ``columns``."""
    lines = ["ITEM: TIMESTEP", str(step), "ITEM: NUMBER OF ATOMS", str(len(rows)), "ITEM: BOX BOUNDS ff ff pp",
             "-1 1", "-1 1", "-0.5 0.5", f"ITEM: ATOMS {columns}"]
    lines += [" ".join(f"{v:.10g}" if isinstance(v, float) else str(v) for v in r) for r in rows]
    return "\n".join(lines) + "\n"


def thermo(header: str, rows, steps: int, seconds: float = 0.5) -> str:
    """A run of ``steps`` steps in a log: its thermo table, then its "Loop time" line."""
    body = [header] + ["  ".join(f"{v:g}" for v in r) for r in rows]
    return "\n".join(body + [f"Loop time of {seconds:g} on 1 procs for {steps} steps with 3 atoms", ""])


def write_run(folder: Path, x: np.ndarray, radius, species, mass, steps, moving_x: np.ndarray,
              dumped: np.ndarray | None = None) -> None:
    """A recorded 2D run's folder: the data file of the particles at ``x``, the static dump and one frame a
    step of ``steps`` holding the positions ``moving_x`` [T, M, 2] of the M ``dumped`` particles (default: those
    of species != 0), in reverse id order (LAMMPS sorts them; the reader must not rely on it)."""
    folder.mkdir(parents=True, exist_ok=True)
    n = len(x)
    atoms = [f"{i + 1} {s + 1} {2 * r:.10g} 1 {a:.10g} {b:.10g} 0" for i, ((a, b), r, s) in
             enumerate(zip(x, radius, species, strict=True))]
    (folder / deck.DATA).write_text("\n".join(["LAMMPS data file: by hand", "", f"{n} atoms", "2 atom types", "",
                                               "Atoms # sphere", "", *atoms, ""]))
    ids = np.arange(1, n + 1)
    (folder / deck.STATIC).write_text(snapshot(0, "id type radius mass", [
        (int(i), int(s) + 1, float(r), float(m)) for i, s, r, m in zip(ids, species, radius, mass, strict=True)]))
    moving = ids[np.asarray(species) != 0 if dumped is None else dumped]
    (folder / deck.FRAMES).write_text("".join(
        snapshot(step, "id x y", [(int(i), float(a), float(b)) for i, (a, b) in zip(moving, frame, strict=True)][::-1])
        for step, frame in zip(steps, moving_x, strict=True)))
