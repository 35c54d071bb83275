"""An unpickler that admits numpy array reconstruction and nothing else.

A pickle names callables that run when it is loaded (``os.system`` is one ``GLOBAL`` away). The
Solid-GN files need exactly three globals to rebuild their float64 arrays; any other global is
refused before it is looked up, so nothing a file names can run.
"""

from __future__ import annotations

import io
import pickle
from pathlib import Path

ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy", "ndarray"), ("numpy", "dtype"),
}


class UnsafePickle(pickle.UnpicklingError):
    """A pickle asks for a global outside numpy array reconstruction."""


class NumpyOnlyUnpickler(pickle.Unpickler):
    def __init__(self, file, name: str):
        super().__init__(file)
        self.name = name

    def find_class(self, module: str, name: str):
        if (module, name) not in ALLOWED:
            raise UnsafePickle(f"{self.name}: refused to load {module}.{name}: only numpy array reconstruction "
                               f"({', '.join(sorted(f'{m}.{n}' for m, n in ALLOWED))}) is allowed")
        return super().find_class(module, name)


def load(path: str | Path):
    """Unpickle ``path`` admitting only numpy arrays, dicts, lists and scalars."""
    path = Path(path)
    data = path.read_bytes()
    try:
        return NumpyOnlyUnpickler(io.BytesIO(data), str(path)).load()
    except UnsafePickle:
        raise
    except Exception as exc:   # noqa: BLE001 - a corrupt pickle raises many kinds of errors
        raise pickle.UnpicklingError(f"{path}: not a readable pickle (corrupt or truncated?): {exc}") from exc
