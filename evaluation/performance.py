"""The performance stage: run time against error (docs/performance.md): DEM contenders and surrogate contenders, timed
the same way on the same test sims, scored with the same metrics against the dataset.

* A DEM contender reruns the engine on the sims' own settled packings with changed settings
  (``dt_safety`` sets the time step as a fraction of the stable limit, ``dt_factor`` multiplies the
  data's, ``stiffness_factor`` the Young's modulus, the time step following the stable limit;
  ``cores``: LAMMPS' MPI ranks or YADE's threads; ``engine``: the other engine, from the same packing). Its time
  is the engine's own timing of
  the recorded window only; the run-up before the first frame and the process start-up (input,
  neighbour lists, output) are reported in their own columns, the settling on its own row.
* A surrogate contender rolls the trained checkpoint out with other runtime switches; a contender
  with sizes (``latent``, ``hidden``, ``message_passing``) is an untrained model of that size,
  timed only (its error is not reported) on the data's own windows (one-step predictions on the
  true graphs, so that it sees the graphs a trained model would). One untimed warm-up rollout per
  sim comes first. ``batch: N`` rolls the sims out N at a time as one disjoint graph per step
  (:func:`surrogate.batched.rollout_batch`; the sims repeated in turn to fill every batch), each
  sim's time being its batch's time / N; ``compile: true`` is the runtime switch.

Every contender's time is the median of ``repeats`` runs per sim, averaged over the sims.
Particle-frames per second count moving particles times predicted frames, summed over the sims,
per second summed over the sims.
"""

from __future__ import annotations

import copy
import json
import math
import resource
import statistics
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from evaluation.evaluate import MSE, score, summarise
from generators import blowup, convert, engine, engines, h5md, scenes
from surrogate import checkpoint, devices
from surrogate import runtime as rt
from surrogate.batched import rollout_batch
from surrogate.rollout import Rollout, rollout
from surrogate.samples import Sim, load_sim
from surrogate.simulator import LearnedSimulator

SIZE_KEYS = ("latent", "hidden", "message_passing")
# how a surrogate contender runs, not what it computes: torch threads (default: performance.threads), and the
# sims rolled out together (default 1)
SURROGATE_EXECUTION = ("threads", "batch")
DEM_KEYS = ("dt_safety", "dt_factor", "stiffness_factor", "cores", "engine")


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _scores(name: str, sims: list[tuple[str, h5md.Trajectory, np.ndarray]], history: int,
            body_displacement: float | None, frames: list[int] | None = None) -> dict:
    """MSE and Acc per scene metric of one contender's predictions over the sims."""
    steps = [rows for sim_id, traj, prediction in sims
             for rows in score(sim_id, traj, np.asarray(traj.position, np.float64), {name: prediction}, history,
                               body_displacement)]
    table = summarise(pd.concat(steps, ignore_index=True), frames)
    table = table[table["sim"] == "all"]
    out = {"mse": float(table.loc[table["metric"] == MSE, "mse"].iloc[0])}
    for row in table.itertuples():
        if pd.notna(row.acc_percent):
            out[f"acc_{row.metric}"] = float(row.acc_percent)
    return out


def dem_row(row: dict, variant: dict) -> dict:
    """The sweep row of a DEM contender: the time step ``dt_safety`` x the stable limit, or the data's
    times ``dt_factor``, and the stiffness times ``stiffness_factor`` (the step follows the stable limit,
    which scales as 1/sqrt(stiffness)), in ``engine`` (absent: the data's) from the same settled packing.
    ``cores`` changes how it runs, not the row."""
    unknown = set(variant) - set(DEM_KEYS)
    if unknown:
        raise ValueError(f"DEM contender: unknown keys {sorted(unknown)}; allowed: {', '.join(DEM_KEYS)}")
    if "dt_safety" in variant and "dt_factor" in variant:
        raise ValueError("DEM contender: give dt_safety (a fraction of the stable limit) or dt_factor (a multiple "
                         "of the data's step), not both")
    if row.get("dt") is not None:
        raise ValueError("DEM contenders scale dt_safety: the scene must not fix an explicit dt")
    safety = float(variant["dt_safety"]) if "dt_safety" in variant else \
        row["dt_safety"] * float(variant.get("dt_factor", 1.0))
    return {**row, "dt_safety": safety, "young": row["young"] * float(variant.get("stiffness_factor", 1.0)),
            "engine": variant.get("engine", row["engine"])}


