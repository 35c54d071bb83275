"""Reading the pipeline's CSV tables back without changing what they say.

A checkpoint's short SHA-256 is 12 hex digits, and some digests are also numbers to a CSV parser:
``15792618e549`` reads as a float (infinity) and ``001234567890`` as an integer without its zeros. Where the
pipeline reads a table that names its model back (``metrics.csv`` and ``metrics_per_step.csv`` in
:func:`evaluation.evaluate.combine`, :func:`evaluation.seeds.read`, ``metrics.html``, the benchmark card and the
performance report), it goes through :func:`read_csv`, which keeps the provenance columns as text, so what it
writes next carries the digest exactly as the evaluation wrote it.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

__all__ = ["TEXT_COLUMNS", "read_csv"]

# columns that identify a model or the code that made a row: never numbers, whatever their characters
TEXT_COLUMNS = ("checkpoint", "checkpoint_sha", "config_sha", "code_version", "rollout_checkpoint_sha")


def read_csv(path: str | Path, **kwargs) -> pd.DataFrame:
    """``pandas.read_csv`` with :data:`TEXT_COLUMNS` (those present) read as strings; ``dtype`` entries given in
    ``kwargs`` are kept beside them."""
    dtype = {column: str for column in TEXT_COLUMNS} | dict(kwargs.pop("dtype", None) or {})
    return pd.read_csv(path, dtype=dtype, **kwargs)
