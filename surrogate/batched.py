"""Rollouts of several sims at once: one network call per step on the disjoint union of their graphs.

Every sim keeps its own radius graph (built per sim as :func:`surrogate.rollout.prepare_step`
builds it, so no edge joins two sims), its own kinematic particles (their next position is its
data's), its own ``keep_in_domain`` and ``contact_correction`` corrections (with its own particle
radii; :func:`surrogate.rollout.correct_step`) and its own non-finite detection. The graphs of a
step are stacked with offset edge indices (:func:`surrogate.graph.stack_graphs`), the network
runs once on the union, and its output is split back per sim. Each message-passing round only
gathers along edges and every MLP works row by row, so each sim's prediction equals its single
rollout up to the rounding of the larger matrix products.

The sims advance in lock-step from the model's history K, B frames per network call (the model's
``bundle``); a sim leaves the batch after its last frame or its first non-finite one. What batching
saves is the per-call overhead of the network (Python, dispatch, small kernels) shared by the sims
of a step; the arithmetic is the same. The
simulator may be an :class:`surrogate.ensemble.Ensemble`, and each sim's graph is capped and counted
as in a single rollout where the model has a neighbour cap.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import torch

from surrogate import devices, samples
from surrogate.graph import stack_graphs
from surrogate.rollout import (
    Rollout,
    finish_step,
    kinematic_frames,
    new_counts,
    particle_radii,
    prepare_step,
    step_timing,
    store_frames,
)
from surrogate.runtime import Runtime
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator

if TYPE_CHECKING:
    from surrogate.ensemble import Ensemble


@torch.inference_mode()
def rollout_batch(simulator: LearnedSimulator | Ensemble, sims: list[Sim], runtime: Runtime,
                  n_frames: int | None = None, forced: bool = False) -> list[Rollout]:
    """One :class:`Rollout` per sim of ``sims`` (frames K .. ``n_frames``-1, default each sim's own
    count), computed together. ``runtime`` and ``forced`` as in :func:`surrogate.rollout.rollout` (the
    simulator prepared with :func:`surrogate.runtime.apply`).

    Timing: each rollout's ``seconds`` and ``seconds_network`` are its share (1/B) of the batch's wall
    time and network time (B sims); ``seconds_graph`` is its own graph building; ``timing`` adds
    ``batch_size`` and ``batch_seconds`` (the whole batch's wall time).
    """
    if not sims:
        return []
    k = simulator.history
    device = devices.of(simulator)
    dtype = runtime.network_dtype
    sims = [samples.to_device(sim, device) for sim in sims]
    totals = [sim.n_frames if n_frames is None else int(n_frames) for sim in sims]
    for sim, total in zip(sims, totals, strict=True):
        if sim.n_frames < k + 1 or total < k + 1:
            raise ValueError(f"{sim.path}: a rollout needs more than {k} frames, the sim has {sim.n_frames}")
        if forced and total > sim.n_frames:
            raise ValueError(f"{sim.path}: a forced rollout needs the data's frames, {sim.n_frames} < {total}")
    positions = []
    for sim, total in zip(sims, totals, strict=True):
        frames = torch.full((total, *sim.position.shape[1:]), float("nan"), dtype=dtype, device=device)
        frames[:k] = sim.position[:k]
        positions.append(frames)
    props = [None if sim.props is None else sim.props.to(dtype) for sim in sims]
    counts = [new_counts() for _ in sims]
    radii = [particle_radii(sim, runtime, dtype, device) for sim in sims]
    first_bad: list[int | None] = [None] * len(sims)
    t_graph = [0.0] * len(sims)
    t_network = 0.0
    start_clock = time.perf_counter()
    calls = [0] * len(sims)
    for t in range(k, max(totals), simulator.bundle):
        active = [i for i, total in enumerate(totals) if t < total and first_bad[i] is None]
        if not active:
            break
        steps = []
        for i in active:
            sim = sims[i]
            window = sim.position[t - k:t].to(dtype) if forced else positions[i][t - k:t]
            kinematic_next = kinematic_frames(sim, t, simulator.bundle, dtype)
            step = prepare_step(simulator, sim, window, kinematic_next, runtime, props[i], counts[i])
            t_graph[i] += step.seconds_graph
            steps.append(step)
        graph = stack_graphs([s.graph for s in steps])
        offsets = torch.tensor([0] + [s.graph.types.numel() for s in steps[:-1]]).cumsum(0).tolist()
        decode = None if steps[0].decode is None else torch.cat(
            [s.decode + offset for s, offset in zip(steps, offsets, strict=True)])
        t0 = time.perf_counter()
        with runtime.autocast(device):
            acceleration = simulator(graph, decode=decode).to(dtype)
        t_network += time.perf_counter() - t0
        rows = [s.graph.types.numel() if s.decode is None else s.decode.numel() for s in steps]
        for i, step, part in zip(active, steps, acceleration.split(rows), strict=True):
            frames = finish_step(simulator, step, part)
            calls[i] += 1
            before = sims[i].position[t - 1].to(dtype) if forced else positions[i][t - 1]   # the step's start
            first_bad[i] = store_frames(positions[i], t, frames, ~sims[i].kinematic, radii[i], runtime, simulator,
                                        counts[i], before)
    devices.synchronize(device)
    seconds = time.perf_counter() - start_clock
    size = len(sims)
    out = []
    for i in range(size):
        timing = {**step_timing(counts[i], max(calls[i], 1)), "batch_size": size, "batch_seconds": seconds}
        out.append(Rollout(positions[i].cpu().numpy(), k, first_bad[i], seconds / size, t_graph[i], timing,
                           t_network / size, simulator.n_models, simulator.max_neighbours))
    return out