def execution(variant: dict, engine_name: str) -> tuple[int, int]:
    """(MPI ranks, threads per process) of a DEM contender on ``cores`` cores: as MPI ranks or as threads of
    one process, as the engine's driver takes them (generators/engines.py; LAMMPS: ranks, YADE: threads)."""
    return engines.execution(engine_name, int(variant.get("cores", 1)))


def dem_contender(name: str, variant: dict, scene: str, rows: list[dict], packings: list[Path],
                  truths: list[Path], history: int, repeats: int, body_displacement: float | None = None,
                  frames: list[int] | None = None) -> dict:
    """Time and score one DEM contender on the sims of ``rows`` (truth in ``truths``)."""
    dem = scenes.get(scene)
    ranks, threads = execution(variant, variant.get("engine", rows[0]["engine"]))
    seconds, wall, steps_per_frame, per_step, peak, scored, work, blown = [], [], [], [], [], [], [], []
    startup, runup, dt_over_limit, particles, per_sim = [], [], [], [], {}
    for row, packing, truth_path in zip(rows, packings, truths, strict=True):
        truth = h5md.read(truth_path)
        runs = []
        with tempfile.TemporaryDirectory(prefix="graphdem-bench-") as scratch:
            for repeat in range(repeats):
                out = Path(scratch) / f"raw{repeat}"
                try:
                    meta = engine.simulate(dem, dem_row(row, variant), packing, out, ranks=ranks, threads=threads)
                except blowup.BlowUp as exc:
                    blown.append(f"{exc}")
                    break
                runs.append(meta)
            if len(runs) < repeats:
                continue
            h5 = convert.convert(Path(scratch) / "raw0", Path(scratch) / "run.h5")
            prediction = np.asarray(h5md.read(h5).position, np.float64)
        predicted = truth.n_frames - history
        # the recorded window covers frames 1..T-1: the predicted frames' share of its loop time
        seconds.append(statistics.median(m.window_seconds for m in runs) * predicted / (truth.n_frames - 1))
        per_step.append(statistics.median(m.window_seconds / m.window_steps for m in runs))
        wall.append(statistics.median(m.run.wall_time for m in runs))
        runup.append(statistics.median(m.run.runup_seconds or 0.0 for m in runs))
        # the process' time outside the engine's timed loops: start, input, neighbour lists, output
        startup.append(statistics.median(m.run.wall_time - m.window_seconds - (m.run.runup_seconds or 0.0)
                                         for m in runs))
        dt_over_limit.append(runs[0].dt / runs[0].dt_limit)
        particles.append(truth.n_particles)
        steps_per_frame.append(runs[0].steps_per_frame)
        peak.append(max(m.run.max_rss_mb for m in runs))
        scored.append((row["id"], truth, prediction))
        work.append((predicted, int((~np.asarray(truth.kinematic, bool)).sum())))
        per_sim[row["id"]] = {"seconds_per_frame": seconds[-1] / predicted, "steps_per_frame": steps_per_frame[-1],
                              "seconds_per_dem_step": per_step[-1], "particles": truth.n_particles,
                              "moving": work[-1][1]}
    out = {"contender": name, "kind": "dem", "settings": json.dumps(variant, sort_keys=True), "trained": True,
           "stable": not blown, "blown_up": " | ".join(blown), "sims": len(scored), "ranks": ranks,
           "threads": threads, "cores": ranks * threads, "per_sim": json.dumps(per_sim, sort_keys=True)}
    if not scored:
        return out
    per_rollout = float(np.mean(seconds))
    n_frames = sum(f for f, _ in work)
    out.update(seconds_per_rollout=per_rollout, seconds_per_frame=sum(seconds) / n_frames,
               particle_frames_per_second=sum(f * m for f, m in work) / sum(seconds), peak_rss_mb=max(peak),
               dem_steps_per_frame=float(np.mean(steps_per_frame)), seconds_per_dem_step=float(np.mean(per_step)),
               wall_seconds_per_run=float(np.mean(wall)), startup_seconds=float(np.mean(startup)),
               runup_seconds=float(np.mean(runup)), dt_over_limit=float(np.mean(dt_over_limit)),
               particles=float(np.mean(particles)),
               seconds_per_particle_step=float(np.mean([s / n for s, n in zip(per_step, particles, strict=True)])))
    out.update(_scores(name, scored, history, body_displacement, frames))
    return out


