"""`graphdem tables`: every results table of the README and the docs written by one command from the results CSVs,
stamped with where its numbers come from, and checked for code that changed since (docs/tables.md).

* :mod:`evaluation.doc_tables.blocks`: the markers ``<!-- table: NAME -->`` ... ``<!-- /table: NAME -->`` in a
  markdown file and the stamp line that opens each block;
* :mod:`evaluation.doc_tables.kinds`: the kinds of table (metrics, speed, card), each a function from a CSV to a
  markdown table and the list of source files that produce the CSV;
* here: what a run finds (:func:`plan`), writes (:func:`write`) and checks (:func:`check`), and the subcommand.

Staleness: a stamp holds the hash of its kind's producing files as they were when the table was generated from a
new CSV. ``--check`` recomputes it from the files as they are now; a difference means the numbers were made by
code that has changed since. ``--write`` never launders that: where the CSV is the same as at the last stamp
(its ``data`` hash), the old code hash is kept, and the table stays stale until the stage is rerun.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from evaluation.doc_tables import blocks
from evaluation.doc_tables.blocks import Block, MarkerError, Stamp
from evaluation.doc_tables.kinds import KINDS, Kind
from generators.atomic import atomic_path
from generators.cli_paths import input_path

__all__ = ["DOCUMENTS", "Outcome", "check", "code_hash", "documents", "plan", "write", "add_command"]

# The markdown files whose tables are generated, as glob patterns under the root (the repository).
DOCUMENTS = ("*.md", "docs/**/*.md", "surrogate/pretrained/*.md")   # the last: the pretrained models' cards
RESULTS = "results"                 # the results folder under the root
CODE_ROOT = Path(__file__).resolve().parents[2]     # holds the packages generators/, surrogate/, evaluation/
DIGITS = 12                         # hex digits of the stamp's hashes


@dataclass(frozen=True)
class Outcome:
    """What a run does to one block: its new body (None: its CSV is missing, the block is left as it is),
    whether that differs from the present one, and whether its code hash is still not the current one."""

    block: Block
    csv: Path
    body: str | None
    changed: bool = False
    stale: bool = False


def documents(root: Path, files: list[Path] | None = None) -> list[Path]:
    """The markdown files to look at: ``files`` where given, else :data:`DOCUMENTS` under ``root``."""
    if files:
        return [Path(f) for f in files]
    return sorted({p for pattern in DOCUMENTS for p in Path(root).glob(pattern) if p.is_file()})


def read_blocks(paths: list[Path]) -> dict[Path, tuple[str, list[Block]]]:
    """Each file's text and blocks (a file that does not exist is named)."""
    found = {}
    for path in paths:
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such markdown file")
        text = path.read_bytes().decode("utf-8")
        found[path] = (text, blocks.find(path, text))
    return found


def kind_of(block: Block, kinds: Mapping[str, Kind]) -> tuple[Kind, str]:
    """The kind and subject of a block's name ``<subject>-<kind>``; an unknown kind is named with the known."""
    subject, _, name = block.name.rpartition("-")
    if name not in kinds:
        raise MarkerError(f"{block.where}: table {block.name}: unknown kind {name!r}; known kinds: "
                          f"{', '.join(sorted(kinds))}")
    return kinds[name], subject


