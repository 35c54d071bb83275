"""What a `graphdem` subcommand reads and writes, declared where its options are added, and the check that none
of its outputs is one of its inputs.

Every option whose value is a path takes one of the argparse types below instead of ``Path`` (tests/test_cli.py
fails on a path option without one), so the declaration sits in the ``add_argument`` call:

* :data:`input_path`: a file it reads, or a folder whose files it reads (those in it and in its subfolders);
* :data:`split_table`: a split table it reads; the sims its ``path`` column names are read too;
* :data:`output_file`: a file it writes;
* :data:`output_folder`: a folder it writes files into;
* :func:`replaced_folder`: a folder it writes whole, replacing the one there (a previous output holds ``marker``);
* :data:`output_series`: a ParaView ``NAME.pvd`` and the folder ``NAME/`` of its frames, replaced whole.

:func:`check` runs before the subcommand. It compares resolved paths (symlinks and ``..`` followed) and refuses,
naming both options, an output that is an input, a file in an input folder or a sim of an input split table, and
a folder output that holds any of those; it also refuses two outputs at one path, a file output that is an
existing folder, a folder output that is an existing file, and a folder written whole that exists and is not
this command's previous output (it would be deleted).
"""

from __future__ import annotations

import argparse
import csv
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from generators.record import RUN_FILE

SPLIT_PATH_COLUMN = "path"          # the column of a split table that names its sims (surrogate/dataset.py)
SERIES_FRAMES = ".vtu"              # the suffix of a ParaView series' frame files (generators/export.py)
#: how deep below a folder it is given a subcommand reads: files in it and in its subfolders (property-sensitivity's
#: --runs LOW: LOW/sims/<id>.h5; import-solidgn's SRC: SRC/train/<n>.pkl); deeper files are not compared, so that
#: the check costs no more than a listing of what the command reads
READ_DEPTH = 2


@dataclass(frozen=True)
class PathType:
    """An argparse type for a path option that says what the subcommand does with the path."""

    name: str                       # in words, for argparse's messages
    writes: bool = False            # an output (else an input)
    folder: bool = False            # output: a folder (else a file)
    table: bool = False             # input: a split table whose path column names sims
    marker: str | None = None       # output folder written whole: a file its previous version holds
    series: bool = False            # output: NAME.pvd and the folder NAME/ of its frames, written whole

    def __call__(self, text: str) -> Path:
        return Path(text)

    def __repr__(self) -> str:
        return self.name


input_path = PathType("input file or folder")
split_table = PathType("split table", table=True)
output_file = PathType("output file", writes=True)
output_folder = PathType("output folder", writes=True, folder=True)
output_series = PathType("ParaView series", writes=True, series=True)


def replaced_folder(marker: str) -> PathType:
    """An output folder the subcommand writes whole: an existing one is replaced, so it must be a previous output
    (one holding ``marker``) or empty."""
    return PathType(f"output folder holding {marker}", writes=True, folder=True, marker=marker)


run_folder = replaced_folder(RUN_FILE)      # prepare's and simulate's: the engine's output and its run.json


@dataclass(frozen=True)
class Use:
    """A path the command reads or writes: the option that gives it (as the user typed it), the value given,
    the resolved path, and, for a path it reaches through that value, in words how."""

    option: str
    given: Path
    path: Path
    via: str = ""
    folder: bool = False
    kind: PathType | None = None


def option_name(action: argparse.Action) -> str:
    """How `graphdem X --help` names the option: its longest flag, or a positional's metavar or name."""
    if action.option_strings:
        return max(action.option_strings, key=len)
    return str(action.metavar or action.dest.upper())


def declared(parser: argparse.ArgumentParser) -> list[tuple[argparse.Action, PathType]]:
    """The path options of a subcommand's parser and their declared types."""
    return [(a, a.type) for a in parser._actions if isinstance(a.type, PathType)]


def _values(value) -> list[Path]:
    items = value if isinstance(value, list | tuple) else [value]
    return [Path(v) for v in items if isinstance(v, Path)]


def _resolved(path: Path) -> Path:
    return Path(os.path.realpath(path))


def _writes(option: str, given: Path, kind: PathType) -> list[Use]:
    out = Use(option, given, _resolved(given), folder=kind.folder, kind=kind)
    if not kind.series or given.suffix != ".pvd":
        return [out]
    frames = given.with_suffix("")
    return [out, Use(option, given, _resolved(frames), f"its frames folder {frames}", True, kind)]


