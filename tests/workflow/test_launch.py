"""How the workflow launches the surrogate's jobs (workflow/graphdem_workflow/launch.py): the device and launcher
arguments, recorded by Snakemake as one constant, and the GPUs a job asks for."""

from graphdem_workflow import launch


def _config(device="auto", launcher="plain", processes=1):
    return {"device": device, "launch": {"launcher": launcher, "processes": processes}}


def test_machine_arguments_are_one_constant_to_snakemake_whatever_their_values():
    cpu, gpu = launch.device_args(_config("cpu")), launch.device_args(_config("cuda:1"))
    assert cpu == ["--device", "cpu"] and gpu == ["--device", "cuda:1"]
    assert repr(cpu) == repr(gpu) == repr(launch.train_command(_config(launcher="torchrun", processes=4)))
    assert launch.train_command(_config(launcher="torchrun", processes=4)) == [
        "torchrun", "--standalone", "--nproc-per-node", "4", "-m", "graphdem"]
    assert launch.train_command(_config(launcher="plain", processes=4)) == ["graphdem"]


def test_gpus_are_asked_for_only_on_a_cuda_device_one_per_process():
    for device, wanted in (("auto", False), ("cpu", False), ("cuda", True), ("cuda:2", True)):
        assert launch.uses_gpu(_config(device)) is wanted
    assert launch.gpus(_config("cuda"), 3) == 3 and launch.gpus(_config("auto"), 3) == 0
    assert launch.train_gpus(_config("cuda", "torchrun", 4)) == 4
    assert launch.train_gpus(_config("cuda", "plain", 4)) == 1          # plain: one process whatever the count
    assert launch.train_gpus(_config("cpu", "torchrun", 4)) == 0
