"""Typed run records: what an engine run leaves beside its raw output (``run.json``), for convert,
the performance stage and the reader of a results folder.

Every driver reports an :class:`EngineRun`; :func:`generators.engine.prepare` and
:func:`generators.engine.simulate` wrap it into a :class:`PackingRecord` or a :class:`SimRecord`.
Reading checks every field and names the file and the field that is missing.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

RUN_FILE = "run.json"


class RecordError(ValueError):
    """A run record is missing, not JSON, or lacks a field; the message names the file."""


@dataclass(frozen=True)
class EngineRun:
    """One engine process: its command line, version and cost."""

    engine: str
    version: str
    command: str
    wall_time: float                     # s, the whole process
    max_rss_mb: float = float("nan")     # peak resident memory of the engine process
    window_seconds: float | None = None  # s, the engine's own timing of the recorded window
    runup_seconds: float | None = None   # s, the engine's own timing of the run-up before the first recorded frame
    threads: int = 1                     # threads per process (YADE's -j; LAMMPS runs one per MPI rank)
    steps: int = 0                       # DEM steps run
    ranks: int = 1                       # MPI ranks the engine ran on (LAMMPS under mpirun; 1: one process)
    notes: dict[str, Any] = field(default_factory=dict)   # engine-specific facts (e.g. YADE's closed servers)


@dataclass(frozen=True)
class PackingRecord:
    """A settled packing (prepare stage)."""

    scene: str
    params: dict
    run: EngineRun
    dt: float
    dt_limit: float
    settle_steps: int
    n_moving: int
    n_kinematic: int
    kind: str = "packing"


@dataclass(frozen=True)
class SimRecord:
    """A recorded simulation (simulate stage): everything convert needs besides the engine's frames."""

    scene: str
    params: dict                         # the sweep row
    run: EngineRun
    dt: float
    dt_limit: float
    steps_per_frame: int
    record_start_step: int
    n_steps: int
    window_steps: int                    # DEM steps of the recorded window (frames 1..T-1)
    frame_interval: float
    packing: str
    box_lower: list[float]
    box_upper: list[float]
    contact_model: str
    parameters: dict                     # scene parameters for the H5MD file (Scene.h5md_parameters)
    properties: dict                     # per-particle properties f_i (name -> value of every particle)
    log_scaled_properties: list[str]
    kinetic_energy: list[float] | None = None
    observables: dict[str, list[float]] = field(default_factory=dict)   # Scene.observables, per frame
    kind: str = "sim"

    @property
    def window_seconds(self) -> float | None:
        return self.run.window_seconds


def write(path: Path, record: PackingRecord | SimRecord) -> None:
    Path(path).write_text(json.dumps(dataclasses.asdict(record), indent=2))


def _build(cls, data: dict, where: str):
    names = {f.name for f in dataclasses.fields(cls)}
    required = {f.name for f in dataclasses.fields(cls)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    missing = sorted(required - set(data))
    if missing:
        raise RecordError(f"{where}: run record lacks the field(s) {missing}")
    values = {k: v for k, v in data.items() if k in names}
    if "run" in values:
        values["run"] = _build(EngineRun, values["run"], where + " (run)")
    return cls(**values)


def read(path: Path) -> PackingRecord | SimRecord:
    """The record in ``path`` (a run.json, or a folder holding one)."""
    path = Path(path)
    if path.is_dir():
        path = path / RUN_FILE
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise RecordError(f"{path}: no run record (a folder written by prepare or simulate holds {RUN_FILE})") from None
    except json.JSONDecodeError as exc:
        raise RecordError(f"{path}: run record is not valid JSON ({exc})") from None
    kinds = {"packing": PackingRecord, "sim": SimRecord}
    if not isinstance(data, dict) or data.get("kind") not in kinds:
        raise RecordError(f"{path}: run record has kind {data.get('kind') if isinstance(data, dict) else None!r}; "
                          f"allowed: {sorted(kinds)}")
    return _build(kinds[data["kind"]], data, str(path))