def code_hash(kind: Kind, code_root: Path = CODE_ROOT, subject: str = "") -> str:
    """A short SHA-256 of the kind's producing files (their paths under ``code_root`` and their bytes, in path
    order; ``{subject}`` in a pattern is the table's subject, e.g. a scene's own module). A pattern that matches
    no file is refused: the registry names a file that is gone."""
    digest = hashlib.sha256()
    files: set[Path] = set()
    for pattern in (p.format(subject=subject) for p in kind.sources):
        matched = [p for p in Path(code_root).glob(pattern) if p.is_file()]
        if not matched:
            raise FileNotFoundError(f"the {kind.name} table's producing files {pattern!r} match nothing under "
                                    f"{code_root} (evaluation/doc_tables/kinds.py names them)")
        files.update(matched)
    for path in sorted(files, key=lambda p: p.relative_to(code_root).as_posix()):
        digest.update(path.relative_to(code_root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:DIGITS]


def _shown(path: Path, root: Path) -> str:
    """``path`` relative to ``root`` where it lies under it (as the stamp names it)."""
    try:
        return Path(path).resolve().relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return Path(path).as_posix()


def provenance(table, csv: Path, root: Path, code: str, previous: Stamp | None) -> Stamp:
    """The stamp of a table generated now from ``csv`` (named relative to ``root``, the folder that holds the
    results folder, so that a table written from a run in another folder names ``results/<name>/...``): its data
    hash, recorded commit and config, the code hash
    (the previous stamp's where the CSV is unchanged since: its numbers are still that code's), machine, date."""
    import datetime

    import torch

    from evaluation import evaluate
    from surrogate import devices

    def recorded(column: str) -> str:
        """The CSV's distinct values of ``column`` joined by '+' (a code_version's commit part); '' where none."""
        values = table[column].dropna().astype(str).unique() if column in table else []
        return "+".join(dict.fromkeys(v.rpartition("+")[2] if column == "code_version" else v for v in values))

    data = hashlib.sha256(Path(csv).read_bytes()).hexdigest()[:DIGITS]
    if previous is not None and previous.data == data:
        code = previous.code
    commit = recorded("code_version") or evaluate.code_version().rpartition("+")[2] + blocks.HEAD
    return Stamp(_shown(csv, root), data, commit, recorded("config_sha") or blocks.NOT_RECORDED, code,
                 devices.name(torch.device("cpu")), datetime.datetime.now(datetime.UTC).date().isoformat())


def regenerate(block: Block, root: Path, results: Path, kinds: Mapping[str, Kind], code_root: Path) -> Outcome:
    """The block's new body from its CSV; unchanged (the same bytes) where only the machine or date would be."""
    from evaluation.tables import read_csv
    kind, subject = kind_of(block, kinds)
    csv = Path(results) / kind.csv.format(subject=subject)
    if not csv.is_file():
        return Outcome(block, csv, None)
    table = read_csv(csv)
    missing = [c for c in kind.columns if c not in table.columns]
    if missing:
        raise ValueError(f"{csv}: lacks the columns {missing} that the {kind.name} table {block.name} "
                         f"({block.where}) needs")
    previous, old_table = blocks.split_body(block.body)
    current = code_hash(kind, code_root, subject)
    stamp = provenance(table, csv, Path(results).parent, current, previous)
    text = kind.render(table)
    same = previous is not None and previous.key() == stamp.key() and old_table == text.strip()
    body = block.body if same else blocks.body(stamp, text)
    return Outcome(block, csv, body, changed=not same, stale=stamp.code != current)


def plan(root: Path, files: list[Path] | None = None, results: Path | None = None,
         kinds: Mapping[str, Kind] = KINDS, code_root: Path = CODE_ROOT) -> list[Outcome]:
    """What ``--write`` would do to every block of the documents, without writing."""
    results = Path(root) / RESULTS if results is None else Path(results)
    return [regenerate(b, Path(root), results, kinds, code_root)
            for _, found in read_blocks(documents(root, files)).values() for b in found]


def write(outcomes: list[Outcome]) -> list[Path]:
    """Write the changed blocks into their files (atomically, each file once); return the files written."""
    written = []
    for path in dict.fromkeys(o.block.document for o in outcomes if o.changed):
        text = path.read_bytes().decode("utf-8")
        bodies = {o.block: o.body for o in outcomes if o.changed and o.block.document == path}
        for block in bodies:
            if text[block.start:block.end] != block.body:
                raise ValueError(f"{block.where}: the file changed while its tables were generated; run graphdem "
                                 "tables --write again")
        with atomic_path(path) as tmp:
            tmp.write_bytes(blocks.replace(text, bodies).encode("utf-8"))
        written.append(path)
    return written


def check(root: Path, files: list[Path] | None = None, kinds: Mapping[str, Kind] = KINDS,
          code_root: Path = CODE_ROOT) -> tuple[list[str], list[str]]:
    """Lines of the stale tables (a stamp whose code hash differs from the producing files' now) and of the
    never generated ones (no stamp); reads no results."""
    stale, never, hashes = [], [], {}
    for _, found in read_blocks(documents(root, files)).values():
        for block in found:
            kind, subject = kind_of(block, kinds)
            if (kind.name, subject) not in hashes:
                hashes[kind.name, subject] = code_hash(kind, code_root, subject)
            now = hashes[kind.name, subject]
            stamp, _ = blocks.split_body(block.body)
            if stamp is None:
                never.append(f"{block.where}: {block.name}: never generated (no stamp); graphdem tables --write "
                             f"fills it from {RESULTS}/{kind.csv.format(subject=subject)}")
            elif stamp.code != now:
                stale.append(f"{block.where}: {block.name}: stale: the code that produces {stamp.source} changed "
                             f"(stamp code {stamp.code}, now {now}); rerun its stage, then "
                             "graphdem tables --write")
    return stale, never


def run(args: argparse.Namespace) -> None:
    """``graphdem tables``: print what would change, or --write it, or --check the stamps (exit 1: stale)."""
    root = Path(args.root)
    if args.check:
        stale, never = check(root, args.files, KINDS, CODE_ROOT)
        for line in never:
            print(f"warning: {line}", file=sys.stderr)
        for line in stale:
            print(line)
        if stale:
            raise SystemExit(1)
        return
    outcomes = plan(root, args.files, args.results, KINDS, CODE_ROOT)
    for o in outcomes:
        if o.body is None:
            print(f"not regenerated: {o.block.where}: {o.block.name}: {_shown(o.csv, root)} missing")
        elif o.stale:
            print(f"stale: {o.block.where}: {o.block.name}: {_shown(o.csv, root)} is unchanged since the code that "
                  "produces it changed; rerun its stage")
        if o.changed:
            print(f"{'written' if args.write else 'would change'}: {o.block.where}: {o.block.name}")
    if args.write:
        write(outcomes)


DESCRIPTION = """\
Every results table of the README and the docs is written by this command from the results CSVs, never by hand.
A generated table lives between two marker lines in any markdown file (README.md, docs/**/*.md):

  <!-- table: NAME -->
  ... (written by graphdem tables --write; everything outside the markers is kept byte for byte)
  <!-- /table: NAME -->

NAME is <subject>-<kind>: the table of that kind from results/<subject>/ (e.g. slide-metrics):
  metrics   results/<scene>/metrics.csv: a row per metric (MSE, the article's Acc, and skill, change error and
            errors in ensemble spreads where the CSV has them; intervals as 0.58 [0.41, 0.77]), a column per method
  speed     results/<scene>/performance.csv: a row per contender: ms per frame, rollout MSE, speed-up over the DEM
  map       results/<scene>/performance_map.csv: per test sim, the surrogate's speed-up, DEM sub-steps, break-even
  pays      results/performance_pays.csv (any subject, e.g. scenes-pays): a row per scene: pays or not, by how much, why
  card      results/<benchmark>/card.csv: a row per quantity and K, mean ± std over the seeds, the article's beside

The first line of a block is its stamp: the CSV, a hash of its bytes (data), the commit and config hash it
records (commit ... (HEAD): the CSV records none, the checkout's HEAD at generation), a hash of the source files
that produce the CSV (code), the machine and the date it was generated on.

Modes:
  (no flag)  print the tables that --write would change, and those whose CSV is missing
  --write    regenerate every table whose CSV exists; a missing CSV leaves its table as it is ("not
             regenerated: results/... missing"); a table whose numbers and stamp would stay the same is not touched
  --check    read no results: list the tables whose stamp's code hash differs from the producing files' now
             (stale: exit status 1) and, on stderr as warnings, those never generated (no stamp; exit status 0).
             Prints nothing when every table is current. Run it in CI and before a commit.

A table stays stale until its CSV is made again: --write keeps the old code hash while the CSV is the same one
(docs/tables.md)."""


def add_command(sub: argparse._SubParsersAction) -> None:
    """Register ``graphdem tables`` on the subcommand parsers ``sub``."""
    p = sub.add_parser("tables", help="write the README's and docs' results tables from the results CSVs, or check "
                                      "their stamps", description=DESCRIPTION,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("files", type=input_path, nargs="*",
                   help=f"markdown files to look at (default: {', '.join(DOCUMENTS)} under --root)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--write", action="store_true", help="regenerate the tables whose CSV exists")
    mode.add_argument("--check", action="store_true",
                      help="list the tables whose producing code changed since their stamp (exit 1), reading no "
                           "results")
    p.add_argument("--root", type=input_path, default=Path("."),
                   help="the repository: where the markdown files and the results folder are (default: .)")
    p.add_argument("--results", type=input_path, help=f"the results folder (default: ROOT/{RESULTS})")
    p.set_defaults(func=run)
