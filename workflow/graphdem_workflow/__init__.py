"""The Snakemake workflow's own helpers, used only by workflow/rules/common.smk (which puts workflow/ on sys.path)
and their tests: how the train job is launched and on which device (launch.py), stale locks of a killed run
(locks.py), the guard of ``snakemake --report`` (report.py) and the scale stamp of a results folder (scales.py).
They are not part of the installed packages: the wheel carries generators, surrogate, evaluation and graphdem."""
