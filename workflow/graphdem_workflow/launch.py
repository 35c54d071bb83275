"""How the workflow starts the surrogate's jobs: the device they compute on and the train stage's launcher,
from the config's ``device`` and ``launch`` keys (docs/scaling.md).

These are machine settings: they change where and in how many processes the arithmetic runs, not what it
computes (results agree up to floating-point rounding), like a job's thread count. Snakemake reruns a job
whose params changed; the arguments made here are :class:`MachineArgs`, which Snakemake records as one
constant, so changing the device or the launcher reruns no job (``--forcerun train`` retrains on purpose).
"""

from __future__ import annotations

PLAIN = ("graphdem",)
TORCHRUN = ("torchrun", "--standalone", "--nproc-per-node")


class MachineArgs(list):
    """Shell arguments that say where a job computes. A rule writes them as ``{params.x:q}`` (every item
    quoted, as any list); Snakemake records a param by its ``repr``, here the same for every value."""

    def __repr__(self) -> str:
        return "MachineArgs(...)"


def device_args(config: dict) -> MachineArgs:
    """``--device`` with the config's ``device``, for every surrogate subcommand that computes."""
    return MachineArgs(["--device", str(config["device"])])


def train_command(config: dict) -> MachineArgs:
    """The command that runs ``graphdem train``: ``graphdem`` itself, or torchrun starting ``launch.processes``
    processes of it on this node (``torchrun --standalone``: a rendezvous on this machine only)."""
    launch = config["launch"]
    if launch["launcher"] == "plain":
        return MachineArgs(PLAIN)
    return MachineArgs([*TORCHRUN, str(int(launch["processes"])), "-m", "graphdem"])


def uses_gpu(config: dict) -> bool:
    """Whether the jobs ask a scheduler for GPUs: only with ``device`` cuda or cuda:N. ``auto`` asks for
    none (it takes a GPU where a job happens to see one)."""
    return str(config["device"]).startswith("cuda")


def gpus(config: dict, processes: int = 1) -> int:
    """The ``gpus`` resource of a job of ``processes`` processes (one GPU each where the jobs use GPUs)."""
    return int(processes) if uses_gpu(config) else 0


def train_gpus(config: dict) -> int:
    """The ``gpus`` resource of the train job: one per training process."""
    launch = config["launch"]
    return gpus(config, launch["processes"] if launch["launcher"] == "torchrun" else 1)
