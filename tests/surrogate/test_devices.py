"""Device settings: what auto, cpu, cuda and cuda:N resolve to, with and without a GPU and under torchrun."""

import pytest
import torch

from generators import config
from surrogate import devices, runtime


def fake_gpus(monkeypatch, count: int) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: count > 0)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: count)


def test_the_config_schema_and_the_command_line_accept_the_same_settings():
    assert config.schema()["properties"]["device"]["pattern"] == devices.SPEC.pattern
    for good in ("auto", "cpu", "cuda", "cuda:0", "cuda:12"):
        assert devices.SPEC.match(good) and config.load({"device": good})["device"] == good
    for bad in ("gpu", "cuda:", "cuda:x", "CPU", "mps"):
        assert not devices.SPEC.match(bad)
        with pytest.raises(ValueError, match="allowed are auto, cpu, cuda or cuda:N"):
            devices.resolve(bad)


def test_without_a_gpu_auto_is_the_cpu_and_cuda_is_refused(monkeypatch):
    fake_gpus(monkeypatch, 0)
    assert devices.resolve("auto") == devices.resolve("cpu") == torch.device("cpu")
    assert devices.resolve("auto", local_rank=1) == torch.device("cpu")          # a CPU process under torchrun
    for spec in ("cuda", "cuda:0"):
        with pytest.raises(ValueError, match=f"device = '{spec}', but torch sees no CUDA GPU"):
            devices.resolve(spec)


def test_with_gpus_auto_and_cuda_take_the_first_or_the_local_ranks(monkeypatch):
    fake_gpus(monkeypatch, 2)
    assert devices.resolve("auto") == devices.resolve("cuda") == torch.device("cuda", 0)
    assert devices.resolve("cuda:1") == torch.device("cuda", 1)
    assert devices.resolve("auto", local_rank=1) == devices.resolve("cuda", local_rank=1) == torch.device("cuda", 1)
    assert devices.resolve("cpu", local_rank=1) == torch.device("cpu")
    with pytest.raises(ValueError, match="under torchrun: every process would take the same GPU"):
        devices.resolve("cuda:1", local_rank=0)
    with pytest.raises(ValueError, match="GPU 2 asked for, torch sees 2"):
        devices.resolve("cuda:2")
    with pytest.raises(ValueError, match="GPU 3 asked for, torch sees 2"):
        devices.resolve("cuda", local_rank=3)


@pytest.mark.filterwarnings("ignore:CUDA is not available:UserWarning")
def test_bfloat16_autocast_follows_the_models_device_type():
    for kind in ("cpu", "cuda"):
        context = runtime.Runtime(True, True, True, "bfloat16", None, False, False).autocast(torch.device(kind))
        assert context.device == kind and context.fast_dtype == torch.bfloat16
        assert context._enabled == (kind == "cpu" or torch.cuda.is_available())    # torch turns it off without a GPU
    assert not runtime.Runtime(True, True, True, "float32", None, False, False).autocast(torch.device("cpu"))._enabled
    with runtime.Runtime(True, True, True, "bfloat16", None, False, False).autocast("cpu"):
        assert torch.is_autocast_enabled("cpu")
        assert torch.nn.functional.linear(torch.ones(2, 3), torch.ones(4, 3)).dtype == torch.bfloat16
    assert devices.of(torch.nn.Linear(2, 2)) == torch.device("cpu")
    assert devices.of(torch.nn.Identity()) == torch.device("cpu")          # no tensor at all: the CPU


def test_a_device_is_named_by_its_gpu_or_its_cpu_model(monkeypatch, tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nmodel name\t: Some CPU @ 2.0GHz\n\nprocessor\t: 1\nmodel name\t: Some CPU\n")
    monkeypatch.setattr(devices.os, "cpu_count", lambda: 2)
    assert devices.name(torch.device("cpu"), cpuinfo) == "Some CPU @ 2.0GHz, 2 logical CPUs"
    assert devices.name("cpu", tmp_path / "none").endswith(", 2 logical CPUs")      # no cpuinfo: platform's word
    monkeypatch.setattr(torch.cuda, "get_device_name", lambda device: f"Some GPU {device.index}")
    assert devices.name(torch.device("cuda", 1)) == "Some GPU 1"
