"""Evaluation (docs/surrogate.md): rollout MSE and the scene metrics of truth, Graph-DEM, the
constant-velocity baseline and, where given, the DEM ensemble (the same sims rerun by their engine from a
perturbed state: the chaos floor), computed by the same code, written to metrics.csv and
metrics_per_step.csv with the checkpoint, config digest and code version they came from; the config itself is
written once, beside metrics.csv (:mod:`evaluation.config_sidecar`)."""

from __future__ import annotations

import logging
import subprocess
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from tqdm import tqdm

from evaluation import config_sidecar
from evaluation.baseline import constant_velocity
from evaluation.metrics import of_scene, plausibility
from evaluation.metrics.scores import Intervals
from evaluation.stored import read_ensemble, read_rollout
from evaluation.summary import summarise
from evaluation.tables import read_csv
from generators import h5md
from generators.atomic import Outputs, atomic_outputs
from surrogate import ensemble, provenance
from surrogate.provenance import as_paths
from surrogate.rollout import rollout, rollout_mse
from surrogate.runtime import Runtime
from surrogate.runtime import apply as apply_runtime
from surrogate.samples import data_files, load_sim

log = logging.getLogger("graphdem.evaluate")

MODEL, BASELINE, ENSEMBLE, ENSEMBLE_MEAN = "graphdem", "constant_velocity", "dem_ensemble", "dem_ensemble_mean"
MSE = "rollout MSE"
SECONDS = "seconds per frame"
# per-step columns that hold values (not provenance): the mean rows of metrics_per_step.csv leave them blank
STEP_VALUES = ("truth", "prediction", "blown_up", "member", "truth_start", "spread", "diameter")
# rows of a model with a neighbour cap: per predicted frame, the receivers it capped and the edges it dropped
CAPPED, DROPPED = "capped receivers per frame", "dropped edges per frame"
# the units of the rows these names make (the metrics' own: evaluation.metrics.units)
UNITS = {SECONDS: "s", CAPPED: "receivers", DROPPED: "edges"}


@dataclass
class Evaluated:
    """One test sim: its truth and the predictions (Graph-DEM, constant velocity, the DEM ensemble), all
    [T, N, D]."""

    id: str
    traj: h5md.Trajectory
    truth: np.ndarray
    predictions: dict[str, np.ndarray]
    first_nonfinite: dict[str, int | None]
    seconds_per_frame: float = float("nan")   # Graph-DEM wall time per predicted frame
    capped_per_frame: float = float("nan")    # receivers the neighbour cap capped per predicted frame (NaN: no cap)
    dropped_per_frame: float = float("nan")   # edges the neighbour cap dropped per predicted frame
    members: list[np.ndarray] = field(default_factory=list)   # the DEM ensemble's members, each [T, N, D]


