"""LAMMPS output formats: `dump custom` and log files (data files in: generators/lammps/deck.py)."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pandas as pd


class LammpsOutputError(ValueError):
    """A LAMMPS output file is missing, truncated or inconsistent."""


def read_dump(path: Path) -> list[tuple[int, pd.DataFrame]]:
    """All snapshots of a `dump custom` text file as (timestep, table sorted by id)."""
    path = Path(path)
    if not path.is_file():
        raise LammpsOutputError(f"{path}: dump file missing")
    text = path.read_text()
    frames = []
    for block in text.split("ITEM: TIMESTEP\n")[1:]:
        try:
            head, _, rest = block.partition("ITEM: ATOMS ")
            step = int(head.split("\n", 1)[0])
            n = int(head.split("ITEM: NUMBER OF ATOMS\n", 1)[1].split("\n", 1)[0])
            columns, _, body = rest.partition("\n")
            table = pd.read_csv(io.StringIO(body), sep=r"\s+", header=None,
                                names=columns.split(), engine="c")
        except (ValueError, IndexError) as exc:
            raise LammpsOutputError(f"{path}: malformed snapshot ({exc})") from exc
        if len(table) != n:
            raise LammpsOutputError(f"{path}: snapshot at step {step} has {len(table)} atoms, header says {n}")
        frames.append((step, table.sort_values("id").reset_index(drop=True)))
    if not frames:
        raise LammpsOutputError(f"{path}: no snapshots")
    return frames


def read_thermo(log: Path, runs: int = 1) -> pd.DataFrame:
    """The thermo tables of the last ``runs`` runs of a LAMMPS log file, one after the other."""
    lines = Path(log).read_text().splitlines()
    tables, current, header = [], None, None
    for line in lines:
        words = line.split()
        if words and words[0] == "Step":
            header, current = words, []
            tables.append((header, current))
        elif current is not None:
            try:
                values = [float(w) for w in words]
            except ValueError:
                current = None
                continue
            if len(values) == len(header):
                current.append(values)
            else:
                current = None
    if not tables:
        return pd.DataFrame()
    return pd.concat([pd.DataFrame(rows, columns=header) for header, rows in tables[-runs:]], ignore_index=True)


def loop_times(log: Path) -> list[tuple[float, int]]:
    """(seconds, steps) of every ``run`` in a LAMMPS log, from its "Loop time of ..." lines."""
    out = []
    for line in Path(log).read_text().splitlines():
        if line.startswith("Loop time of "):
            words = line.split()
            out.append((float(words[3]), int(words[8])))
    return out


def version(log: Path) -> str:
    """The LAMMPS version from the first line of a log file, e.g. '29 Sep 2021 - Update 2'."""
    first = Path(log).read_text().split("\n", 1)[0]
    match = re.search(r"LAMMPS \((.*)\)", first)
    return match.group(1) if match else "unknown"


def error_message(log: Path, stderr: str = "") -> str:
    """The ERROR line LAMMPS printed, if any."""
    text = (Path(log).read_text() if Path(log).is_file() else "") + "\n" + stderr
    errors = [line.strip() for line in text.splitlines() if "ERROR" in line]
    return errors[-1] if errors else ""


def last_step(log: Path) -> int:
    """The last timestep printed in the thermo output (0 if none)."""
    table = read_thermo(log) if Path(log).is_file() else pd.DataFrame()
    return int(table["Step"].iloc[-1]) if len(table) else 0