def surrogate_contender(name: str, variant: dict, checkpoint_path: Path, base: rt.Runtime, truths: list[Path],
                        repeats: int, threads: int, seed: int = 0, body_displacement: float | None = None,
                        frames: list[int] | None = None, device: str = "cpu") -> dict:
    """Time and score one surrogate contender (the trained checkpoint, or an untrained model of
    other sizes when ``variant`` has size keys) on the sims ``truths``, computed on ``device``
    (:mod:`surrogate.devices`; the row names the device it ran on)."""
    threads = int(variant.get("threads", threads))
    torch.set_num_threads(max(1, threads))
    simulator, meta = checkpoint.simulator_from(checkpoint_path, device)
    sizes = {k: variant[k] for k in SIZE_KEYS if k in variant}
    switches = {k: v for k, v in variant.items() if k not in SIZE_KEYS + SURROGATE_EXECUTION}
    runtime = rt.Runtime.from_config({**base.as_dict(), **switches})
    trained = not sizes
    if sizes:
        torch.manual_seed(seed)
        simulator = LearnedSimulator(meta["stats"], {**meta["model"], **sizes}).to(devices.of(simulator)).eval()
    simulator = rt.apply(copy.deepcopy(simulator), runtime)
    props = list(meta["model"].get("properties") or [])
    batch = int(variant.get("batch", 1))
    trajs = [h5md.read(path) for path in truths]
    sims = [load_sim(path, meta["stats"], props, traj) for path, traj in zip(truths, trajs, strict=True)]
    seconds, scored, blown, work, graph_share, edges, particles = [], [], [], [], [], [], []
    for traj, sim, (run, median, share) in zip(trajs, sims, timed_rollouts(simulator, sims, runtime, not trained,
                                                                          repeats, batch), strict=True):
        if run.first_nonfinite is not None:
            blown.append(f"{sim.id} non-finite from frame {run.first_nonfinite}")
        seconds.append(median)
        graph_share.append(share)
        timing = run.timing
        edges.append(timing["edges_per_step"])
        predicted = sim.n_frames - simulator.history
        particles.append(traj.n_particles)
        work.append((predicted, int((~sim.kinematic).sum()),
                     gflop_per_step({**meta["model"], **sizes}, sim.position.shape[-1], len(props),
                                    timing["nodes_per_step"], timing["edges_per_step"], runtime.split_edge_mlp,
                                    timing["decoded_per_step"])))
        scored.append((sim.id, traj, run.position))
    per_sim = {sim.id: {"seconds_per_frame": s / f, "particles": n, "moving": m}
               for sim, s, (f, m, _), n in zip(sims, seconds, work, particles, strict=True)}
    n_frames = sum(f for f, _, _ in work)
    gflop = sum(f * g for f, _, g in work)
    out = {"contender": name, "kind": "surrogate", "settings": json.dumps(variant, sort_keys=True),
           "trained": trained, "stable": not blown, "blown_up": " | ".join(blown), "sims": len(scored),
           "seconds_per_rollout": float(np.mean(seconds)), "seconds_per_frame": sum(seconds) / n_frames,
           "particle_frames_per_second": sum(f * m for f, m, _ in work) / sum(seconds),
           "peak_rss_mb": _peak_rss_mb(), "threads": threads, "cores": threads, "device": str(devices.of(simulator)),
           "batch": batch,
           "particles": float(np.mean(particles)),
           "seconds_per_particle_step": float(np.mean([s / (f * n) for s, (f, _, _), n
                                                       in zip(seconds, work, particles, strict=True)])),
           "runtime": json.dumps(runtime.as_dict(), sort_keys=True),
           "parameters": sum(p.numel() for p in simulator.parameters()), "edges_per_step": float(np.mean(edges)),
           "graph_building_share": float(np.mean(graph_share)), "gflop_per_frame": gflop / n_frames,
           "gflop_per_second": gflop / sum(seconds), "per_sim": json.dumps(per_sim, sort_keys=True)}
    if trained:
        out.update(_scores(name, scored, simulator.history, body_displacement, frames))
    return out


