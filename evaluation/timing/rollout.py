"""CPU cost per rollout frame of a trained surrogate, lever by lever: ``python -m evaluation.timing.rollout``.

Usage: ``python -m evaluation.timing.rollout --checkpoint results/slide/model/best.pt --data
results/slide/sims/slide_0003.h5 [--threads 1] [--out bench.csv]`` (the test sims are listed in
``results/<scene>/dataset/splits.csv``).

Protocol, in one process on the same sims, every variant a ratio to the eager one of the same run:

* workload: the sims of ``--data`` repeated in turn up to a multiple of the least common multiple of
  the batch sizes (8 rollouts for 1, 2, 4, 8 from one sim), every rollout from the model's K frames
  to the sim's last;
* ``eager``: one rollout at a time with the configured runtime switches (``--runtime-json``, by
  default the scene's ``runtime`` section) and ``compile`` off; ``compiled``: the same with
  ``compile`` on (:mod:`surrogate.runtime`); ``batch B``: the workload ``B`` sims at a time as one
  disjoint graph per step (:func:`surrogate.batched.rollout_batch`), and ``compiled, batch B`` for
  the largest ``B``; per-sim cost = batch time / batch size, so every row is seconds per rollout
  frame of one sim;
* ``R x f``: the same network on the graph of radius f x the checkpoint's R, every step on the
  data's window (forced: a graph of the data's particle layout at every step, as an untrained size is
  timed in the performance stage), the first row f = 1 being its reference. Timing only: the model
  was trained at its R, so its error at another R says nothing without retraining. Beside it, the
  contact-miss rate on the data (:mod:`surrogate.contacts`: the contacts at t+1 a graph at t of that
  radius lacks) and the graph's edges per particle;
* clock: the process's CPU time on one thread (the wall time of an unloaded machine, robust to other
  load on the machine), the wall time on more; one untimed warm-up run of every variant (it
  compiles: its wall time is ``warmup_s``), then ``--repeats`` repeats, the variants alternating
  order from one repeat to the next so that load affects all alike; the median per variant;
* shares of a step: graph building (neighbour search, pruning, sleeping), the network's forward
  pass, and the rest (Python, bookkeeping, integration, keep_in_domain), from the rollouts' own
  wall-clock split, median over the repeats.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from generators import config
from surrogate import checkpoint, contacts
from surrogate import runtime as rt
from surrogate.batched import rollout_batch
from surrogate.rollout import Rollout, rollout
from surrogate.samples import Sim, load_sim
from surrogate.simulator import LearnedSimulator

BATCHES = (1, 2, 4, 8)
RADIUS_FACTORS = (1.0, 0.8, 0.6)
LEVERS = ("compile", "batch", "radius")


@dataclass
class Variant:
    """One way of computing the workload: ``run`` returns its rollouts."""

    name: str
    lever: str                       # compile, batch or radius
    run: Callable[[], list[Rollout]]
    reference: str                   # the variant its ratio is taken to
    batch: int = 1
    radius: float | None = None


def scene_runtime(meta: dict) -> rt.Runtime:
    """The runtime section of the checkpoint's scene in the project config."""
    scene = meta["stats"].get("scene")
    section = config.load().get(scene) if scene else None
    if not isinstance(section, dict) or "runtime" not in section:
        raise SystemExit(f"the checkpoint's scene {scene!r} has no runtime section in the config; "
                         "give --runtime-json")
    return rt.Runtime.from_config(section["runtime"])


def one_at_a_time(simulator: LearnedSimulator, sims: list[Sim], runtime: rt.Runtime,
                  forced: bool = False) -> Callable[[], list[Rollout]]:
    return lambda: [rollout(simulator, sim, runtime=runtime, forced=forced) for sim in sims]


def in_batches(simulator: LearnedSimulator, sims: list[Sim], runtime: rt.Runtime,
               batch: int) -> Callable[[], list[Rollout]]:
    return lambda: [r for i in range(0, len(sims), batch) for r in rollout_batch(simulator, sims[i:i + batch], runtime)]


