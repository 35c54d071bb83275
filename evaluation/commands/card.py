"""`graphdem card`: a public benchmark's card, Graph-DEM and constant velocity over seeds beside the article
(evaluation/card.py)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from generators import cli as gcli
from generators.cli_paths import input_path, output_file
from surrogate.commands import options

DESCRIPTION = """\
The benchmark card of a public benchmark (docs/benchmarks.md, Benchmark card). From the
evaluation of each model trained with a different seed: per method, protocol K and quantity
the mean, sample standard deviation (ddof 1), smallest and largest value over the seeds and
each seed's value (--out, CSV), and a short table to read (--markdown) that also states the
split scored, the hardware and the article's figures beside ours.

quantities (per seed first, then over the seeds; NaN is never skipped):
  rollout_mse           rollout MSE (m^2) of metrics.csv
  mse_first_frame       MSE (m^2) at the first predicted frame, mean over sims (--steps)
  mse_last_frame        MSE (m^2) at the last predicted frame, mean over sims (--steps)
  rmse_diameters        sqrt(rollout MSE) / d, d = the moving particles' mean diameter
                        (2 x the mean radius of --stats, the train split's moving particles)
  blown_up              rollouts that blew up (n_blown_up); total: over all seeds
  rollout_ms_per_frame  Graph-DEM's rollout wall time per predicted frame (ms)
  train_seconds         training wall time per model (history.csv's seconds)
  train_cost            each epoch's seconds x its threads x processes (CPU: core-hours)
                        or x its processes (GPU: GPU-hours), summed, per model

seed ensemble (--ensemble-metrics, --ensemble-steps): the seeds' models as one simulator that
integrates their mean acceleration, scored once (method seed_ensemble, no spread); its
training is every model's, summed"""

EPILOG = """\
The workflow makes it (B: slide_samer or slide_small; the seeds: the config key seeds):
  snakemake -c2 results/<B>/card.md --config solidgn_root=/path/to/solidgn"""


def register(sub) -> None:
    from surrogate import devices
    p = sub.add_parser(
        "card", help="a public benchmark's card: Graph-DEM and constant velocity over seeds, beside the article",
        formatter_class=argparse.RawDescriptionHelpFormatter, description=DESCRIPTION, epilog=EPILOG)
    p.add_argument("--benchmark", choices=sorted(gcli.gconfig.BENCHMARKS), required=True,
                   help="the public benchmark (its name in the card)")
    p.add_argument("--seeds", type=int, nargs="+", required=True, help="the training seeds, one per model")
    p.add_argument("--metrics", type=input_path, nargs="+", required=True,
                   help="each seed's metrics.csv (graphdem evaluate --out), in --seeds order")
    p.add_argument("--steps", type=input_path, nargs="+", required=True,
                   help="each seed's per-step table (graphdem evaluate --per-step), in --seeds order")
    p.add_argument("--histories", type=input_path, nargs="+", required=True,
                   help="each seed's model/history.csv (graphdem train), in --seeds order")
    p.add_argument("--stats", type=input_path, required=True,
                   help="the dataset's stats.json (the mean particle radius)")
    p.add_argument("--ensemble-metrics", type=input_path,
                   help="the seed ensemble's metrics.csv (graphdem evaluate with every seed's --checkpoint): its "
                        "rows join the card as seed_ensemble, costed as all its models")
    p.add_argument("--ensemble-steps", type=input_path,
                   help="the seed ensemble's per-step table (with --ensemble-metrics)")
    p.add_argument("--article-json", type=options.json_arg, required=True,
                   help='the article\'s figures, the config\'s B.article: {"history": K, "split": "test", '
                        '"rollout_mse": {"graphdem": ..., "gns": ...}}')
    p.add_argument("--device", type=options.device_arg, default="auto",
                   help=f"the device setting the jobs were given ({devices.CHOICES}); said on the card, and "
                        "where a model trained with --train-threads")
    p.add_argument("--train-threads", type=int,
                   help="torch threads a model trained on (one process, on --device), for a history.csv that does "
                        "not record where it ran (written before it had the threads and device columns); default: "
                        "refuse such a file")
    p.add_argument("--out", type=output_file, required=True, help="card.csv to write")
    p.add_argument("--markdown", type=output_file, required=True, help="card.md to write")
    p.set_defaults(func=run)


def run(args) -> None:
    from evaluation import card
    from evaluation import tables as tables_csv
    from generators.atomic import atomic_path
    counts = {"--metrics": len(args.metrics), "--steps": len(args.steps), "--histories": len(args.histories)}
    if set(counts.values()) != {len(args.seeds)}:
        raise SystemExit(f"graphdem card: give one file per seed ({len(args.seeds)} seeds: {args.seeds}); got "
                         + ", ".join(f"{n} {flag}" for flag, n in counts.items()))
    if len(set(args.seeds)) != len(args.seeds):
        raise SystemExit(f"graphdem card: --seeds {args.seeds} repeat a seed")
    tables, trainings = _per_seed(args)
    if (args.ensemble_metrics is None) != (args.ensemble_steps is None):
        raise SystemExit("graphdem card: give both --ensemble-metrics and --ensemble-steps (the seed ensemble's "
                         "evaluation), or neither")
    ensemble = None if args.ensemble_metrics is None else (tables_csv.read_csv(args.ensemble_metrics),
                                                           tables_csv.read_csv(args.ensemble_steps))
    stats = json.loads(Path(args.stats).read_text())
    table, split, note = card.card(tables, stats, args.article_json, args.benchmark, ensemble)
    text = card.markdown(table, args.benchmark, split, note, card.mean_diameter(stats), trainings, args.device)
    options.write_table(table, args.out, na_rep="NaN")
    with atomic_path(args.markdown) as tmp:
        tmp.write_text(text)
    print(text)


def _per_seed(args) -> tuple[dict, dict]:
    """Each seed's (metrics, per-step table, training) and its training alone, by seed."""
    import pandas as pd

    from evaluation import card
    from evaluation import tables as tables_csv
    tables, trainings = {}, {}
    for seed, metrics, steps, history in zip(args.seeds, args.metrics, args.steps, args.histories, strict=True):
        epochs = pd.read_csv(history)
        try:
            trainings[seed] = card.training(epochs, None if card.records_hardware(epochs) else _fallback(args))
        except ValueError as exc:
            raise ValueError(f"{history}: {exc}") from None
        tables[seed] = (tables_csv.read_csv(metrics), tables_csv.read_csv(steps), trainings[seed])
    return tables, trainings


def _fallback(args):
    """Where a model whose history.csv does not say trained: --train-threads on --device, here resolved."""
    from evaluation import card
    from surrogate import devices
    if args.train_threads is None:
        return None
    where = devices.resolve(args.device)
    return card.Hardware(str(where), devices.name(where), int(args.train_threads), 1)
