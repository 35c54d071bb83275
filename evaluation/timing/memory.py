"""The largest particle count one training step fits in a device's memory: ``python -m evaluation.timing.memory``.

A checkpoint's model (its dimension, R, types and properties) takes one training step, the forward pass
with gradient and the backward pass (the graph built on the device, as in training), on a synthetic
packing of N moving particles. Only the graph's size matters for memory, so the packing is particles at
random in a box (a Poisson packing; overlaps are allowed) whose density gives each particle the dataset's
99th-percentile neighbour count within R (``stats.json``'s ``neighbour_counts.p99``: a dense granular
flow, the heavy end of what training sees): among points of number density rho a particle has on average
rho V(R) others within R, V(R) the disc's area or the ball's volume, so rho = p99 / V(R)
(:func:`density_for`). Every particle moves by one frame at the data's velocity spread, so the features
are of the data's size.

N doubles from ``--start`` until a step runs out of memory or ``--max-particles`` is reached; then
``--refine`` bisections between the last N that fitted and the first that did not. One training batch of
B samples of N/B particles each is one graph of N particles, so the figure is the batch's total. The table
gives per N the edges, the edges per particle, the peak memory the step allocated above the model's own
(CUDA: ``torch.cuda.max_memory_allocated``; on the CPU it is not measured) and the step's wall time.
"""

from __future__ import annotations

import argparse
import gc
import math
import time
from pathlib import Path

import pandas as pd
import torch

from surrogate import checkpoint, devices
from surrogate.graph import build_graph, prune_isolated
from surrogate.simulator import LearnedSimulator

COLUMNS = ["particles", "edges", "edges_per_particle", "peak_bytes", "bytes_per_particle", "seconds", "fits"]


def ball_volume(radius: float, dim: int) -> float:
    """Area (2D) or volume (3D) of a ball of ``radius``."""
    if dim == 2:
        return math.pi * radius ** 2
    if dim == 3:
        return 4.0 / 3.0 * math.pi * radius ** 3
    raise ValueError(f"dimension {dim}: 2 or 3 allowed")


def density_for(neighbours: float, radius: float, dim: int) -> float:
    """Number density at which a particle has on average ``neighbours`` others within ``radius``."""
    if neighbours <= 0:
        raise ValueError(f"neighbour count {neighbours}: more than 0 allowed")
    return neighbours / ball_volume(radius, dim)


def synthetic_window(n: int, dim: int, density: float, history: int, velocity_std: torch.Tensor,
                     seed: int = 0) -> torch.Tensor:
    """[history, n, dim] float32 positions: ``n`` particles uniformly at random in a cube of side
    (n / ``density``)^(1/dim); each frame moves every particle by a step drawn at ``velocity_std`` (m per
    frame)."""
    gen = torch.Generator().manual_seed(seed)
    side = (n / density) ** (1.0 / dim)
    first = torch.rand((n, dim), generator=gen, dtype=torch.float64) * side
    steps = torch.randn((history, n, dim), generator=gen, dtype=torch.float64) * velocity_std.double().cpu()
    steps[0] = 0.0
    return (first + steps.cumsum(0)).float()


def training_step(simulator: LearnedSimulator, n: int, neighbours: float, seed: int = 0) -> dict:
    """One training step of ``simulator`` on ``n`` synthetic moving particles on its device: the edges
    built, the peak bytes allocated above what was held before (NaN off CUDA) and the wall seconds."""
    device = simulator.lower.device
    stats = simulator.stats
    kinematic_species = set(stats.get("kinematic_species", []))
    moving_type = min(t for t in range(int(stats["n_types"])) if t not in kinematic_species)
    density = density_for(neighbours, simulator.radius, simulator.dim)
    window = synthetic_window(n, simulator.dim, density, simulator.history, simulator.velocity_std, seed).to(device)
    types = torch.full((n,), moving_type, dtype=torch.long, device=device)
    kinematic = torch.zeros(n, dtype=torch.bool, device=device)
    props = (torch.zeros((n, len(simulator.property_names)), device=device) if simulator.property_names else None)
    simulator.train()
    simulator.zero_grad(set_to_none=True)
    cuda = device.type == "cuda"
    if cuda:
        torch.cuda.synchronize(device)
        torch.cuda.reset_peak_memory_stats(device)
        held = torch.cuda.memory_allocated(device)
    start = time.perf_counter()
    graph = build_graph(window, types, kinematic, simulator.radius, props, max_neighbours=simulator.max_neighbours)
    edges = int(graph.edge_index.shape[1])
    graph, _ = prune_isolated(graph)
    prediction = simulator(graph, decode=(~graph.kinematic).nonzero().squeeze(1))
    loss = (prediction ** 2).mean()
    loss.backward()
    if cuda:
        torch.cuda.synchronize(device)
    seconds = time.perf_counter() - start
    peak = float(torch.cuda.max_memory_allocated(device) - held) if cuda else float("nan")
    simulator.zero_grad(set_to_none=True)
    return {"particles": n, "edges": edges, "edges_per_particle": edges / n, "peak_bytes": peak,
            "bytes_per_particle": peak / n, "seconds": seconds, "fits": True}


