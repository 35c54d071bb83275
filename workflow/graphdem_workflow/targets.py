"""A target no rule makes (a misspelt scene, stage or file name) is refused before the DAG is built, with the
closest targets the workflow does make and the main target of each scene, benchmark and user-data set, instead of
Snakemake's bare MissingRuleException."""

from __future__ import annotations

import difflib
import itertools
import re
import sys
from pathlib import Path

#: a wildcard in an output pattern, ``{name}`` or ``{name,regex}``
WILDCARD = re.compile(r"\{([A-Za-z_]\w*)(?:,[^{}]*)?\}")


def unmade(targets, rules) -> list[str]:
    """The ``targets`` (files or rule names) that are neither a rule's name nor a file some rule makes (outputs,
    logs and benchmarks, as Snakemake matches them, under the global wildcard constraints)."""
    names = {rule.name for rule in rules}
    return sorted(t for t in targets if t not in names and not any(rule.is_producer(t) for rule in rules))


def concrete(rules, values: dict[str, list[str]]) -> list[str]:
    """Every output of ``rules`` whose wildcards are all keys of ``values``, filled with each of their values
    (e.g. results/{name}/metrics.csv for every scene and benchmark)."""
    found = set()
    for rule in rules:
        for pattern in map(str, rule.output):
            keys = sorted(set(WILDCARD.findall(pattern)))
            if not all(k in values for k in keys):
                continue
            for combo in itertools.product(*(values[k] for k in keys)):
                fill = dict(zip(keys, combo, strict=True))
                found.add(WILDCARD.sub(lambda m, fill=fill: fill[m.group(1)], pattern))
    return sorted(found)


def message(missing: list[str], known: list[str], names: list[str]) -> str:
    """The refusal: each target no rule makes with its closest known targets, then the main ones."""
    lines = []
    for target in missing:
        close = difflib.get_close_matches(target, known, n=3, cutoff=0.6)
        hint = f"; did you mean {' or '.join(close)}?" if close else ""
        lines.append(f"graphdem: no rule makes {target!r}{hint}")
    lines.append("the main targets: " + ", ".join(f"results/{n}/metrics.csv" for n in names)
                 + "; rules: all, benchmarks (docs/workflow.md lists every stage's outputs)")
    return "\n".join(lines)


def command_line_targets(workflow, argv: list[str] | None = None) -> list[str]:
    """The targets the run was asked for: Snakemake's DAG settings where they are set when the Snakefile is read,
    else the positional targets of the ``snakemake`` command line (``argv``, default sys.argv) read by Snakemake's
    own argument parser; none when the Snakefile is read by anything else (the API, a test)."""
    settings = getattr(workflow, "dag_settings", None)
    if settings is not None and settings.targets:
        return sorted(settings.targets)
    argv = sys.argv if argv is None else argv
    if not argv or "snakemake" not in (Path(argv[0]).name, Path(argv[0]).parent.name):   # bin/snakemake, -m snakemake
        return []
    from snakemake.cli import get_argument_parser
    try:
        parsed, _ = get_argument_parser().parse_known_args(argv[1:])
    except SystemExit:                      # Snakemake reports its own usage errors
        return []
    return sorted(parsed.targets or [])


def check(workflow, values: dict[str, list[str]], names: list[str]) -> None:
    """Exit with :func:`message` when a command-line target of ``workflow`` is made by no rule; ``values`` fill
    the wildcards of the candidates, ``names`` are the results folders (scenes, benchmarks, user-data sets)."""
    if len(getattr(workflow, "modifier_stack", ())) > 1:
        return          # read as a module of another workflow: its own rules, defined later, may make the targets
    targets = command_line_targets(workflow)
    rules = list(workflow.rules)
    missing = unmade(targets, rules)
    if missing:
        raise SystemExit(message(missing, concrete(rules, values), names))
