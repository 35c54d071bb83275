"""The engine registry: every DEM engine the project runs, one name a line in :data:`NAMES`.

An engine is the package ``generators/<name>/``; its module ``generators/<name>/driver.py`` runs any
engine-neutral Setup (generators/dem.py) whose features it supports and refuses the others by name
(docs/architecture.md, "Adding an engine"). Every choice of engine the project offers is read from here:
the `graphdem` options (``--engine``, ``--engines``, ``--trained-on``, ``--other-engine`` and the cross-check's
one option per engine), the config schema's ``engine`` enum (filled in by generators/config.py), each scene's
engines (generators/scene.py), the workflow's engine wildcard and cross-check runs (workflow/rules/common.smk).

What a driver module provides:

- ``settle(setup, workdir, ranks=1, threads=1)`` -> (dem.Particles, record.EngineRun);
- ``run_recording(setup, workdir, ranks=1, threads=1)`` -> (dem.Frames, record.EngineRun);
- ``read_raw(raw_dir, dt)`` -> the run folder's frames again (generators/convert.py);
- ``CONTACT_MODEL``: the contact law's description in every sim's run record;
- ``PARALLEL``: how the engine takes more cores, ``"ranks"`` (MPI ranks, the scene's ``ranks`` key) or
  ``"threads"`` (threads of one process);
- ``ERRORS``: its own exception classes, which `graphdem` reports as one line;
- with ``PARALLEL = "ranks"``: ``ranks_problem(ranks)``, why ``ranks`` ranks cannot run on this host (None
  where they can), checked when the config is read.
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: the registered engines; an engine is added by one line here and its package generators/<name>/
NAMES: tuple[str, ...] = (
    "lammps",
    "yade",
)
PARALLEL_KINDS = ("ranks", "threads")


def names() -> list[str]:
    """The registered engines' names, in registry order."""
    return list(NAMES)


def driver(name: str) -> ModuleType:
    """The driver module of engine ``name`` (settle, run_recording, read_raw, CONTACT_MODEL, PARALLEL, ERRORS)."""
    if name not in NAMES:
        raise ValueError(f"unknown engine {name!r}; known: {', '.join(NAMES)}")
    return importlib.import_module(f"generators.{name}.driver")


def takes_ranks(name: str) -> bool:
    """Whether engine ``name`` takes more cores as MPI ranks (else as threads of one process)."""
    kind = driver(name).PARALLEL
    if kind not in PARALLEL_KINDS:
        raise ValueError(f"the {name} driver's PARALLEL = {kind!r}; allowed: {', '.join(PARALLEL_KINDS)}")
    return kind == "ranks"


def execution(name: str, cores: int) -> tuple[int, int]:
    """(MPI ranks, threads per process) of a run of engine ``name`` on ``cores`` cores."""
    return (cores, 1) if takes_ranks(name) else (1, cores)


def ranks_problem(ranks: int) -> str | None:
    """Why ``ranks`` MPI ranks cannot run on this host, from the first engine taking ranks that refuses them
    (the scene's ``ranks`` key serves every such engine's runs); None where they can."""
    if ranks == 1:
        return None
    for name in NAMES:
        if takes_ranks(name):
            problem = driver(name).ranks_problem(ranks)
            if problem:
                return problem
    return None


def errors() -> tuple[type[Exception], ...]:
    """Every registered driver's own exception classes."""
    return tuple(error for name in NAMES for error in driver(name).ERRORS)