def _out_of_memory(exc: BaseException) -> bool:
    """Whether ``exc`` is an allocation failure (CUDA's, or the CPU allocator's)."""
    text = str(exc).lower()
    return isinstance(exc, torch.cuda.OutOfMemoryError) or "out of memory" in text or "can't allocate" in text


def sweep(simulator: LearnedSimulator, start: int, max_particles: int, refine: int = 3,
          neighbours: float | None = None, seed: int = 0) -> pd.DataFrame:
    """Training steps at N = start, 2 start, ... up to ``max_particles``, until one runs out of memory, then
    ``refine`` bisections between the last N that fitted and the first that did not (one row per step;
    ``fits`` False on the steps that ran out of memory). ``neighbours``: the count per particle the packing
    is built for (default the dataset's 99th percentile)."""
    if not 1 <= start <= max_particles:
        raise ValueError(f"start = {start}, max_particles = {max_particles}: 1 <= start <= max_particles needed")
    if neighbours is None:
        if "p99" not in simulator.stats.get("neighbour_counts", {}):
            raise ValueError("the model's dataset stats have no neighbour_counts.p99 (a stats.json from before "
                             "the key): rebuild the dataset stage, or give the neighbour count")
        neighbours = float(simulator.stats["neighbour_counts"]["p99"])
    rows: list[dict] = []

    def attempt(n: int) -> bool:
        try:
            rows.append(training_step(simulator, n, neighbours, seed))
            fits = True
        except RuntimeError as exc:          # torch.cuda.OutOfMemoryError is one
            if not _out_of_memory(exc):
                raise
            rows.append({"particles": n, "fits": False})
            fits = False
        # Outside the handler: the exception's traceback (and the failed step's tensors it holds) is gone, so
        # the next step starts from the model's own memory alone, not from what the last one left cached.
        simulator.zero_grad(set_to_none=True)
        if simulator.lower.device.type == "cuda":
            gc.collect()
            torch.cuda.empty_cache()
        return fits

    fitted, failed, n = 0, None, start
    while n <= max_particles:
        if not attempt(n):
            failed = n
            break
        fitted, n = n, 2 * n
    for _ in range(refine if failed is not None and fitted else 0):
        middle = (fitted + failed) // 2
        if middle in (fitted, failed):
            break
        if attempt(middle):
            fitted = middle
        else:
            failed = middle
    return pd.DataFrame(rows, columns=COLUMNS).sort_values("particles", kind="stable").reset_index(drop=True)


def largest_fitting(table: pd.DataFrame) -> int:
    """The largest particle count of the sweep whose step fitted (0 when none did)."""
    fitted = table.loc[table["fits"].astype(bool), "particles"]
    return int(fitted.max()) if len(fitted) else 0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog="The packing and the sweep are described in the module's docstring "
                                            "(docs/scaling.md).")
    parser.add_argument("--checkpoint", required=True, type=Path, help="a trained model (best.pt); its stats "
                        "give the dimension, R, types and the neighbour count the packing is built for")
    parser.add_argument("--device", default="auto", help=f"{devices.CHOICES} (default auto)")
    parser.add_argument("--start", type=int, default=1000, help="first particle count (default 1000)")
    parser.add_argument("--max-particles", type=int, default=4_000_000, help="stop doubling here (default 4e6)")
    parser.add_argument("--refine", type=int, default=3, help="bisections after the first step that runs out "
                        "of memory (default 3)")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    parser.add_argument("--out", type=Path, help="write the table here as CSV")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    simulator, _ = checkpoint.simulator_from(args.checkpoint, args.device)
    table = sweep(simulator, args.start, args.max_particles, args.refine)
    where = devices.name(simulator.lower.device)
    print(f"{args.checkpoint}: one training step per row on {where} (R = {simulator.radius:g}, "
          f"{simulator.stats['neighbour_counts']['p99']} neighbours per particle at the 99th percentile)")
    print(table.to_string(index=False))
    print(f"largest particle count that trained: {largest_fitting(table)}")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