def timed_rollouts(simulator: LearnedSimulator, sims: list[Sim], runtime: rt.Runtime, forced: bool, repeats: int,
                   batch: int = 1) -> list[tuple[Rollout, float, float]]:
    """Per sim: its first timed rollout, the median of its ``repeats`` times per rollout and of its
    graph-building share. Alone (``batch`` 1) every sim has an untimed warm-up rollout first. With
    ``batch`` N, the sims are repeated in turn to fill groups of N, each group rolled out together
    (:func:`surrogate.batched.rollout_batch`, one warm-up first); a sim's time is its group's wall time / N."""
    if batch < 1:
        raise ValueError(f"surrogate contender: batch = {batch}, must be at least 1")
    if batch == 1:
        out = []
        for sim in sims:
            rollout(simulator, sim, runtime=runtime, forced=forced)                    # warm-up, untimed
            runs = [rollout(simulator, sim, runtime=runtime, forced=forced) for _ in range(repeats)]
            out.append((runs[0], statistics.median(r.seconds for r in runs),
                        statistics.median(r.seconds_graph / r.seconds for r in runs)))
        return out
    members = [sims[i % len(sims)] for i in range(batch * math.ceil(len(sims) / batch))]
    found: dict[int, tuple[Rollout, float, float]] = {}
    for start in range(0, len(members), batch):
        group = members[start:start + batch]
        rollout_batch(simulator, group, runtime, forced=forced)                        # warm-up, untimed
        runs = [rollout_batch(simulator, group, runtime, forced=forced) for _ in range(repeats)]
        median = statistics.median(r[0].timing["batch_seconds"] for r in runs) / batch
        for j in range(batch):
            share = statistics.median(r[j].seconds_graph / r[j].timing["batch_seconds"] for r in runs)
            found.setdefault((start + j) % len(sims), (runs[0][j], median, share))
    return [found[i] for i in range(len(sims))]


def gflop_per_step(model: dict, dim: int, n_props: int, nodes: float, edges: float, split: bool,
                   decoded: float | None = None) -> float:
    """Floating-point operations (2 per multiply-add) of one Graph-DEM step on a graph of ``nodes``
    and ``edges`` whose generator decodes ``decoded`` nodes (default all): the matrix products of
    every MLP (biases, norms and gathers left out)."""
    lat, hid, layers, k = int(model["latent"]), int(model["hidden"]), int(model["mlp_layers"]), int(model["history"])

    def mlp(n_in: int, n_out: int) -> int:
        return n_in * hid + (layers - 2) * hid * hid + hid * n_out

    node_in = (k - 1) * dim + int(model["embed"]) + n_props + 2 * dim
    first_edge = lat * hid if split else 3 * lat * hid
    per_updater = (edges * (first_edge + (layers - 2) * hid * hid + hid * lat) + (2 * nodes * lat * hid if split else 0)
                   + nodes * mlp(2 * lat, lat))
    macs = nodes * mlp(node_in, lat) + edges * mlp(dim + 1, lat) + int(model["message_passing"]) * per_updater \
        + (nodes if decoded is None else decoded) * mlp(lat, dim)
    return 2.0 * macs / 1e9


def pareto_front(table: pd.DataFrame) -> pd.Series:
    """True for contenders that no other contender beats in both time per rollout and MSE."""
    scored = table["mse"].notna() & table["seconds_per_rollout"].notna() & table["stable"].astype(bool)
    front = pd.Series(False, index=table.index)
    for i in table.index[scored]:
        t, e = table.at[i, "seconds_per_rollout"], table.at[i, "mse"]
        others = table[scored & (table.index != i)]
        dominated = ((others["seconds_per_rollout"] <= t) & (others["mse"] <= e)
                     & ((others["seconds_per_rollout"] < t) | (others["mse"] < e))).any()
        front[i] = not dominated
    return front


def _acc_columns(table: pd.DataFrame) -> list[str]:
    return [c for c in table.columns if c.startswith("acc_")]


def as_accurate(dem: pd.Series, surrogate: pd.Series, metrics: list[str]) -> bool:
    """True when a DEM contender's error against the reference is at most the surrogate's on the rollout
    MSE and on every scene metric (Acc at least the surrogate's; a metric the surrogate has no value
    for is not compared)."""
    if not dem["mse"] <= surrogate["mse"]:
        return False
    for column in metrics:
        if pd.notna(surrogate.get(column)) and not (pd.notna(dem.get(column)) and dem[column] >= surrogate[column]):
            return False
    return True


