"""Checkpoint names: the digest of a file, of an ensemble, and the modules that read stored files stay light."""

import hashlib
import subprocess
import sys

import pytest

from surrogate import provenance


def test_digest_is_the_files_sha256_and_an_ensemble_joins_its_members_in_order(tmp_path):
    a, b = tmp_path / "a.pt", tmp_path / "b.pt"
    a.write_bytes(b"weights a" * 300_000)            # over one read block of 1 MiB
    b.write_bytes(b"weights b")
    da, db = (hashlib.sha256(p.read_bytes()).hexdigest()[:12] for p in (a, b))
    assert provenance.digest(a) == provenance.file_digest(a) == da
    assert provenance.digest([b, a]) == f"{db}+{da}"
    assert provenance.label([a, str(b)]) == f"{a} {b}"
    with pytest.raises(ValueError, match="no checkpoint given"):
        provenance.digest([])


@pytest.mark.parametrize("module", ["evaluation.property_sensitivity", "evaluation.shear_stress_check",
                                    "evaluation.stored", "surrogate.provenance"])
def test_scoring_stored_files_does_not_import_the_model(module):
    probe = f"import sys\nimport {module}\nprint('torch_geometric' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"]                 # torch_geometric costs about 4 s per job that imports it