def variants(simulator: LearnedSimulator, sims: list[Sim], runtime: rt.Runtime, batches: list[int],
             radius_factors: list[float], levers: tuple[str, ...] = LEVERS) -> list[Variant]:
    """The variants of the protocol (module docstring) of the ``levers`` on the distinct ``sims``; the
    eager one always."""
    eager_rt, compiled_rt = replace(runtime, compile=False), replace(runtime, compile=True)
    eager = rt.apply(copy.deepcopy(simulator), eager_rt)
    unit = math.lcm(*batches)
    workload = [sims[i % len(sims)] for i in range(unit * math.ceil(len(sims) / unit))]
    out = [Variant("eager", "compile", one_at_a_time(eager, workload, eager_rt), "eager")]
    compiled = rt.apply(copy.deepcopy(simulator), compiled_rt) if "compile" in levers else None
    if compiled is not None:
        out.append(Variant("compiled", "compile", one_at_a_time(compiled, workload, compiled_rt), "eager"))
    if "batch" in levers:
        out += [Variant(f"batch {b}", "batch", in_batches(eager, workload, eager_rt, b), "eager", batch=b)
                for b in batches]
    if "batch" in levers and compiled is not None:
        largest = max(batches)
        out.append(Variant(f"compiled, batch {largest}", "batch",
                           in_batches(compiled, workload, compiled_rt, largest), "eager", batch=largest))
    reference = f"R x {radius_factors[0]:g}"
    for factor in radius_factors if "radius" in levers else ():
        smaller = copy.deepcopy(eager)
        smaller.radius = simulator.radius * factor
        out.append(Variant(f"R x {factor:g}", "radius", one_at_a_time(smaller, sims, eager_rt, forced=True),
                           reference, radius=smaller.radius))
    return out


def frames_of(rollouts: list[Rollout]) -> int:
    return sum(r.n_predicted for r in rollouts)


def time_variants(chosen: list[Variant], repeats: int, clock: Callable[[], float]) -> pd.DataFrame:
    """Per variant: the median seconds per rollout frame (and the fastest and slowest repeat), the median
    shares of a step, the warm-up's wall time and the network's edges per step."""
    warmup = {}
    for v in chosen:
        t0 = time.perf_counter()
        v.run()
        warmup[v.name] = time.perf_counter() - t0
    per_frame: dict[str, list[float]] = {v.name: [] for v in chosen}
    shares: dict[str, list[tuple[float, float]]] = {v.name: [] for v in chosen}
    edges: dict[str, float] = {}
    for r in range(repeats):
        for v in chosen if r % 2 == 0 else chosen[::-1]:
            t0 = clock()
            rollouts = v.run()
            per_frame[v.name].append((clock() - t0) / frames_of(rollouts))
            wall = sum(x.seconds for x in rollouts)
            shares[v.name].append((sum(x.seconds_graph for x in rollouts) / wall,
                                   sum(x.seconds_network for x in rollouts) / wall))
            edges[v.name] = float(np.mean([x.timing["edges_per_step"] for x in rollouts]))
    rows = []
    for v in chosen:
        graph = statistics.median(s[0] for s in shares[v.name])
        network = statistics.median(s[1] for s in shares[v.name])
        rows.append({"variant": v.name, "lever": v.lever, "batch": v.batch, "radius": v.radius,
                     "seconds_per_frame": statistics.median(per_frame[v.name]),
                     "seconds_per_frame_min": min(per_frame[v.name]), "seconds_per_frame_max": max(per_frame[v.name]),
                     "graph_share": graph,
                     "network_share": network, "rest_share": 1.0 - graph - network, "warmup_s": warmup[v.name],
                     "edges_per_step": edges[v.name]})
    table = pd.DataFrame(rows)
    seconds = dict(zip(table["variant"], table["seconds_per_frame"], strict=True))
    table["ratio_to_reference"] = [seconds[v.reference] / seconds[v.name] for v in chosen]
    table["reference"] = [v.reference for v in chosen]
    return table


