"""`graphdem rollout`: a checkpoint's predictions of every frame after the first K of each sim, as H5MD
(surrogate/rollout.py)."""

from __future__ import annotations

from pathlib import Path

from generators import cli as gcli
from generators.cli_paths import output_folder
from surrogate.commands import options


def register(sub) -> None:
    p = gcli.add_command(sub, "rollout", run, help="predict every frame after the first K of each sim; write H5MD")
    options.checkpoint_and_data(p, ensemble=True)
    p.add_argument("--out-dir", type=output_folder, required=True)


def run(args) -> None:
    """Roll the checkpoint's model out on H5MD sims: the first K frames come from the data, every later frame is
    predicted; kinematic particles follow the data. Writes <out-dir>/<sim>.h5 in the sims' layout. Several
    --checkpoint: their ensemble (the mean acceleration of the models)."""
    import torch

    from surrogate import ensemble, provenance, rollout
    from surrogate.samples import data_files, load_sim
    options.log_to_stderr()
    torch.set_num_threads(max(1, args.threads))
    simulator, metas = ensemble.load(args.checkpoint, args.device)
    meta = metas[0]
    simulator, rt = options.apply_runtime(args, simulator)
    sha = provenance.digest(args.checkpoint)
    for path in data_files(args.data):
        sim = load_sim(path, meta["stats"], meta["model"].get("properties") or [],
                       allow_other_scene=args.allow_other_scene)
        result = rollout.rollout(simulator, sim, runtime=rt)
        out = rollout.write(Path(args.out_dir) / f"{sim.id}.h5", sim, result, args.checkpoint, sha)
        per_frame = result.seconds / max(result.n_predicted, 1)
        status = "" if result.first_nonfinite is None else f", NON-FINITE from frame {result.first_nonfinite}"
        models = f", {result.models} models averaged" if result.models > 1 else ""
        cap = ("" if result.max_neighbours is None else
               f"; neighbour cap {result.max_neighbours}: {result.timing['capped']} receivers capped and "
               f"{result.timing['dropped']} edges dropped over the predicted frames")
        contacts = ("" if rt is None or rt.contact_correction is None else
                    f"; contact correction: {result.timing['stopped']} particle-steps stopped at a kinematic "
                    f"particle, {result.timing['corrected']} pair-steps pushed apart")
        print(f"{out}: {result.n_predicted} frames predicted in {result.seconds:.2f} s "
              f"({1000 * per_frame:.1f} ms per frame{models}, of which graph building "
              f"{1000 * result.seconds_graph / max(result.n_predicted, 1):.1f} ms{status}){cap}{contacts}")
