"""`graphdem stability-surrogate`: long and perturbed rollouts, and precision, of a checkpoint
(evaluation/stability.py)."""

from __future__ import annotations

from generators import cli as gcli
from generators.cli_paths import output_file
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "stability-surrogate", run,
                         help="long and perturbed rollouts, and precision, of a checkpoint")
    options.checkpoint_and_data(p)
    p.add_argument("--lengths", type=int, nargs="+", required=True, help="rollout lengths in recorded windows")
    p.add_argument("--noise", type=float, required=True, help="std (m per frame) of the initial history's noise")
    p.add_argument("--seed", type=int, required=True, help="seed of the history noise")
    p.add_argument("--max-overlap", type=float, required=True, help="overlap limit (fraction of the smaller radius)")
    p.add_argument("--energy-envelope", type=float, default=float("inf"),
                   help="a frame whose kinetic energy exceeds this multiple of the data's peak leaves the physical "
                        "envelope (default: no energy limit)")
    p.add_argument("--out", type=output_file, required=True, help="CSV report")
    p.add_argument("--frames-out", type=output_file,
                   help="CSV: per frame of each long rollout (energy, overlaps, outside)")
    p.add_argument("--plot", type=output_file, help="PNG: kinetic energy and overlaps per frame of the long rollouts")
    p.add_argument("--title", help="the plot's title")


def run(args) -> None:
    """Stability test of the surrogate on H5MD sims: rollouts --lengths times the recorded window from a history with
    random-walk noise (non-finite frames, escapes or particles put back into the box, the overlap distribution and
    kinetic energy per frame, the first frame outside the physical envelope, error growth per step, final speed),
    and the recorded rollout in float64, float32 and bfloat16 (differences from float64)."""
    import torch

    from evaluation import stability
    from surrogate import checkpoint
    from surrogate.samples import data_files, load_sim
    options.log_to_stderr()
    torch.set_num_threads(max(1, args.threads))
    simulator, meta = checkpoint.simulator_from(args.checkpoint, args.device)
    sims = [load_sim(p, meta["stats"], meta["model"].get("properties") or [], allow_other_scene=args.allow_other_scene)
            for p in data_files(args.data)]
    rt = options.runtime_config(args, required_by="stability-surrogate")
    table, frames = stability.surrogate_report(simulator, rt, sims, args.lengths, args.noise, args.seed,
                                               args.max_overlap, args.energy_envelope)
    if args.frames_out:
        options.write_table(frames, args.frames_out)
    if args.plot:
        from evaluation import plots
        plots.stability(frames, args.plot, args.title or "long rollouts")
    options.write_table(table, args.out)
    print(table.drop(columns=["cause", "envelope_cause"], errors="ignore").to_string(index=False))
