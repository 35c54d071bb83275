import os
import shutil

import pytest

from generators import config

# torch.compile's inductor compiles its kernels in a pool of worker processes by default; on the 2-core test
# machine starting that pool costs more than it saves (the compiled-rollout test: 49 s with it, 19 s without).
# Set before torch is imported, inherited by every job the workflow tests start.
os.environ.setdefault("TORCHINDUCTOR_COMPILE_THREADS", "1")


@pytest.fixture
def ci_slide() -> dict:
    """The validated ci-scale slide config section."""
    return config.load({"scale": "ci"})["slide"]


def pytest_collection_modifyitems(config, items):
    """``make test`` runs the suite on two pytest-xdist workers (``-n 2 --dist loadgroup``). Each test file is one
    group, so a module's fixtures are built once, on one worker; the workflow files, the longest, are handed out
    first so that neither worker is left with a long file at the end. (The ci-scale workflow run that several
    files share is built once for both workers: tests/workflow/conftest.py.)"""
    if shutil.which("lmp") is None:
        raise pytest.UsageError("LAMMPS (`lmp`) is not installed: run `make test`, which installs it")
    items.sort(key=lambda item: not item.nodeid.startswith("tests/workflow/"))      # stable: file order kept
    for item in items:
        item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))
