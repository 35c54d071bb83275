"""`graphdem publish`: a trained model as a pretrained checkpoint with its model card (evaluation/publish.py)."""

from __future__ import annotations

from pathlib import Path

from generators import cli as gcli
from generators import scenes
from generators.cli_paths import input_path, output_folder, split_table
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "publish", run,
                         help="a trained model as a pretrained checkpoint and its model card",
                         epilog="The workflow makes it: snakemake -c2 results/<scene>/pretrained/<scene>.pt; "
                                "the package ships the default scale's (surrogate/pretrained/, docs/pretrained.md).")
    p.add_argument("--scene", choices=scenes.names(), required=True, help="the scene the model was trained on")
    p.add_argument("--checkpoint", type=input_path, required=True,
                   help="the trained model (results/<scene>/model/best.pt)")
    p.add_argument("--splits", type=split_table, required=True,
                   help="its split table (results/<scene>/dataset/splits.csv)")
    p.add_argument("--metrics", type=input_path, required=True,
                   help="its test metrics (results/<scene>/metrics.csv), whose summary table the card shows")
    p.add_argument("--runtime-json", type=options.json_arg, required=True,
                   help="the runtime switches its metrics were measured with (the scene's runtime config)")
    p.add_argument("--out-dir", type=output_folder, required=True, help="folder for <scene>.pt and <scene>.md")


def run(args) -> None:
    """Publish a trained model: <out-dir>/<scene>.pt, the checkpoint's weights and metadata with its provenance
    added (the scene, the runtime switches of its test metrics, the config hash and code version they record, the
    source checkpoint's digest, the data it was trained on), and <out-dir>/<scene>.md, its model card: those facts
    and the scene's summary table of the test metrics (Graph-DEM beside constant velocity and the DEM ensemble,
    with intervals), generated and stamped as `graphdem tables` writes it. The results folder is the one that holds
    --metrics. `graphdem.load_simulator(path)` loads it, with the runtime switches as its default."""
    from evaluation import publish
    results = Path(args.metrics).resolve().parent.parent
    pt, md = publish.publish(args.scene, Path(args.checkpoint), Path(args.splits), Path(args.metrics),
                             args.runtime_json, Path(args.out_dir), results)
    print(f"{pt}: {pt.stat().st_size / 1e6:.2f} MB; model card {md}")
