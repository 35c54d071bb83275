"""`graphdem seeds`: the mean and spread of every metric over models trained with different seeds
(evaluation/seeds.py)."""

from __future__ import annotations

from generators import cli as gcli
from generators.cli_paths import input_path, output_file
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "seeds", run,
                         help="mean and spread of every metric over models trained with different seeds")
    p.add_argument("--metrics", type=input_path, nargs="+", required=True, help="one metrics.csv per seed")
    p.add_argument("--seeds", type=int, nargs="+", required=True, help="the seed of each table, in the same order")
    p.add_argument("--out", type=output_file, required=True)


def run(args) -> None:
    """Combine the metrics.csv of models trained with different seeds (the same data, the same evaluation) into one
    table: per method, metric, protocol and value column the mean, sample standard deviation, range and each seed's
    value (docs/surrogate.md, Seeds)."""
    from evaluation import seeds
    table = seeds.spread(seeds.read(args.metrics, args.seeds))
    options.write_table(table, args.out)
    shown = table[table["column"].isin(["acc_percent", "mse"])]
    for row in shown.itertuples():
        print(f"{row.method:>18}  {row.metric:<14} {row.column:<11} {row.mean:.4g} +- {row.std:.2g} "
              f"({row.min:.4g} .. {row.max:.4g}, {row.n_seeds} seeds)")
