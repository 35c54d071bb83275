"""Rollout (article 5.4.4): from the first K frames of a sim, predict every later frame in turn.

Kinematic particles are never predicted: at every step their positions are taken from the data.
A model that predicts B frames per call (``model.bundle``, temporal bundling) advances B frames per
step; the last step keeps only the frames still wanted.
A rollout that produces a non-finite position stops there; the remaining frames are NaN and the
first bad frame is reported, never hidden.

After the network's step, the runtime's corrections apply to the moving particles in this order:
``keep_in_domain`` puts the particles that left the box back on its faces, then
``contact_correction`` stops the particles whose path from the frame before passed a kinematic
particle and pushes too-deep overlaps apart (keeping the particles in the box when
``keep_in_domain`` is on; :mod:`surrogate.correction`). Both act on the frame that the next step
reads, so the next step's velocities (position differences) are the corrected ones.

The simulator may be an :class:`surrogate.ensemble.Ensemble` (the mean acceleration of several models);
the rollout records how many models it ran (``Rollout.models``). With the model's neighbour cap
(``max_neighbours``), every step's graph keeps each receiver's nearest senders; the rollout counts the
receivers capped and the edges dropped over its steps (``timing``: ``capped`` and ``dropped``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from scipy.spatial import cKDTree

from generators import h5md
from surrogate import devices, samples
from surrogate.correction import correct_overlaps, stop_at_kinematic
from surrogate.graph import Graph, build_graph, neighbour_edges, prune_isolated
from surrogate.runtime import Runtime
from surrogate.samples import Sim
from surrogate.simulator import LearnedSimulator

if TYPE_CHECKING:
    from surrogate.ensemble import Ensemble


@dataclass
class Rollout:
    position: np.ndarray                 # [T, N, D] (float64 for a float64 rollout); frames < history are the data's
    history: int                         # frames given (G >= the model's K)
    first_nonfinite: int | None = None   # first frame with a non-finite position, None if clean
    seconds: float = 0.0                 # wall time of the predicted frames
    seconds_graph: float = 0.0           # of which building the radius graph
    timing: dict = field(default_factory=dict)
    seconds_network: float = 0.0         # of which the network's forward pass (on a GPU: the time to queue it)
    models: int = 1                      # models whose mean acceleration was integrated (an ensemble: several)
    max_neighbours: int | None = None    # the model's neighbour cap (null: none)

    @property
    def n_predicted(self) -> int:
        """Frames the model computed (up to and including a first non-finite one)."""
        end = self.position.shape[0] if self.first_nonfinite is None else self.first_nonfinite + 1
        return end - self.history


@dataclass
class Step:
    """One sim's network input of one step, and what turns the network's output into its next frame."""

    graph: Graph                    # what the network sees (pruned, when the runtime prunes)
    decode: torch.Tensor | None     # graph nodes decoded and integrated; None: every node (the unreduced graph)
    index: torch.Tensor             # particle of every graph node
    rest: torch.Tensor              # [B, N, D] next positions where nothing is predicted (kinematic: the data's)
    seconds_graph: float            # wall time of building it


def prepare_step(simulator: LearnedSimulator, sim: Sim, window: torch.Tensor, kinematic_next: torch.Tensor,
                 runtime: Runtime, props: torch.Tensor | None, counts: dict) -> Step:
    """The graph of one step of ``sim`` under ``runtime`` (on the window's last frame; ``kinematic_next`` ``[B, N, D]``
    holds the kinematic particles' next B positions), with sleeping
    particles and isolated unpredicted ones left out when the runtime switches say so; ``counts`` gets
    its nodes, edges, decoded and sleeping particles added."""
    t0 = time.perf_counter()
    if not (runtime.prune_isolated or runtime.sleep_speed is not None):
        graph = build_graph(window, sim.types, sim.kinematic, simulator.radius, props, runtime.skip_kinematic_pairs,
                            simulator.max_neighbours)
        seconds = time.perf_counter() - t0
        n = graph.types.numel()
        count_graph(counts, graph, n)
        return Step(graph, None, torch.arange(n, device=window.device), kinematic_next, seconds)
    last = window[-1]
    kinematic = sim.kinematic
    static = kinematic.clone()
    if runtime.sleep_speed is not None:
        speed = (window[1:] - window[:-1]).norm(dim=-1).amax(dim=0)
        resting = ~kinematic & (speed < runtime.sleep_speed)
        awake = ~kinematic & ~resting
        if resting.any() and awake.any():
            distance, _ = cKDTree(last[awake].double().cpu().numpy()).query(
                last[resting].double().cpu().numpy(), distance_upper_bound=simulator.radius)
            woken = torch.from_numpy(distance < simulator.radius).to(last.device)
            resting[resting.clone()] = ~woken
        static = kinematic | resting
        counts["asleep"] += int(resting.sum())
    edges = neighbour_edges(last, simulator.radius, static.cpu().numpy(), simulator.max_neighbours)
    graph = Graph(window, sim.types, static, edges.edge_index, props, edges.capped_receivers, edges.dropped_edges)
    if runtime.prune_isolated:
        graph, index = prune_isolated(graph)
    else:
        index = torch.arange(len(static), device=static.device)
    seconds = time.perf_counter() - t0
    moving = (~graph.kinematic).nonzero().squeeze(1)       # only these are decoded and integrated
    count_graph(counts, graph, len(moving), len(index))
    rest = torch.where(kinematic.unsqueeze(-1), kinematic_next, last)      # asleep: stays where it is
    return Step(graph, moving, index, rest, seconds)


def count_graph(counts: dict, graph: Graph, decoded: int, nodes: int | None = None) -> None:
    """Add one step's graph to a rollout's ``counts``: its nodes (default: the graph's), edges, decoded
    nodes, and the receivers the neighbour cap capped and the edges it dropped."""
    counts["nodes"] += graph.types.numel() if nodes is None else nodes
    counts["edges"] += graph.edge_index.shape[1]
    counts["decoded"] += decoded
    counts["capped"] += graph.capped_receivers
    counts["dropped"] += graph.dropped_edges


def finish_step(simulator: LearnedSimulator, step: Step, acceleration: torch.Tensor) -> torch.Tensor:
    """``[B, N, D]``: the next B positions of the step's sim from the network's accelerations of its decoded
    nodes (B = the model's bundle)."""
    if step.decode is None:
        return torch.where(step.graph.kinematic.unsqueeze(-1), step.rest,
                           simulator.integrate(step.graph.window, acceleration))
    nxt = step.rest
    nxt[:, step.index[step.decode]] = simulator.integrate(step.graph.window[:, step.decode], acceleration)
    return nxt


def particle_radii(sim: Sim, runtime: Runtime | None, dtype: torch.dtype, device: torch.device) -> torch.Tensor | None:
    """[N] radii of the sim's particles (its H5MD ``radius``) where the runtime corrects contacts, else None."""
    if runtime is None or runtime.contact_correction is None:
        return None
    return torch.as_tensor(np.asarray(sim.traj.radius, np.float64), dtype=dtype, device=device)


def correct_step(position: torch.Tensor, moving: torch.Tensor, radius: torch.Tensor | None, runtime: Runtime | None,
                 simulator: LearnedSimulator, counts: dict, previous: torch.Tensor | None = None) -> torch.Tensor:
    """The runtime's corrections of one predicted frame (module docstring): ``keep_in_domain``, then
    ``contact_correction`` (``radius`` from :func:`particle_radii`): the paths from ``previous`` (the
    frame before, where given) stopped at the kinematic particles they passed, then the sweeps;
    ``counts`` gets the particles put back into the box, the particles stopped and the pairs pushed
    apart added."""
    if runtime is None:
        return position
    if runtime.keep_in_domain:
        position, counts["clamped"] = keep_in_domain(position, moving, simulator.lower, simulator.upper,
                                                     counts["clamped"])
    if runtime.contact_correction is not None:
        box = (simulator.lower, simulator.upper) if runtime.keep_in_domain else (None, None)
        settings = runtime.contact_correction
        allowed = float(settings["allowed_overlap"])
        if previous is not None:
            position, stopped = stop_at_kinematic(previous, position, radius, moving, allowed, *box)
            counts["stopped"] += stopped
        position, found = correct_overlaps(position, radius, moving, allowed, int(settings["iterations"]), *box,
                                           tolerance=float(settings.get("tolerance", 0.0)))
        counts["corrected"] += found
    return position


def keep_in_domain(position: torch.Tensor, moving: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor,
                   clamped: int = 0) -> tuple[torch.Tensor, int]:
    """``position`` [N, D] with every moving particle outside the box ``[lower, upper]`` put back on
    the face it crossed (runtime switch ``keep_in_domain``); returns it and ``clamped`` plus the number
    of particles put back."""
    lo, hi = lower.to(position), upper.to(position)
    outside = moving & ((position < lo) | (position > hi)).any(dim=-1)
    if not outside.any():
        return position, clamped
    position = position.clone()
    position[outside] = torch.maximum(torch.minimum(position[outside], hi), lo)
    return position, clamped + int(outside.sum())


def kinematic_frames(sim: Sim, t: int, bundle: int, dtype: torch.dtype) -> torch.Tensor:
    """``[B, N, D]``: the data's positions of frames ``t .. t+B-1`` (B = ``bundle``), where the kinematic particles'
    next positions come from; beyond the recorded frames, the last one."""
    last = sim.n_frames - 1
    return torch.stack([sim.position[min(t + b, last)] for b in range(bundle)]).to(dtype)


def store_frames(positions: torch.Tensor, t: int, frames: torch.Tensor, moving: torch.Tensor,
                 radius: torch.Tensor | None, runtime: Runtime | None, simulator: LearnedSimulator, counts: dict,
                 before: torch.Tensor) -> int | None:
    """Write one network call's frames ``[B, N, D]`` into ``positions`` from frame ``t`` on (those past its end are
    dropped), each with the runtime's corrections (:func:`correct_step`, from the frame ``before`` it); the
    first non-finite frame's index, where one is met (it and the frames after it stay NaN), else None."""
    for b in range(min(frames.shape[0], positions.shape[0] - t)):
        if not torch.isfinite(frames[b]).all():
            return t + b
        positions[t + b] = correct_step(frames[b], moving, radius, runtime, simulator, counts, before)
        before = positions[t + b]
    return None


@torch.inference_mode()
def rollout(simulator: LearnedSimulator | Ensemble, sim: Sim, n_frames: int | None = None,
            runtime: Runtime | None = None, start: torch.Tensor | None = None, forced: bool = False,
            given: int | None = None) -> Rollout:
    """Predict frames ``G .. n_frames-1`` (default: as many frames as the sim has) from the first G.

    G is ``given``, by default the model's history K; a protocol may give more frames than the model
    reads (G > K: each step still sees the last K frames). ``runtime`` selects the switches of
    :mod:`surrogate.runtime` (the simulator must have been prepared with
    :func:`surrogate.runtime.apply`); None computes as in training. ``start`` replaces the first G
    frames (e.g. a perturbed history for a stability test). ``forced`` feeds every step the data's
    window instead of the predicted one (one-step predictions on the true graphs: how an untrained
    model of some size is timed on representative graphs). It runs on the simulator's device (the sim
    is copied there); the positions come back to the CPU.
    """
    k = simulator.history
    g = k if given is None else int(given)
    if g < k:
        raise ValueError(f"{sim.path}: the model reads K = {k} frames; a rollout given {g} cannot start it")
    total = sim.n_frames if n_frames is None else int(n_frames)
    if sim.n_frames < g + 1 or total < g + 1:
        raise ValueError(f"{sim.path}: a rollout needs more than {g} frames, the sim has {sim.n_frames}")
    if forced and total > sim.n_frames:
        raise ValueError(f"{sim.path}: a forced rollout needs the data's frames, {sim.n_frames} < {total}")
    device = devices.of(simulator)
    sim = samples.to_device(sim, device)
    dtype = runtime.network_dtype if runtime is not None else torch.float32
    positions = torch.full((total, *sim.position.shape[1:]), float("nan"), dtype=dtype, device=device)
    positions[:g] = sim.position[:g] if start is None else start.to(device)
    props = None if sim.props is None else sim.props.to(dtype)
    counts = new_counts()
    moving = ~sim.kinematic
    radius = particle_radii(sim, runtime, dtype, device)
    first_bad = None
    t_graph = t_network = 0.0
    start_clock = time.perf_counter()
    calls = 0
    for t in range(g, total, simulator.bundle):
        window = sim.position[t - k:t].to(dtype) if forced else positions[t - k:t]
        # beyond the recorded window, kinematic particles stay where the data left them
        kinematic_next = kinematic_frames(sim, t, simulator.bundle, dtype)
        if runtime is None:
            t0 = time.perf_counter()
            graph = build_graph(window, sim.types, sim.kinematic, simulator.radius, props,
                                max_neighbours=simulator.max_neighbours)
            t_graph += time.perf_counter() - t0
            count_graph(counts, graph, graph.types.numel())
            t0 = time.perf_counter()
            frames = simulator.step(graph, kinematic_next)
            t_network += time.perf_counter() - t0           # the step's pruning and integration included
        else:
            step = prepare_step(simulator, sim, window, kinematic_next, runtime, props, counts)
            t_graph += step.seconds_graph
            t0 = time.perf_counter()
            with runtime.autocast(device):
                acceleration = simulator(step.graph, decode=step.decode).to(dtype)
            t_network += time.perf_counter() - t0
            frames = finish_step(simulator, step, acceleration)
        calls += 1
        first_bad = store_frames(positions, t, frames, moving, radius, runtime, simulator, counts, window[-1])
        if first_bad is not None:
            break
    devices.synchronize(device)
    seconds = time.perf_counter() - start_clock
    steps = max(calls, 1)                                   # network calls made (B frames each)
    return Rollout(positions.cpu().numpy(), g, first_bad, seconds, t_graph, step_timing(counts, steps), t_network,
                   simulator.n_models, simulator.max_neighbours)


def new_counts() -> dict:
    """Zeroed per-rollout counters: sleeping particles, graph nodes, edges and decoded nodes summed over the
    steps, particles put back into the box, particles stopped at a kinematic particle and particle pairs
    pushed apart by the contact correction, and the receivers the neighbour cap capped and the edges it
    dropped."""
    return {"asleep": 0, "nodes": 0, "edges": 0, "decoded": 0, "clamped": 0, "stopped": 0, "corrected": 0,
            "capped": 0, "dropped": 0}


def step_timing(counts: dict, steps: int) -> dict:
    """A rollout's ``timing``: every count per computed step, and the totals of the particle-steps put back
    into the box, the particle-steps stopped at a kinematic particle and the pair-steps pushed apart by the
    contact correction, the receiver-steps capped and the edges dropped by the neighbour cap."""
    timing = {f"{name}_per_step": value / steps for name, value in counts.items()}
    for name in ("clamped", "stopped", "corrected", "capped", "dropped"):
        timing[name] = counts[name]
    return timing


def rollout_mse(predicted: np.ndarray, truth: np.ndarray, moving: np.ndarray, history: int) -> np.ndarray:
    """Per predicted frame: mean over moving particles of the squared Euclidean error (docs/surrogate.md)."""
    err = np.asarray(predicted, np.float64)[history:, moving] - np.asarray(truth, np.float64)[history:, moving]
    return (err**2).sum(axis=-1).mean(axis=-1)


def write(path, sim: Sim, result: Rollout, checkpoint_path, checkpoint_sha: str):
    """The predicted trajectory as H5MD, same layout as the sim, with the rollout's provenance.

    ``checkpoint_path`` is one path, or the list of an ensemble's (recorded separated by spaces, with
    ``rollout_models``); a rollout with a neighbour cap records it and its counts
    (``rollout_max_neighbours``, ``rollout_capped_receivers``, ``rollout_dropped_edges``)."""
    params = dict(sim.traj.parameters)
    paths = [checkpoint_path] if isinstance(checkpoint_path, str | Path) else list(checkpoint_path)
    params.update(source_sim=str(sim.path), rollout_checkpoint=" ".join(str(p) for p in paths),
                  rollout_checkpoint_sha=checkpoint_sha, rollout_history=result.history,
                  rollout_first_nonfinite=-1 if result.first_nonfinite is None else result.first_nonfinite,
                  rollout_wall_time=result.seconds, rollout_graph_time=result.seconds_graph,
                  rollout_seconds_per_frame=result.seconds / max(result.n_predicted, 1),
                  content="Graph-DEM rollout: frames < rollout_history are the data's, later frames predicted")
    if result.models > 1:
        params.update(rollout_models=result.models)
    if result.max_neighbours is not None:
        params.update(rollout_max_neighbours=result.max_neighbours,
                      rollout_capped_receivers=int(result.timing.get("capped", 0)),
                      rollout_dropped_edges=int(result.timing.get("dropped", 0)))
    traj = replace(sim.traj, position=result.position.astype(np.float32), parameters=params, observables={})
    return h5md.write(path, traj, allow_nonfinite=True)
