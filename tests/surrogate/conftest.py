"""A tiny real slide dataset (LAMMPS, ci scale) shared by the surrogate tests."""

import json

import pandas as pd
import pytest

from generators import config, convert, engine, sweep
from generators.scenes import slide
from surrogate import dataset


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """4 real sims (2 train, 1 valid, 1 test) of 10 frames, their splits and stats, and tiny model configs."""
    cfg = config.load({"scale": "ci", "slide": {
        "n_sims": 4, "settle_time": 4.0, "frames": 10, "frame_interval": 0.1, "record_start": 0.5}})["slide"]
    root = tmp_path_factory.mktemp("tiny_slide")
    table = sweep.build("slide", cfg)
    table.to_csv(root / "sweep.csv", index=False)
    packing = root / "packing"
    engine.prepare(slide.SCENE, "lammps", slide.SCENE.packing_params(cfg, 0), packing)
    for row in table.to_dict("records"):
        engine.simulate(slide.SCENE, row, packing, root / "raw" / row["id"])
        convert.convert(root / "raw" / row["id"], root / "sims" / f"{row['id']}.h5")
    stats = dataset.build(dataset.split_table(table, root / "sims"), root / "dataset", cfg["connectivity_radius"])
    model = {**cfg["model"], "history": 4}
    train = {**cfg["train"], "lr": 1e-3, "batch_size": 2, "epochs": 3, "patience": 3, "checkpoint_every": 2}
    return {"root": root, "cfg": cfg, "stats": stats, "stats_path": root / "dataset" / "stats.json",
            "splits": root / "dataset" / "splits.csv", "model": model, "train": train,
            "split_table": pd.read_csv(root / "dataset" / "splits.csv"),
            "stats_json": json.dumps(stats)}


@pytest.fixture
def untrained(tiny_dataset):
    """A freshly initialised (seed 0) simulator of the tiny dataset, in eval mode, and its first test sim."""
    import torch

    from surrogate.samples import load_sim
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    table = tiny_dataset["split_table"]
    torch.manual_seed(0)
    sim = load_sim(table.loc[table["split"] == "test", "path"].iloc[0], stats)
    return LearnedSimulator(stats, tiny_dataset["model"]).eval(), sim
