"""User data (docs/user-data.md): any folder of H5MD sims (generators/h5md.py), trained on and scored by the
workflow's shared stages under a results name of its own, with the config's ``user`` section.

The config key ``user_data`` maps a results name to a folder; a plain path is one folder, named by its basename.
When the config is read, each entry is checked (:func:`check`): the name is a results folder of its own (letters,
digits, ``_``, ``.``, ``-``; not a scene's, a public benchmark's or ``crosscheck``), the folder exists and holds
``*.h5`` files whose names are sim ids of the same alphabet, and enough of them that the split leaves every split
(train, valid, test) a sim. Nothing is read from the files here: the dataset stage reads them.

The split (:func:`split_table`): the folder's sims sorted by file name, labelled by the sweep's seeded rule
(:func:`generators.sweep.split_labels`, with ``user.split`` and ``user.seed``), so the same folder and settings
always give the same table, and a scene's sweep and a user-data set are split alike.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pandas as pd

from generators import sweep
from generators.errors import ConfigError

#: a results name and a sim id (a file's name without ``.h5``): a folder and a file name, one shell word
NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
SUFFIX = ".h5"
#: results folders of the workflow's own that are no scene's or benchmark's (the cross-check's runs)
RESERVED = ("crosscheck",)


def sim_files(folder: str | Path) -> list[Path]:
    """The sims of ``folder``: its ``*.h5`` files sorted by name, hidden ones (a writer's temporaries) left out,
    each as ``folder``/<file> (a relative folder stays relative)."""
    folder = Path(folder)
    return sorted(p for p in folder.glob(f"*{SUFFIX}") if p.is_file() and not p.name.startswith("."))


def normalise(value: str | dict) -> dict[str, str]:
    """``user_data`` as a mapping of results name -> folder: a plain path is one folder named by its basename."""
    if isinstance(value, str):
        return {Path(os.path.abspath(value)).name: value}
    return dict(value)


def check(value: str | dict, taken: list[str], fractions: list[float]) -> dict[str, str]:
    """The normalised ``user_data`` (:func:`normalise`), each entry checked (module docstring) against the results
    names ``taken`` (scenes and public benchmarks) and the split ``fractions``; raise ConfigError naming the entry."""
    out = normalise(value)
    for name, folder in out.items():
        key = f"user_data.{name}" if isinstance(value, dict) else "user_data"
        if not NAME.match(name):
            raise ConfigError(f"config key {key!r}: {name!r} is not a results name; allowed: letters, digits, _, . and "
                              f"- (not first); name the folder with --config user_data='{{NAME: {folder}}}'")
        if name in (*taken, *RESERVED):
            raise ConfigError(f"config key {key!r}: the name {name!r} is taken by the workflow's "
                              f"results/{name}/; allowed: any other name, e.g. --config user_data='{{my_{name}: "
                              f"{folder}}}' (taken: {', '.join([*taken, *RESERVED])})")
        _check_folder(key, folder, fractions)
    return out


def _check_folder(key: str, folder: str, fractions: list[float]) -> None:
    """The folder exists, its sims have usable ids and every split gets one of them."""
    if not Path(folder).is_dir():
        raise ConfigError(f"config key {key!r} = {folder!r}: no such folder (a relative path is taken from the "
                          f"working directory, {os.getcwd()}); allowed: a folder of H5MD sims (*{SUFFIX})")
    files = sim_files(folder)
    if not files:
        raise ConfigError(f"config key {key!r} = {folder!r}: the folder holds no *{SUFFIX} file; allowed: a folder of "
                          f"H5MD sims (generators/h5md.py; docs/user-data.md)")
    bad = [p.name for p in files if not NAME.match(p.stem)]
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise ConfigError(f"config key {key!r} = {folder!r}: the file name {bad[0]!r}{more} is no usable sim id; "
                          f"allowed file names: letters, digits, _, . and - (not first), then {SUFFIX}")
    _check_split(f"config key {key!r} = {folder!r}", len(files), fractions, "'user.split' = ")


def _check_split(where: str, n: int, fractions: list[float], named: str = "") -> None:
    """The ``fractions`` are a split (three, none negative, summing to 1) that gives each split one of ``n`` sims by
    the sweep's rule (generators/sweep.py, split_counts); raise ConfigError starting with ``where``."""
    if len(fractions) != 3 or min(fractions) < 0 or abs(sum(fractions) - 1.0) > 1e-6:
        raise ConfigError(f"{where}: the split {named}{list(fractions)} is not allowed; allowed: three fractions "
                          f"(train, valid, test), none negative, summing to 1")
    counts = dict(zip(sweep.SPLITS, sweep.split_counts(n, fractions), strict=True))
    empty = [split for split, count in counts.items() if count < 1]
    if empty:
        raise ConfigError(f"{where}: its {n} sims split by {named}{list(fractions)} leave the {' and '.join(empty)} "
                          f"split empty ({counts}); every split needs a sim: give each split a fraction > 0 and the "
                          f"folder at least 3 sims")


def split_table(folder: str | Path, fractions: list[float], seed: int) -> pd.DataFrame:
    """The split table (id, split, path) of the sims of ``folder`` (module docstring); raise ConfigError where the
    folder holds no sim or the split leaves a split empty."""
    if not Path(folder).is_dir():
        raise ConfigError(f"{folder}: no such folder; allowed: a folder of H5MD sims (*{SUFFIX})")
    files = sim_files(folder)
    if not files:
        raise ConfigError(f"{folder}: no *{SUFFIX} file in this folder; allowed: a folder of H5MD sims")
    _check_split(str(folder), len(files), fractions)
    labels = sweep.split_labels(len(files), fractions, seed)
    return pd.DataFrame({"id": [p.stem for p in files], "split": labels, "path": [str(p) for p in files]})
