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
    if shutil.which("lmp") is None:
        raise pytest.UsageError("LAMMPS (`lmp`) is not installed: run `make test`, which installs it")
