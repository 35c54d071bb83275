"""Where the surrogate computes: the ``device`` config key and every stage's ``--device`` option.

``auto`` takes the first CUDA GPU when torch sees one (``torch.cuda.is_available()``), else the CPU;
``cpu``; ``cuda`` the first GPU; ``cuda:N`` GPU N. Under ``torchrun`` each process takes the GPU of
its ``LOCAL_RANK`` (``auto`` and ``cuda``); a fixed ``cuda:N`` is refused there, as every process
would share one GPU. The device changes where the arithmetic runs, not what it computes: results
agree with the CPU's up to floating-point rounding.

The module imports torch only when a function runs, so the command line checks ``--device`` before
loading it.
"""

from __future__ import annotations

import os
import platform
import re
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import torch

SPEC = re.compile(r"^(auto|cpu|cuda(:[0-9]+)?)$")
CHOICES = "auto, cpu, cuda or cuda:N"


def resolve(spec: str | torch.device = "auto", local_rank: int | None = None) -> torch.device:
    """The torch device of a ``device`` setting; ``local_rank`` is the process's GPU under torchrun."""
    import torch
    if isinstance(spec, torch.device):
        spec = str(spec)
    if not SPEC.match(spec):
        raise ValueError(f"device = {spec!r}: allowed are {CHOICES}")
    if spec == "cpu" or (spec == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        raise ValueError(f"device = {spec!r}, but torch sees no CUDA GPU (torch {torch.__version__}, "
                         f"CUDA build {torch.version.cuda}); use device=auto or device=cpu")
    if ":" in spec:
        if local_rank is not None:
            raise ValueError(f"device = {spec!r} under torchrun: every process would take the same GPU; give "
                             f"device=cuda and each process takes the GPU of its LOCAL_RANK")
        index = int(spec.split(":")[1])
    else:
        index = 0 if local_rank is None else local_rank
    if index >= torch.cuda.device_count():
        raise ValueError(f"device = {spec!r}: GPU {index} asked for, torch sees {torch.cuda.device_count()}")
    return torch.device("cuda", index)


def of(module: torch.nn.Module) -> torch.device:
    """The device a module's tensors live on (its first parameter's, else its first buffer's, else the CPU)."""
    import torch
    for tensor in (*module.parameters(), *module.buffers()):
        return tensor.device
    return torch.device("cpu")


def name(device: torch.device, cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """What a device is, for the records that say where something ran (history.csv, the benchmark card): a
    GPU's name (``torch.cuda.get_device_name``), or the CPU's model (``cpuinfo``'s first ``model name``, else
    :func:`platform.processor`) with the machine's logical CPU count."""
    import torch
    device = torch.device(device)
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    model = ""
    try:
        model = next((line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines()
                      if line.startswith("model name") and ":" in line), "")
    except OSError:
        pass
    return f"{model or platform.processor() or platform.machine() or 'CPU'}, {os.cpu_count()} logical CPUs"


def synchronize(device: torch.device) -> None:
    """Wait for the device's queued work (a CUDA timing must not stop the clock before the GPU is done)."""
    if device.type == "cuda":
        import torch
        torch.cuda.synchronize(device)


def autocast(device: torch.device, precision: str):
    """bfloat16 autocast of the network's forward pass on ``device``'s type (cpu or cuda) when ``precision``
    is ``bfloat16``; otherwise a context that changes nothing."""
    import torch
    return torch.autocast(device.type, dtype=torch.bfloat16, enabled=precision == "bfloat16")
