"""``python -m graphdem``: the `graphdem` command (graphdem/cli.py)."""

import sys

from graphdem.cli import main

sys.exit(main())
