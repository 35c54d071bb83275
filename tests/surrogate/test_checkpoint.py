import pickle

import pytest

from surrogate import checkpoint


class Exploit:
    def __reduce__(self):
        import os
        return (os.system, ("touch PWNED_BY_CHECKPOINT",))


def test_a_checkpoint_that_would_run_code_is_refused_and_runs_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    bad = tmp_path / "evil.pt"
    bad.write_bytes(pickle.dumps({"model": Exploit(), "json": "{}"}))
    with pytest.raises(checkpoint.CheckpointError, match="evil.pt: not a loadable Graph-DEM checkpoint"):
        checkpoint.load(bad)
    assert not (tmp_path / "PWNED_BY_CHECKPOINT").exists()


def test_missing_and_foreign_checkpoints_are_named(tmp_path):
    with pytest.raises(checkpoint.CheckpointError, match="nope.pt: no such checkpoint"):
        checkpoint.load(tmp_path / "nope.pt")
    import torch
    torch.save({"weights": torch.zeros(2)}, tmp_path / "other.pt")
    with pytest.raises(checkpoint.CheckpointError, match="other.pt: not a Graph-DEM checkpoint"):
        checkpoint.load(tmp_path / "other.pt")
