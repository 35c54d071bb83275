import shutil

import pytest

from generators import config


@pytest.fixture
def ci_slide() -> dict:
    """The validated ci-scale slide config section."""
    return config.load({"scale": "ci"})["slide"]


def pytest_collection_modifyitems(config, items):
    if shutil.which("lmp") is None:
        raise pytest.UsageError("LAMMPS (`lmp`) is not installed: run `make test`, which installs it")
