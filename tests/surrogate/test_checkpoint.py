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


def _saved(untrained, path):
    """The untrained simulator saved as a checkpoint, with the metadata a trained one carries."""
    simulator, _ = untrained
    checkpoint.save(path, {"model": simulator.state_dict(),
                           "json": {"stats": simulator.stats, "model": simulator.model_config}})
    return path


@pytest.mark.engine
def test_a_checkpoint_loads_on_any_device_setting_and_rolls_out_the_same(untrained, tmp_path):
    import numpy as np
    import torch

    from surrogate import rollout
    simulator, sim = untrained
    reference = rollout.rollout(simulator, sim).position
    path = _saved(untrained, tmp_path / "best.pt")
    settings = ["cpu", torch.device("cpu")] + ([] if torch.cuda.is_available() else ["auto"])   # auto: the CPU here
    for device in settings:
        loaded, meta = checkpoint.simulator_from(path, device)
        assert {t.device.type for t in loaded.state_dict().values()} == {"cpu"} and not loaded.training
        np.testing.assert_array_equal(rollout.rollout(loaded, sim).position, reference)      # bit for bit
    # tensors are stored from the CPU: a plain torch.load reads them on a machine without a GPU
    plain = torch.load(path, weights_only=True)
    assert all(t.device.type == "cpu" for t in plain["model"].values())
    # on the meta device: shapes and dtypes, no data (inspect a large checkpoint without reading its weights)
    meta_only = checkpoint.load(path, map_location="meta")
    for name, value in simulator.state_dict().items():
        assert meta_only["model"][name].is_meta and meta_only["model"][name].shape == value.shape
    assert meta_only["json"]["model"] == simulator.model_config


@pytest.mark.engine
def test_a_checkpoint_moves_between_cpu_and_gpu(untrained, tmp_path):
    import numpy as np
    import torch

    from surrogate import rollout
    if not torch.cuda.is_available():
        pytest.skip("no CUDA GPU: the CPU-to-GPU round trip needs one (the CPU settings are tested above)")
    simulator, sim = untrained
    reference = rollout.rollout(simulator, sim).position
    on_gpu, _ = checkpoint.simulator_from(_saved(untrained, tmp_path / "cpu.pt"), "cuda")
    assert {t.device.type for t in on_gpu.state_dict().values()} == {"cuda"}
    gpu_rollout = rollout.rollout(on_gpu, sim).position
    spread = np.abs(reference[-1] - reference[0]).max()
    np.testing.assert_allclose(gpu_rollout, reference, rtol=0, atol=1e-4 * max(spread, 1.0))   # float32 rounding
    checkpoint.save(tmp_path / "gpu.pt", {"model": on_gpu.state_dict(),
                                          "json": {"stats": simulator.stats, "model": simulator.model_config}})
    back, _ = checkpoint.simulator_from(tmp_path / "gpu.pt", "cpu")
    np.testing.assert_array_equal(rollout.rollout(back, sim).position, reference)     # the same weights