def report(contenders: pd.DataFrame, main: str, reference: str, settling_seconds: float | None) -> pd.DataFrame:
    """performance.csv: every contender with its Pareto flag, the speed-up over the DEM reference, the
    break-even number of DEM sub-steps per frame and the speed-ups over the fastest DEM contender that is
    as accurate (surrogate rows), plus the settling row.

    Two matches per surrogate contender: ``matched_dem`` is the fastest stable DEM contender at least as
    accurate on the rollout MSE *and* on every scene metric (the headline), ``matched_dem_by_mse`` the
    fastest on the MSE alone. ``break_even_substeps`` is the number of DEM steps per frame above which the
    reference engine setting (one core) is slower than the surrogate; ``break_even_substeps_fastest`` the
    same against the fastest DEM cost per step of any stable contender (more cores included)."""
    table = contenders.reset_index(drop=True).copy()
    ref = table[table["contender"] == reference]
    if ref.empty or pd.isna(ref["seconds_per_rollout"].iloc[0]):
        raise ValueError(f"the DEM reference contender {reference!r} is missing or blew up")
    ref = ref.iloc[0]
    if main not in set(table.loc[table["kind"] == "surrogate", "contender"]):
        raise ValueError(f"performance.main = {main!r} is not a surrogate contender; configured: "
                         f"{sorted(table.loc[table['kind'] == 'surrogate', 'contender'])}")
    table["on_pareto_front"] = pareto_front(table)
    table["speedup_vs_reference"] = ref["seconds_per_rollout"] / table["seconds_per_rollout"]
    surrogate = table["kind"] == "surrogate"
    metrics = _acc_columns(table)
    for column in ("break_even_substeps", "break_even_substeps_fastest", "speedup_vs_matched_dem",
                   "speedup_vs_matched_dem_by_mse"):
        table[column] = np.nan
    table["matched_dem"] = ""
    table["matched_dem_by_mse"] = ""
    dem = table[(table["kind"] == "dem") & table["mse"].notna() & table["stable"].astype(bool)]
    table.loc[surrogate, "break_even_substeps"] = (table.loc[surrogate, "seconds_per_frame"]
                                                   / ref["seconds_per_dem_step"])
    if not dem.empty:
        table.loc[surrogate, "break_even_substeps_fastest"] = (table.loc[surrogate, "seconds_per_frame"]
                                                               / dem["seconds_per_dem_step"].min())
    for i in table.index[surrogate & table["mse"].notna()]:
        row = table.loc[i]
        for suffix, matched in (("", dem[[as_accurate(d, row, metrics) for _, d in dem.iterrows()]]),
                                ("_by_mse", dem[dem["mse"] <= row["mse"]])):
            if matched.empty:
                continue
            fastest = matched.loc[matched["seconds_per_rollout"].idxmin()]
            table.at[i, f"matched_dem{suffix}"] = fastest["contender"]
            table.at[i, f"speedup_vs_matched_dem{suffix}"] = fastest["seconds_per_rollout"] / row["seconds_per_rollout"]
    table["main"] = table["contender"] == main
    if settling_seconds is not None:
        table = pd.concat([table, pd.DataFrame([{
            "contender": "dem_settling", "kind": "dem_settling", "settings": "prepare stage, once per packing",
            "trained": True, "stable": True, "wall_seconds_per_run": settling_seconds, "main": False}])],
            ignore_index=True)
    return table


def speedup_curve(table: pd.DataFrame, main: str, substeps: np.ndarray) -> pd.DataFrame:
    """The surrogate's speed-up over each stable DEM contender's cost per step as a function of the DEM
    sub-steps per frame: n x (s per DEM step) / (surrogate s per frame). The surrogate's cost per frame
    does not depend on the physical time per frame; the DEM's grows with the sub-steps it needs (stiffer
    contacts, smaller grains, longer frames)."""
    frame = table.loc[table["contender"] == main, "seconds_per_frame"].iloc[0]
    dem = table[(table["kind"] == "dem") & table["stable"].astype(bool) & table["seconds_per_dem_step"].notna()]
    rows = [{"contender": d["contender"], "substeps_per_frame": float(n),
             "speedup": float(n) * d["seconds_per_dem_step"] / frame} for _, d in dem.iterrows() for n in substeps]
    return pd.DataFrame(rows)