def _in_folder(use: Use) -> Iterator[Use]:
    """The files in an input folder and in its subfolders (:data:`READ_DEPTH`), each resolved (a symlink counts as
    its target)."""
    for top, dirs, files in os.walk(use.given):
        if len(Path(top).relative_to(use.given).parts) + 1 >= READ_DEPTH:
            dirs.clear()
        for name in files:
            inside = Path(top) / name
            yield Use(use.option, use.given, _resolved(inside), f"{inside} in that folder")


def _listed_sims(use: Use) -> Iterator[Use]:
    """The sims a split table's path column names (resolved as the stages read them, from the working folder);
    nothing where the table cannot be read as CSV (the command itself says why)."""
    try:
        with open(use.path, newline="", encoding="utf-8") as handle:
            rows = csv.reader(handle)
            header = next(rows, [])
            if SPLIT_PATH_COLUMN not in header:
                return
            column = header.index(SPLIT_PATH_COLUMN)
            for row in rows:
                if len(row) > column and row[column]:
                    yield Use(use.option, use.given, _resolved(Path(row[column])), f"the sim {row[column]} it lists")
    except (OSError, UnicodeDecodeError, csv.Error):
        return


def _reads(option: str, given: Path, kind: PathType) -> Iterator[Use]:
    use = Use(option, given, _resolved(given))
    yield use
    if use.path.is_dir():
        yield from _in_folder(use)
    elif kind.table and use.path.is_file():
        yield from _listed_sims(use)


def _refuse(command: str, text: str) -> None:
    raise SystemExit(f"graphdem {command}: {text}")


def _check_kind(command: str, out: Use) -> None:
    """A file output may not be an existing folder, a folder output not an existing file, and a folder written
    whole only a previous output of the command (or an empty folder)."""
    where = f"{out.option} {out.given}" + (f": {out.via}," if out.via else "")
    if not out.folder and out.path.is_dir():
        _refuse(command, f"{where} is an existing folder; a file is written there and the folder would be deleted: "
                         "give a file path")
    if out.folder and out.path.exists() and not out.path.is_dir():
        _refuse(command, f"{where} is an existing file; a folder is written there: give a folder path")
    if out.folder and out.path.is_dir() and (out.kind.series or out.kind.marker):
        try:
            held = list(out.path.iterdir())
        except OSError:
            held = [out.path]                       # cannot be listed: not known to be a previous output
        own = (all(p.is_file() and p.suffix == SERIES_FRAMES for p in held) if out.kind.series
               else (out.path / out.kind.marker).is_file())
        if held and not own:
            what = f"{SERIES_FRAMES} frames only" if out.kind.series else out.kind.marker
            _refuse(command, f"{where} is an existing folder that is not a previous output of this command (it "
                             f"would hold {what}); it would be replaced whole: give a new path")


def _collision(out: Use, read: Use) -> bool:
    if read.path == out.path:
        return True
    return out.folder and out.path in read.path.parents


def check(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse, before anything is read or written, a subcommand whose outputs (the options of ``parser`` declared
    as outputs) meet what it reads or each other (module docstring)."""
    outputs: list[Use] = []
    inputs: list[tuple[str, Path, PathType]] = []
    for action, kind in declared(parser):
        for given in _values(getattr(args, action.dest, None)):
            if kind.writes:
                outputs.extend(_writes(option_name(action), given, kind))
            else:
                inputs.append((option_name(action), given, kind))
    if not outputs:
        return
    for option, given, kind in inputs:
        for read in _reads(option, given, kind):
            for out in outputs:
                if _collision(out, read):
                    _refuse(args.command, _overwrite(out, read))
    for i, out in enumerate(outputs):
        for other in outputs[:i]:
            if other.path == out.path:
                _refuse(args.command, f"{out.option} {out.given} and {other.option} {other.given} are one path; "
                                      "each output needs its own")
        _check_kind(args.command, out)


def _overwrite(out: Use, read: Use) -> str:
    written = f"{out.option} {out.given}" + (f" ({out.via})" if out.via else "")
    held = " (held in that output folder)" if read.path != out.path else ""
    through = f" ({read.via})" if read.via else ""
    return (f"{written} would overwrite the input {read.option} {read.given}{through}{held}; write the output "
            "elsewhere")
