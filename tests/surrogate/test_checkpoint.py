import json
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


@pytest.fixture
def tiny_checkpoint(tmp_path):
    """A tiny Graph-DEM checkpoint (no dataset needed) and its parts."""
    from surrogate.simulator import LearnedSimulator
    stats = {"dim": 2, "n_types": 2, "connectivity_radius": 1.0, "bounds": [[0, 10], [0, 10]],
             "velocity_mean": [0, 0], "velocity_std": [1, 1], "acceleration_mean": [0, 0], "acceleration_std": [1, 1]}
    model = {"history": 3, "embed": 4, "mlp_layers": 2, "properties": [], "latent": 8, "hidden": 8,
             "message_passing": 1}
    weights = LearnedSimulator(stats, model).state_dict()
    path = tmp_path / "model.pt"
    checkpoint.save(path, {"model": weights, "json": {"stats": stats, "model": model}})
    return path, stats, model, weights


def test_a_compressed_record_is_refused_before_it_inflates(tiny_checkpoint, tmp_path):
    import zipfile
    path = tiny_checkpoint[0]
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(tmp_path / "deflated.pt", "w") as out:
        for info in source.infolist():
            out.writestr(info.filename, source.read(info), compress_type=zipfile.ZIP_DEFLATED)
    assert checkpoint.simulator_from(path)[1]["model"]["latent"] == 8
    with pytest.raises(checkpoint.CheckpointError, match=r"deflated.pt: record .*data.pkl is compressed \(zip method"):
        checkpoint.read(tmp_path / "deflated.pt")


def test_a_tensor_that_repeats_its_bytes_over_a_huge_shape_is_refused(tiny_checkpoint, tmp_path):
    import torch
    _, stats, model, weights = tiny_checkpoint
    torch.save({"model": weights, "optimiser": {"exp_avg": torch.zeros(1).expand(2**30)},
                "json": json.dumps({"stats": stats, "model": model})}, tmp_path / "view.pt")
    with pytest.raises(checkpoint.CheckpointError, match=r"view.pt: its tensors hold more than the \d+ bytes it stores "
                                                         r"\(a tensor of shape \(1073741824,\) repeats its data\)"):
        checkpoint.read(tmp_path / "view.pt")


@pytest.mark.parametrize("change, message", [
    ({"latent": 60000}, "model.latent' = 60000 .* maximum of 4096"),
    ({"message_passing": 2.0}, "model.message_passing' = 2.0 .* must be an integer"),
    ({"history": 1}, "model.history' = 1 .* minimum of 2"),
])
def test_model_sizes_outside_the_schemas_ranges_are_refused_from_the_metadata(tiny_checkpoint, tmp_path, change,
                                                                                message):
    import torch
    _, stats, model, weights = tiny_checkpoint
    torch.save({"model": weights, "json": json.dumps({"stats": stats, "model": {**model, **change}})},
               tmp_path / "sizes.pt")
    with pytest.raises(checkpoint.CheckpointError, match=f"sizes.pt: its model metadata is outside the config "
                                                         f"schema's range: config key '{message}"):
        checkpoint.load(tmp_path / "sizes.pt")


def test_sizes_in_range_that_do_not_fit_the_weights_are_refused_before_the_model_is_built(tiny_checkpoint, tmp_path):
    import torch
    _, stats, model, weights = tiny_checkpoint
    torch.save({"model": weights, "json": json.dumps({"stats": {**stats, "n_types": 10**7},
                                                      "model": {**model, "embed": 1024}})}, tmp_path / "types.pt")
    with pytest.raises(checkpoint.CheckpointError, match=r"types.pt: weights do not fit the model it describes: "
                                                         r"model.node_constructor.embedding.weight is \(2, 4\), the "
                                                         r"model's \(10000000, 1024\)"):
        checkpoint.simulator_from(tmp_path / "types.pt")
