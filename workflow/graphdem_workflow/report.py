"""The guard of ``snakemake --report``: a report is refused while its DAG has jobs that never ran.

Snakemake builds a report's DAG from the config the ``--report`` command is given, not from the one the
results were built with. Results of another config (the usual case: results of ``--config scale=ci``
reported without it) then look half-built: every output of a job of the report's config that never ran
(its sims, raw runs, packings and rollouts) is missing, Snakemake prints one "Missing metadata" warning
per such file (208 for the ci-scale slide, meteorite and shear reported at the default scale) and goes on,
showing the plots on disk as if they came from the report's config. A change of scale is refused earlier,
by the scale guard (workflow/graphdem_workflow/scales.py); this guard catches every other config the results were not
built with (more sims, another sweep). The workflow calls :func:`check`
from the report's category function, which Snakemake calls only while it builds a report, before the
first result is added; it raises with what is unbuilt and what to do (docs/architecture.md, "The report").
"""

from __future__ import annotations

import os
from collections import Counter

_checked: set[int] = set()       # the DAGs already checked (the check runs once per report)


class ReportError(Exception):
    """The report's DAG has jobs whose outputs were never built."""


def unbuilt(dag) -> list[tuple[str, str]]:
    """(rule, path) of every output of a job of ``dag`` that does not exist."""
    return [(job.rule.name, str(f)) for job in dag.jobs for f in job.output if not os.path.exists(str(f))]


def message(missing: list[tuple[str, str]], shown: int = 3) -> str:
    per_rule = Counter(rule for rule, _ in missing)
    rules = ", ".join(f"{rule} {n}" for rule, n in sorted(per_rule.items(), key=lambda item: (-item[1], item[0])))
    examples = ", ".join(path for _, path in missing[:shown]) + (", ..." if len(missing) > shown else "")
    return (f"snakemake --report: {len(missing)} outputs of this report's jobs were never built ({rules}; "
            f"e.g. {examples}), so the results on disk were built with another config or not at all. Give "
            f"--report the --config/--configfile the results were built with (e.g. --config scale=ci), or "
            f"build the targets first (snakemake -c2 TARGETS with the same config), then build the report.")


def check(dag) -> None:
    """Raise :class:`ReportError` where a job of ``dag`` has an output that does not exist (once per DAG)."""
    if dag is None or id(dag) in _checked:
        return
    missing = unbuilt(dag)
    if missing:
        raise ReportError(message(missing))
    _checked.add(id(dag))