def radius_columns(table: pd.DataFrame, sims: list[Sim], chosen: list[Variant]) -> pd.DataFrame:
    """The contact-miss rate and edges per particle (before pruning) on the data at each R of the radius rows."""
    table = table.copy()
    table["contact_miss_rate"] = np.nan
    table["edges_per_particle"] = np.nan
    for i, v in zip(table.index, chosen, strict=True):
        if v.radius is None:
            continue
        counts = [contacts.contact_misses(sim.position.numpy(), sim.traj.radius, v.radius, sim.kinematic.numpy())
                  for sim in sims]
        missed, total = (sum(c) for c in zip(*counts, strict=True))
        table.at[i, "contact_miss_rate"] = missed / total if total else np.nan
        table.at[i, "edges_per_particle"] = float(np.mean([
            contacts.edges_per_particle(sim.position.numpy(), v.radius, sim.kinematic.numpy()) for sim in sims]))
    return table


def markdown(table: pd.DataFrame) -> str:
    """The table as Markdown, times in ms per frame."""
    lines = ["| variant | ms per frame (min-max) | ratio | graph / network / rest (%) | warm-up (s) | edges per step "
             "| contact-miss rate | edges per particle |", "| --- " * 8 + "|"]
    for row in table.itertuples():
        miss = "" if pd.isna(row.contact_miss_rate) else f"{100 * row.contact_miss_rate:.2f} %"
        per_particle = "" if pd.isna(row.edges_per_particle) else f"{row.edges_per_particle:.1f}"
        lines.append(f"| {row.variant} | {1e3 * row.seconds_per_frame:.3f} ({1e3 * row.seconds_per_frame_min:.2f}-"
                     f"{1e3 * row.seconds_per_frame_max:.2f}) | {row.ratio_to_reference:.2f}x vs "
                     f"{row.reference} | {100 * row.graph_share:.0f} / {100 * row.network_share:.0f} / "
                     f"{100 * row.rest_share:.0f} | {row.warmup_s:.1f} | {row.edges_per_step:.0f} | {miss} "
                     f"| {per_particle} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", type=Path, required=True, help="a best.pt written by train")
    parser.add_argument("--data", type=Path, nargs="+", required=True, help="H5MD sims (the scene's test sims)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1; rollouts use 1)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats per variant after the warm-up")
    parser.add_argument("--batches", type=int, nargs="+", default=list(BATCHES), help="batch sizes")
    parser.add_argument("--radius-factors", type=float, nargs="+", default=list(RADIUS_FACTORS),
                        help="R as multiples of the checkpoint's (the first is the reference of the radius rows)")
    parser.add_argument("--levers", nargs="+", choices=LEVERS, default=list(LEVERS),
                        help="the levers to time (default all; the eager rows always)")
    parser.add_argument("--runtime-json", type=json.loads,
                        help="runtime switches (JSON, surrogate/runtime.py); default: the scene's runtime section")
    parser.add_argument("--out", type=Path, help="write the table as CSV here")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    simulator, meta = checkpoint.simulator_from(args.checkpoint, "cpu")
    runtime = rt.Runtime.from_config(args.runtime_json) if args.runtime_json else scene_runtime(meta)
    props = list(meta["model"].get("properties") or [])
    sims = [load_sim(path, meta["stats"], props) for path in args.data]
    clock = time.process_time if args.threads == 1 else time.perf_counter
    model = {k: meta["model"][k] for k in ("latent", "hidden", "message_passing", "history")}
    print(f"torch {torch.__version__}, {args.threads} thread(s), {'CPU' if args.threads == 1 else 'wall'} time, "
          f"median of {args.repeats} after a warm-up; {len(sims)} sim(s) of "
          f"{', '.join(f'{s.position.shape[1]} particles x {s.n_frames} frames' for s in sims)}; model {model}, "
          f"R = {simulator.radius:g}; runtime {json.dumps(runtime.as_dict())}", flush=True)
    chosen = variants(simulator, sims, runtime, args.batches, args.radius_factors, tuple(args.levers))
    table = radius_columns(time_variants(chosen, args.repeats, clock), sims, chosen)
    table.insert(0, "checkpoint", str(args.checkpoint))
    print(markdown(table))
    print("Batch B: seconds per frame of one sim (batch time / B). R x f: forced rollouts (the data's window every "
          "step), timing only: the model was trained at R x 1, so its error at another R is not meaningful "
          "without retraining.")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.out, index=False)
        print(f"{args.out}: {len(table)} rows")


if __name__ == "__main__":
    main()
