"""The model configuration an evaluation scored, in a sidecar file beside its table, content-addressed.

metrics.csv (and metrics_per_step.csv) name the configuration of the model they score by ``config_sha`` only; the
configuration itself is written once, beside the table: ``metrics.config.json`` beside ``metrics.csv`` (in general
``<stem>.config.json`` beside ``<stem>.csv``). The rule:

* the configuration is the checkpoint's ``model``, ``train`` and ``stats`` sections (an ensemble of checkpoints: a
  list of them, one per model, in the order given) -- what :func:`surrogate.ensemble.config_digest` hashes;
* its canonical JSON is ``json.dumps(config, sort_keys=True)`` (keys sorted, Python's default separators
  ``", "`` and ``": "``, non-ASCII as ``\\u`` escapes, no trailing newline), encoded as UTF-8;
* ``config_sha`` is the first 12 hex digits of the SHA-256 of that text, and the sidecar holds exactly that text,
  so ``sha256sum metrics.config.json`` starts with the ``config_sha`` of every row;
* a reader parses the sidecar, re-canonicalises it and checks the digest against the table's ``config_sha``
  (:func:`read`): a sidecar of another model, or edited, is refused by name.

The sidecar is written in the same :func:`generators.atomic.atomic_outputs` group as the table, so the two appear
together or not at all.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from generators.atomic import Outputs, atomic_path

__all__ = ["DIGITS", "SUFFIX", "canonical", "carry", "config_of", "digest", "path_of", "read", "write"]

SUFFIX = ".config.json"
DIGITS = 12                     # hex digits of config_sha
SECTIONS = ("model", "train", "stats")


def path_of(table: str | Path) -> Path:
    """The sidecar of the table ``table``: ``metrics.csv`` -> ``metrics.config.json`` beside it."""
    table = Path(table)
    return table.with_name(table.stem + SUFFIX)


def config_of(metas: list[dict]) -> object:
    """The configuration of the checkpoints whose metadata are ``metas``: the model, train and stats sections of
    one, or the list of them of several; plain JSON (a JSON round trip, so that it reads back as written)."""
    sections = [{k: meta[k] for k in SECTIONS} for meta in metas]
    return json.loads(json.dumps(sections[0] if len(sections) == 1 else sections))


def canonical(config: object) -> str:
    """The canonical JSON text of ``config`` (module docstring)."""
    return json.dumps(config, sort_keys=True)


def digest(config: object) -> str:
    """``config_sha`` of ``config``: the first :data:`DIGITS` hex digits of the SHA-256 of its canonical JSON."""
    return hashlib.sha256(canonical(config).encode("utf-8")).hexdigest()[:DIGITS]


def write(table: str | Path, config: object, output: Outputs | None = None) -> str:
    """Write ``config`` as the sidecar of ``table`` (staged in ``output``, else atomically on its own); returns
    its ``config_sha``."""
    if output is None:
        with atomic_path(path_of(table)) as tmp:
            tmp.write_text(canonical(config), encoding="utf-8")
    else:
        with output(path_of(table)) as tmp:
            tmp.write_text(canonical(config), encoding="utf-8")
    return digest(config)


def read(table: str | Path, config_sha: str) -> object:
    """The configuration in ``table``'s sidecar, checked to be the one whose digest is ``config_sha``."""
    path = path_of(table)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file; the config of {Path(table).name} (config_sha {config_sha}) "
                                "is written beside it by graphdem evaluate")
    try:
        config = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a JSON config sidecar ({exc})") from None
    found = digest(config)
    if found != str(config_sha):
        raise ValueError(f"{path}: holds the config {found}, not the config_sha {config_sha} of "
                         f"{Path(table).name}; rerun the evaluation that wrote them")
    return config


def carry(tables: list[Path], shas: list[str], out: Path) -> str:
    """The sidecar of a table ``out`` stacked from ``tables`` whose rows name the configs ``shas``: where they name
    one config and a table's sidecar holds it, that config is written beside ``out``; returns what was done, in
    words ('' where the tables name no config)."""
    shas = list(dict.fromkeys(str(s) for s in shas))
    if not shas:
        return ""
    if len(shas) > 1:
        return (f"the rows name {len(shas)} configs ({', '.join(shas)}): no sidecar beside {out}; each stays "
                f"beside its own table")
    for table in tables:
        if path_of(table).is_file():
            write(out, read(table, shas[0]))
            return f"config {shas[0]}: {path_of(out)}"
    return f"config {shas[0]}: no sidecar beside the tables given, none written beside {out}"
