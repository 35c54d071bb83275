"""The evaluation's `graphdem` subcommands, one module per stage, as surrogate/commands/: each has
``register(sub)`` and the functions that run them; graphdem/cli.py lists the registrars. They share
surrogate/commands/options.py's options and metric_options.py's (the scene metrics', the bootstrap intervals).

Modules import only the standard library and light registries at the top; a command imports what it drives
when it runs, so that `graphdem --help` and a wrong option answer at once.
"""
