"""CPU timing of the contact correction's pair search (docs/surrogate.md, Plausibility):
``python -m evaluation.timing.correction``.

The correction (:mod:`surrogate.correction`) with its Verlet list against a search before every
sweep (skin 0), on squeezed packings: the jittered lattices of :func:`evaluation.timing.graph.packing`
(unit mean diameter, radii 0.5 +- 5 %, the first tenth kinematic) with every coordinate scaled by
``--squeeze``, so that many pairs overlap by more than allowed, as a learned rollout's frames do.
Both searches alternate in every repeat; the table gives medians, their ratio and the largest
difference of the corrected positions (rounding: the two find the same pairs). On one thread the
clock is the process's CPU time.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from evaluation.timing.graph import packing
from surrogate.correction import SKIN, correct_overlaps

# (dimension, particles): the slide's and the shear's default sizes, and larger
CASES = [(2, 265), (2, 2_000), (2, 20_000), (3, 939), (3, 6_000)]


def squeezed(n: int, dim: int, squeeze: float, seed: int = 0) -> tuple[torch.Tensor, ...]:
    """Positions [n, dim], radii [n], moving [n] and the box (lower, upper) of one squeezed packing."""
    x = packing(n, dim, seed) * squeeze
    generator = torch.Generator().manual_seed(seed)
    r = 0.5 * (1 + 0.1 * (torch.rand(n, generator=generator) - 0.5))
    moving = torch.ones(n, dtype=torch.bool)
    moving[: n // 10] = False
    return x, r, moving, x.min(dim=0).values - 1, x.max(dim=0).values + 1


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--iterations", type=int, default=50, help="sweeps at most (the slide's setting)")
    parser.add_argument("--allowed-overlap", type=float, default=0.05, help="the slide's setting")
    parser.add_argument("--squeeze", type=float, default=0.93, help="coordinates scaled by this (< 1: overlaps)")
    parser.add_argument("--max-particles", type=int, default=20_000, help="leave out the larger cases")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    print(f"torch {torch.__version__}, 1 thread, CPU time, median of {args.repeats}, {args.iterations} sweeps at "
          f"most, allowed overlap {args.allowed_overlap}, skin {SKIN} max(r)")
    print("| D | N | pairs too deep | search every sweep (ms) | Verlet list (ms) | speed-up | max diff |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for dim, n in CASES:
        if n > args.max_particles:
            continue
        x, r, moving, lower, upper = squeezed(n, dim, args.squeeze)
        times: dict[float, list[float]] = {0.0: [], SKIN: []}
        out: dict[float, torch.Tensor] = {}
        for repeat in range(args.repeats + 1):
            for skin in (0.0, SKIN) if repeat % 2 else (SKIN, 0.0):
                t0 = time.process_time()
                out[skin], found = correct_overlaps(x, r, moving, args.allowed_overlap, args.iterations, lower,
                                                    upper, skin=skin)
                if repeat:                                   # the first round is a warm-up
                    times[skin].append(time.process_time() - t0)
        every, listed = (statistics.median(times[s]) for s in (0.0, SKIN))
        print(f"| {dim} | {n} | {found} | {1e3 * every:.1f} | {1e3 * listed:.1f} | {every / listed:.2f} "
              f"| {float((out[0.0] - out[SKIN]).abs().max()):.1e} |", flush=True)


if __name__ == "__main__":
    main()
