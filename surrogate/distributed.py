"""Several training processes on one batch: DistributedDataParallel under ``torchrun``.

``torchrun --nproc-per-node N -m graphdem train ...`` starts N processes and tells each its
``RANK``, ``LOCAL_RANK`` and ``WORLD_SIZE``. Every process draws the same global batch (sample order,
flips, pushforward steps and input noise from the shared seed) and computes the loss of its own
contiguous share of the batch's samples (:func:`share`); the gradients are averaged across processes, and the
share's loss is weighted so that the average is the gradient of the one-process loss of the whole
batch. One process with the same ``train.batch_size`` so ends with the same weights, up to float
rounding. Rank 0 alone validates and writes the outputs; the others wait for it.

Backends: ``nccl`` between GPUs, ``gloo`` on the CPU.
"""

from __future__ import annotations

import contextlib
import datetime
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import torch
import torch.distributed as dist

# Rank 0 validates (rollouts of every valid sim) while the others wait at a barrier: far longer than a step.
TIMEOUT = datetime.timedelta(hours=2)


@dataclass(frozen=True)
class World:
    """This process's place among the training processes (one process: rank 0 of 1)."""

    rank: int = 0
    size: int = 1
    local_rank: int | None = None       # set under torchrun: the process's GPU on its node
    local_size: int = 1                 # the processes on this node (they share its CPU threads)

    @property
    def main(self) -> bool:
        """The process that validates and writes."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.size > 1

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None) -> World:
        """The world torchrun describes in ``WORLD_SIZE``, ``RANK`` and ``LOCAL_RANK``; one process without them."""
        env = os.environ if environ is None else environ
        if "WORLD_SIZE" not in env:
            return cls()
        try:
            size, rank = int(env["WORLD_SIZE"]), int(env.get("RANK", "0"))
            local = int(env.get("LOCAL_RANK", str(rank)))
            local_size = int(env.get("LOCAL_WORLD_SIZE", str(size)))
        except ValueError as exc:
            raise ValueError(f"WORLD_SIZE, RANK, LOCAL_RANK and LOCAL_WORLD_SIZE must be integers: {exc}") from exc
        if not 0 <= rank < size:
            raise ValueError(f"RANK = {rank} is outside WORLD_SIZE = {size}")
        return cls(rank=rank, size=size, local_rank=local, local_size=max(1, local_size))


def backend(device: torch.device) -> str:
    return "nccl" if device.type == "cuda" else "gloo"


@contextlib.contextmanager
def session(world: World, device: torch.device) -> Iterator[None]:
    """The process group of a multi-process ``world`` (set up from torchrun's environment, torn down at the end);
    nothing for one process or where the caller already set one up."""
    if not world.distributed or dist.is_initialized():
        yield
        return
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(backend(device), rank=world.rank, world_size=world.size, timeout=TIMEOUT)
    try:
        yield
    finally:
        dist.destroy_process_group()


def share(n: int, world: World) -> range:
    """The positions in a batch of ``n`` samples that ``world.rank`` computes: contiguous blocks whose sizes
    differ by at most one (the first ``n % size`` ranks take one more), empty where ``n < size``."""
    base, extra = divmod(n, world.size)
    start = world.rank * base + min(world.rank, extra)
    return range(start, start + base + (world.rank < extra))


def total(value: torch.Tensor, world: World) -> torch.Tensor:
    """Sum of a tensor over the processes (the tensor itself for one process)."""
    if not world.distributed:
        return value
    out = value.detach().clone()
    dist.all_reduce(out, op=dist.ReduceOp.SUM)
    return out


def mean(value: torch.Tensor, world: World) -> float:
    """Mean over the processes of a one-element tensor, as a float (the value itself for one process)."""
    return float(total(value.detach(), world)) / world.size


def barrier(world: World) -> None:
    if world.distributed:
        dist.barrier()


def from_main(value: Any, world: World) -> Any:
    """Rank 0's ``value`` (any picklable object) on every process."""
    if not world.distributed:
        return value
    box = [value]
    dist.broadcast_object_list(box, src=0)
    return box[0]


def wrap(module: torch.nn.Module, world: World, device: torch.device) -> torch.nn.Module:
    """The module whose forward pass carries the gradient: DDP on several processes, the module itself on one.
    Buffers (the dataset statistics) are the same everywhere and are not broadcast."""
    if not world.distributed:
        return module
    ids = [device.index] if device.type == "cuda" else None
    return torch.nn.parallel.DistributedDataParallel(module, device_ids=ids, forward_sync_buffers=False)