def code_version() -> str:
    """Package version plus the git commit of the source tree, when the packages are a git checkout's own (an
    installed wheel has none: its site-packages may lie inside some other repository, whose commit is not ours)."""
    root = Path(__file__).resolve().parent.parent
    try:
        top = subprocess.run(["git", "-C", str(root), "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        if Path(top).resolve() != root:
            return h5md.CREATOR_VERSION
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return f"{h5md.CREATOR_VERSION}+{commit}{'.dirty' if dirty else ''}"
    except (OSError, subprocess.SubprocessError):
        return h5md.CREATOR_VERSION


def evaluation_split(splits: pd.DataFrame, choice: str) -> tuple[str, list[Path], str]:
    """The split to evaluate on, its sims, and a note saying so where it is not a held-out test split.

    ``choice`` is ``test``, ``valid`` or ``auto`` (test where the table has test sims, else valid).
    """
    if choice not in ("auto", "test", "valid"):
        raise ValueError(f"evaluation split {choice!r} is not allowed; allowed: auto, test, valid")
    present = set(splits["split"])
    split = ("test" if "test" in present else "valid") if choice == "auto" else choice
    if split not in present:
        raise ValueError(f"the split table has no {split} sims (it has {sorted(present)})")
    note = ""
    if split == "valid":
        why = "the source has no test split" if "test" not in present else "chosen although a test split exists"
        note = (f"evaluated on the valid split ({why}); valid also chose the best epoch, so these figures are "
                f"slightly optimistic")
    return split, [Path(p) for p in splits.loc[splits["split"] == split, "path"]], note


def blown_up_from(prediction: np.ndarray, traj: h5md.Trajectory, history: int) -> int | None:
    """The first predicted frame at which the rollout has blown up: a moving particle non-finite, or farther
    outside the box than the box is long on that axis (no granular flow goes there); None if it never does."""
    moving = ~np.asarray(traj.kinematic, bool)
    p = np.asarray(prediction, np.float64)[history:, moving]
    lower, upper = np.asarray(traj.box_lower, np.float64), np.asarray(traj.box_upper, np.float64)
    extent = upper - lower
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(p).all(axis=(1, 2)) | ((p < lower - extent) | (p > upper + extent)).any(axis=(1, 2))
    return int(history + np.argmax(bad)) if bad.any() else None


def _per_step(scene: str, method: str, sim: str, metric: str, times: np.ndarray, truth, prediction, k: int,
              blown: int | None = None, member: int = 0, start: float = float("nan"), spread=None,
              diameter: float = float("nan")):
    """Rows of one metric; from frame ``blown`` on (a blown-up rollout) the prediction is NaN and flagged.
    ``member``: which DEM ensemble member (0 for any other method); ``start``: the truth at the last given
    frame; ``spread``: the DEM ensemble members' spread per frame (NaN: no ensemble); ``diameter``: the sim's
    mean diameter of the moving particles."""
    n = len(prediction)
    frame = np.arange(k, k + n)
    flagged = np.zeros(n, bool) if blown is None else frame >= blown
    return pd.DataFrame({"scene": scene, "method": method, "sim": sim, "metric": metric, "member": member,
                         "tau": np.arange(1, n + 1), "frame": frame, "time": times[k:k + n],
                         "truth": np.nan if truth is None else truth,
                         "prediction": np.where(flagged, np.nan, np.asarray(prediction, np.float64)),
                         "blown_up": flagged, "truth_start": start,
                         "spread": np.nan if spread is None else spread, "diameter": diameter})


def member_spreads(members: list[np.ndarray], member_values: list[dict[str, np.ndarray]], moving: np.ndarray,
                   history: int) -> dict[str, np.ndarray]:
    """The DEM ensemble members' spread per predicted frame: for the rollout MSE the members' positional variance
    about their mean (m², mean over moving particles of the summed per-axis sample variance), for every scene metric
    the members' sample standard deviation of it (NaN where fewer than two members define it)."""
    if len(members) < 2:
        return {}
    stack = np.stack([np.asarray(m, np.float64)[history:, moving] for m in members])       # [M, T, n, D]
    out = {MSE: stack.var(axis=0, ddof=1).sum(axis=-1).mean(axis=-1)}
    for name in member_values[0]:
        values = np.stack([v[name][history:] for v in member_values])                       # [M, T]
        defined = np.isfinite(values).sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            out[name] = np.where(defined >= 2, np.nanstd(values, axis=0, ddof=1), np.nan)
    return out


def _runs(predictions: dict[str, np.ndarray], members: list[np.ndarray] | None) -> list[tuple[str, int, np.ndarray]]:
    """(method, member, positions) of every prediction scored: the given methods, each DEM ensemble member and
    the members' mean trajectory."""
    runs = [(method, 0, prediction) for method, prediction in predictions.items()]
    if members:
        runs += [(ENSEMBLE, j, member) for j, member in enumerate(members)]
        runs.append((ENSEMBLE_MEAN, 0, np.mean(np.stack(members), axis=0)))
    return runs


def score(sim: str, traj: h5md.Trajectory, truth: np.ndarray, predictions: dict[str, np.ndarray], history: int,
          body_displacement: float | None = None, members: list[np.ndarray] | None = None,
          generic: bool = False) -> list[pd.DataFrame]:
    """Per-step rows of sim ``sim``: rollout MSE and the scene's metrics of every prediction
    (method name -> [T, N, D]) over the frames after the first ``history``; ``members``, the DEM ensemble's
    reruns started at the last given frame, are scored one by one (method dem_ensemble, each its member index)
    and as their mean trajectory (dem_ensemble_mean), and give every row the members' spread. ``generic``: the
    generic metrics only, whatever scene the sims name (user data): rollout MSE and plausibility (overlaps,
    particles outside the box and through a wall, kinetic energy). Plausibility comes with a scene's metrics too;
    data of no registered scene, not generic, gets the rollout MSE alone."""
    scene = str(traj.parameters.get("scene", "unknown"))
    moving = ~np.asarray(traj.kinematic, bool)
    diameter = float(2.0 * np.mean(np.asarray(traj.radius, np.float64)[moving])) if moving.any() else float("nan")
    cls = None if generic else of_scene(scene)
    metrics = cls.for_trajectory(traj, body_displacement) if cls is not None else None
    plausible = generic or metrics is not None
    truth_values = metrics(truth) if metrics else {}
    truth_plausibility = plausibility.of_trajectory(truth, traj) if plausible else {}
    spreads = member_spreads(members or [], [metrics(m) for m in members] if metrics and members else
                             [{} for _ in members or []], moving, history)
    rows = []
    for method, member, prediction in _runs(predictions, members):
        blown = blown_up_from(prediction, traj, history)
        common = dict(blown=blown, member=member, diameter=diameter)
        with np.errstate(invalid="ignore", over="ignore"):
            rows.append(_per_step(scene, method, sim, MSE, traj.time, None,
                                  rollout_mse(prediction, truth, moving, history), history,
                                  spread=spreads.get(MSE), **common))
            if not plausible:
                continue
            for name, values in (metrics(prediction) if metrics else {}).items():
                rows.append(_per_step(scene, method, sim, name, traj.time, truth_values[name][history:],
                                      values[history:], history, start=float(truth_values[name][history - 1]),
                                      spread=spreads.get(name), **common))
            for name, values in (metrics.compare(prediction, truth) if metrics else {}).items():
                rows.append(_per_step(scene, method, sim, name, traj.time, None, values[history:], history, **common))
            for name, values in plausibility.of_trajectory(prediction, traj).items():
                rows.append(_per_step(scene, method, sim, name, traj.time, truth_plausibility[name][history:],
                                      values[history:], history,
                                      start=float(truth_plausibility[name][history - 1]), **common))
    return rows


def evaluate(checkpoint_path: Path | list[Path], data: list[Path], history: int, rollouts_dir: Path | None = None,
             body_displacement: float | None = None, frames: list[int] | None = None,
             ensemble_dir: Path | list[Path] | None = None, threads: int = 1,
             progress: bool = True,
             split: str = "test", split_note: str = "", runtime: Runtime | None = None,
             allow_other_scene: bool = False,
             device: str = "cpu", intervals: Intervals | None = None
             ) -> tuple[pd.DataFrame, pd.DataFrame, list[Evaluated], object]:
    """Metrics table, per-step table, the evaluated sims of a checkpoint on H5MD sims and the configuration the
    rows' ``config_sha`` names (:mod:`evaluation.config_sidecar`; :func:`write` puts it beside the table).

    ``ensemble_dir``: the DEM ensemble's member folders (one or several), ``<sim id>.h5`` per sim in each, every
    member restarted from the sim's state at its last given frame; scored one by one (dem_ensemble) and as their
    mean (dem_ensemble_mean). The constant-velocity baseline is rolled out with the same ``runtime`` as the model
    (:mod:`evaluation.baseline`). ``intervals``: the bootstrap of every figure (default: the config's).
    ``frames``: the taus of the article-style Acc (every predicted frame when None). ``split`` and ``split_note``
    name the split the sims come from in every row written; ``runtime``
    sets the switches of rollouts made here (:mod:`surrogate.runtime`), on ``device``
    (:mod:`surrogate.devices`).

    Several checkpoints are scored as one model, their :class:`surrogate.ensemble.Ensemble`: the rows name
    every checkpoint (``checkpoint``, separated by spaces; ``checkpoint_sha``, joined by '+'), and the
    seconds per frame are the ensemble's. A model with a neighbour cap adds the rows ``capped receivers per
    frame`` and ``dropped edges per frame`` (means over the sims). A model trained on user data (its stats.json
    records ``user_data``, docs/user-data.md) is scored by the generic metrics only (:func:`score`).
    """
    torch.set_num_threads(max(1, int(threads)))
    simulator, metas = ensemble.load(checkpoint_path, device)
    meta = metas[0]
    name = provenance.label(checkpoint_path)
    if runtime is not None:
        apply_runtime(simulator, runtime)
    if int(history) < int(meta["model"]["history"]):
        raise ValueError(f"{name} reads a history of K = {meta['model']['history']} frames; "
                         f"--history {history} gives fewer (allowed: {meta['model']['history']} or more)")
    sha = provenance.digest(checkpoint_path)
    cap = simulator.max_neighbours
    props = list(meta["model"].get("properties") or [])
    generic = "user_data" in meta["stats"]
    per_step, sims = [], []
    member_dirs = [] if ensemble_dir is None else as_paths(ensemble_dir)
    box = (simulator.lower.double().cpu().numpy(), simulator.upper.double().cpu().numpy())
    for path in tqdm(data_files(data), desc="evaluate", unit="sim", disable=not progress):
        traj = h5md.read(path)
        sim = load_sim(path, meta["stats"], props, traj, allow_other_scene)
        pred, bad, seconds, capped, dropped = _prediction(simulator, sim, traj, rollouts_dir, sha, history, runtime)
        truth = np.asarray(traj.position, np.float64)
        baseline = constant_velocity(truth, traj.kinematic, history, runtime, box, traj.radius)
        predictions, nonfinite = {MODEL: pred, BASELINE: baseline}, {MODEL: bad, BASELINE: None}
        members = [read_ensemble(Path(folder) / f"{sim.id}.h5", traj, history) for folder in member_dirs]
        entry = Evaluated(sim.id, traj, truth, predictions, nonfinite, seconds, capped, dropped, members)
        if bad is not None:
            log.warning("%s: the Graph-DEM rollout is non-finite from frame %d on (counted, not skipped)", sim.id, bad)
        sims.append(entry)
        per_step.extend(score(sim.id, traj, truth, entry.predictions, history, body_displacement, members,
                              generic=generic))
    if not sims:
        raise ValueError(f"no H5MD sims to evaluate in {', '.join(map(str, data))}")
    steps = pd.concat(per_step, ignore_index=True)
    table = summarise(steps, frames, intervals)
    timing = _timing_rows(str(table["scene"].iloc[0]), sims, cap is not None)
    table = pd.concat([table, pd.DataFrame(timing).reindex(columns=table.columns)], ignore_index=True)
    config = config_sidecar.config_of(metas)
    recorded = {"split": split, "split_note": split_note, "history": int(history),
                "checkpoint": name, "checkpoint_sha": sha, "config_sha": config_sidecar.digest(config),
                "code_version": code_version()}
    for df in (table, steps):
        for key, value in recorded.items():
            df[key] = value
    return table, steps, sims, config


def _prediction(simulator, sim, traj: h5md.Trajectory, rollouts_dir: Path | None, sha: str, history: int,
                runtime: Runtime | None) -> tuple[np.ndarray, int | None, float, float, float]:
    """Graph-DEM's positions of a sim, read from ``rollouts_dir`` (made by checkpoint ``sha``) or rolled out now,
    with its first non-finite frame, seconds per predicted frame and the neighbour cap's counts per frame."""
    if rollouts_dir is None:
        result = rollout(simulator, sim, runtime=runtime, given=history)
        n = max(result.n_predicted, 1)
        return (result.position, result.first_nonfinite, result.seconds / n, result.timing["capped"] / n,
                result.timing["dropped"] / n)
    predicted = read_rollout(Path(rollouts_dir) / f"{sim.id}.h5", sha, history)
    if predicted.position.shape != traj.position.shape:
        raise ValueError(f"{rollouts_dir}/{sim.id}.h5: shape {predicted.position.shape} differs from the "
                         f"sim's {traj.position.shape}")
    bad = predicted.parameters.get("rollout_first_nonfinite")
    bad = None if bad in (None, "null", -1) else int(bad)
    computed = max((traj.n_frames if bad is None else bad + 1) - history, 1)      # frames predicted
    capped, dropped = (float(predicted.parameters.get(key, np.nan)) / computed
                       for key in ("rollout_capped_receivers", "rollout_dropped_edges"))
    return (np.asarray(predicted.position, np.float64), bad,
            float(predicted.parameters.get("rollout_seconds_per_frame", np.nan)), capped, dropped)


def _timing_rows(scene: str, sims: list[Evaluated], capped: bool) -> list[dict]:
    """Graph-DEM's seconds per predicted frame and, with a neighbour cap, its counts per frame (means over sims)."""
    rows = [{"scene": scene, "method": MODEL, "metric": SECONDS, "unit": UNITS[SECONDS], "sim": "all",
             "mean_prediction": float(np.mean([s.seconds_per_frame for s in sims])), "n_sims": len(sims)}]
    if capped:
        rows += [{"scene": scene, "method": MODEL, "metric": metric, "unit": UNITS[metric], "sim": "all",
                  "mean_prediction": float(np.mean([getattr(s, field) for s in sims])), "n_sims": len(sims)}
                 for metric, field in ((CAPPED, "capped_per_frame"), (DROPPED, "dropped_per_frame"))]
    return rows


def mean_per_step(steps: pd.DataFrame) -> pd.DataFrame:
    """Per method, metric and tau: truth and prediction averaged over sims (``sim = all`` rows)."""
    keys = ["scene", "method", "metric", "tau", "frame"] + (["history"] if "history" in steps.columns else [])
    grouped = steps.groupby(keys, sort=False)
    mean = grouped[["time", "truth"]].mean().reset_index()                   # truth NaN: no body, skipped
    mean["prediction"] = grouped["prediction"].mean(skipna=False).to_numpy()  # a blow-up stays visible
    mean.insert(2, "sim", "all")
    return mean


def write(table: pd.DataFrame, steps: pd.DataFrame, out_csv: Path, per_step_csv: Path | None,
          output: Outputs | None = None, config: object = None) -> Path:
    """The metrics table at ``out_csv``, the ``config`` its rows' ``config_sha`` names beside it
    (:func:`evaluation.config_sidecar.path_of`) and, if given, the per-step table (the mean over sims first) at
    ``per_step_csv``; all or none. A table with ``config_sha`` needs that config. With ``output``
    (generators.atomic.atomic_outputs) they are staged in that group, appearing only with its other outputs.
    Returns where the metrics CSV is (its temporary while staged)."""
    if output is None:
        with atomic_outputs() as group:
            write(table, steps, out_csv, per_step_csv, group, config)
        return Path(out_csv)
    shas = list(dict.fromkeys(table["config_sha"].dropna().astype(str))) if "config_sha" in table else []
    if shas and (config is None or shas != [config_sidecar.digest(config)]):
        given = "no config" if config is None else f"the config {config_sidecar.digest(config)}"
        raise ValueError(f"{out_csv}: its rows name config_sha {', '.join(shas)}, and {given} was given to write "
                         "beside it; write one evaluation's table with its own config")
    with output(Path(out_csv)) as metrics:
        table.to_csv(metrics, index=False)
    if shas:
        config_sidecar.write(out_csv, config, output)
    if per_step_csv is not None:
        mean = mean_per_step(steps)
        # the provenance columns (the same in every row), not the keys of the mean: under several protocols the
        # mean rows keep their own history
        extra = [c for c in steps.columns if c not in (*STEP_VALUES, *mean.columns)]
        both = pd.concat([mean.assign(**{c: steps[c].iloc[0] for c in extra}), steps], ignore_index=True)
        with output(Path(per_step_csv)) as tmp:
            both.to_csv(tmp, index=False)
    return metrics


def combine(paths: list[Path], union: bool = False) -> pd.DataFrame:
    """Tables of the same layout (e.g. one metrics.csv per protocol) stacked in the given order;
    with ``union``, tables of different columns (blank where a table has no such column)."""
    tables = [read_csv(p) for p in paths]
    if not tables:
        raise ValueError("nothing to combine: no tables given")
    if union:
        return pd.concat(tables, ignore_index=True)
    for path, table in zip(paths, tables, strict=True):
        if list(table.columns) != list(tables[0].columns):
            raise ValueError(f"{path}: columns {list(table.columns)} differ from {paths[0]}'s "
                             f"{list(tables[0].columns)}")
    return pd.concat(tables, ignore_index=True)


def report(table: pd.DataFrame) -> str:
    """A short human-readable summary (printed by ``graphdem evaluate``)."""
    lines = []
    overall = table[table["sim"] == "all"]
    for _, row in overall.iterrows():
        if row["metric"] == SECONDS:
            value = f"{1000 * row['mean_prediction']:.1f} ms per predicted frame (wall time, mean over sims)"
        elif row["metric"] in (CAPPED, DROPPED):
            value = f"{row['mean_prediction']:.4g} (neighbour cap; mean over sims)"
        elif row["metric"] == MSE:
            value = f"{row['mse']:.4g} m^2"
            if row["n_blown_up"]:
                value += f" ({int(row['n_blown_up'])} blown up: {row['blown_up_sims']})"
        elif row.get("n_blown_up", 0) and row["metric"] != MSE and pd.isna(row["mean_prediction"]):
            value = f"undefined: {int(row['n_blown_up'])} rollout(s) blew up ({row['blown_up_sims']})"
        elif pd.notna(row["acc_percent"]):
            value = (f"Acc {row['acc_percent']:.1f} %  (truth {row['mean_truth']:.4g}, "
                     f"prediction {row['mean_prediction']:.4g}, {int(row['n_frames_left_out'])} frames left out)")
        else:
            value = f"mean {row['mean_prediction']:.4g}"
        lines.append(f"{row['method']:>18}  {row['metric']:<11} {value}")
    per_sim = table[(table["metric"] == MSE) & (table["sim"] != "all") & (table["method"] == MODEL)]
    lines += [f"{MODEL:>18}  {MSE} of {row['sim']}: {row['mse']:.4g} m^2" for _, row in per_sim.iterrows()]
    return "\n".join(lines)
