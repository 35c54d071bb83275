"""The surrogate's `graphdem` subcommands, one module per stage: each has ``register(sub)``, which adds its
subcommands' parsers to the subparsers ``sub``, and the functions that run them (``run``, or ``run_<name>`` where
a module has several). graphdem/cli.py lists the registrars in the order `graphdem --help` shows them;
options.py holds the options several subcommands share.

Modules import only the standard library and light registries at the top; a command imports what it drives
(torch, pandas, the stage's module) when it runs, so that `graphdem --help` and a wrong option answer at once.
"""
