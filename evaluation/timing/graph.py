"""CPU timing of the two radius-graph methods (docs/surrogate.md): ``python -m evaluation.timing.graph``.

Jittered lattice packings of unit-diameter particles at DEM packing fractions (0.8 in 2D, 0.6 in
3D), R in mean diameters as the scenes use it (slide and meteorite 2.5, slide paper 9.6, shear
1.5). Both methods alternate in every repeat; the table gives medians and their ratio. On one thread
the clock is the process's CPU time (the wall time of an unloaded machine, robust to other load),
on more the wall time.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from surrogate.graph import choose_split, radius_graph

# (dimension, particles, R in mean diameters)
CASES = [(2, 700, 2.5), (2, 2_000, 2.5), (2, 6_000, 2.5), (2, 20_000, 2.5), (2, 50_000, 2.5), (2, 200_000, 2.5),
         (2, 6_000, 9.6), (3, 2_000, 1.5), (3, 6_000, 1.5), (3, 20_000, 1.5), (3, 50_000, 1.5), (3, 200_000, 1.5),
         (3, 50_000, 2.5)]
FRACTION = {2: 0.8, 3: 0.6}
METHODS = ("kdtree", "cells")


def packing(n: int, dim: int, seed: int = 0) -> torch.Tensor:
    """[n, dim] float32 centres: a cubic lattice at the packing fraction's density, jittered by 10 %,
    shifted to negative coordinates, in random order (as particles are after mixing)."""
    ball = torch.pi / 4 if dim == 2 else torch.pi / 6          # area / volume of a unit-diameter particle
    spacing = (ball / FRACTION[dim]) ** (1 / dim)
    side = round(n ** (1 / dim) + 0.5)
    grid = torch.cartesian_prod(*[torch.arange(side, dtype=torch.float64)] * dim)[:n]
    gen = torch.Generator().manual_seed(seed)
    jitter = (torch.rand(grid.shape, generator=gen, dtype=torch.float64) - 0.5) * 0.2
    return ((grid + jitter) * spacing - side * spacing / 3).float()[torch.randperm(n, generator=gen)]


def time_methods(pos: torch.Tensor, radius: float, repeats: int) -> dict[str, float]:
    """Median seconds per method, the methods alternating inside every repeat (one warm-up each)."""
    clock = time.process_time if torch.get_num_threads() == 1 else time.perf_counter
    times: dict[str, list[float]] = {m: [] for m in METHODS}
    for r in range(repeats + 1):
        for method in METHODS if r % 2 else METHODS[::-1]:
            t0 = clock()
            radius_graph(pos, radius, method=method)
            if r:
                times[method].append(clock() - t0)
    return {m: statistics.median(t) for m, t in times.items()}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (rollouts use 1)")
    parser.add_argument("--max-particles", type=int, default=200_000)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    clock = "CPU time" if args.threads == 1 else "wall time"
    print(f"torch {torch.__version__}, {args.threads} thread(s), {clock}, median of {args.repeats}")
    print("| D | N | R / d | edges | cells per R | k-d tree (ms) | cell list (ms) | cell / k-d |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for dim, n, ratio in CASES:
        if n > args.max_particles:
            continue
        pos = packing(n, dim)
        edges = radius_graph(pos, ratio).shape[1]
        t = time_methods(pos, ratio, args.repeats)
        print(f"| {dim} | {n} | {ratio} | {edges} | {choose_split(pos, ratio)} | {1e3 * t['kdtree']:.1f} "
              f"| {1e3 * t['cells']:.1f} "
              f"| {t['cells'] / t['kdtree']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
