import os
import shutil

import pytest

from generators import config

# torch.compile's inductor compiles its kernels in a pool of worker processes by default; on the 2-core test
# machine starting that pool costs more than it saves (the compiled-rollout test: 49 s with it, 19 s without).
# Set before torch is imported, inherited by every job the workflow tests start.
os.environ.setdefault("TORCHINDUCTOR_COMPILE_THREADS", "1")


def pytest_configure(config):
    """Under pytest-xdist each worker computes with one torch thread: two workers with a thread per core each
    would oversubscribe the cores (the jobs the workflow tests start set their own threads)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        import torch
        torch.set_num_threads(1)


@pytest.fixture
def ci_slide() -> dict:
    """The validated ci-scale slide config section."""
    return config.load({"scale": "ci"})["slide"]


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """A tiny real slide dataset (LAMMPS, ci scale) shared by the surrogate's and the evaluation's tests: 4 real
    sims (2 train, 1 valid, 1 test) of 10 frames, their splits and stats, and tiny model configs."""
    import json

    import pandas as pd

    from generators import convert, engine, sweep
    from generators.scenes import slide
    from surrogate import dataset
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
    import json

    import torch

    from surrogate.samples import load_sim
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    table = tiny_dataset["split_table"]
    torch.manual_seed(0)
    sim = load_sim(table.loc[table["split"] == "test", "path"].iloc[0], stats)
    return LearnedSimulator(stats, tiny_dataset["model"]).eval(), sim


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """``make test`` runs the suite on two pytest-xdist workers (``-n 2 --dist loadgroup --no-loadscope-reorder``),
    handing out groups of tests in the order sorted here. Every test that reads the shared ci-scale run of every
    scene (the ``ci_results`` fixture, about 6 minutes on two cores) is one group, handed out first: one worker
    builds the run and reads it while the other works through the rest. Every other test file is a group of its
    own, so its module fixtures are built once, on one worker; the workflow files, the longest, go next. It runs
    before pytest-xdist's hook of the same name, which turns the marks into the groups."""
    if shutil.which("lmp") is None:
        raise pytest.UsageError("LAMMPS (`lmp`) is not installed: run `make test`, which installs it")

    def group(item) -> str:
        return "ci_results" if "ci_results" in getattr(item, "fixturenames", ()) else item.nodeid.split("::")[0]

    items.sort(key=lambda item: (group(item) != "ci_results", not item.nodeid.startswith("tests/workflow/")))
    for item in items:
        item.add_marker(pytest.mark.xdist_group(group(item)))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_node_collection_finished(node, ids):
    """The groups above take effect only if pytest-xdist appends them to the test ids (``<id>@<group>``), which
    it does by setting an attribute pytest 9.2 no longer reads: there every test became a group of its own, each
    worker built the module fixtures it met (the ci-scale slide run twice) and one worker sat waiting on the
    other's ci-scale run of every scene. So a run whose workers collected ids without groups stops and says
    why."""
    ungrouped = [nodeid for nodeid in ids if "@" not in nodeid]
    if node.config.getvalue("dist") == "loadgroup" and ungrouped:
        raise pytest.UsageError(
            f"pytest-xdist ignored the xdist_group marks (pytest {pytest.__version__}; e.g. {ungrouped[0]}): "
            "install the pins of constraints.txt (`make install`), under which the tests share their fixtures")


@pytest.fixture
def saved_checkpoint(tiny_dataset, tmp_path):
    """An initialised (seed 0) simulator of the tiny dataset saved as a checkpoint: its path, the path of the
    first test sim, and the dataset statistics."""
    import json

    import torch

    from surrogate import checkpoint
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    checkpoint.save(tmp_path / "best.pt", {"model": simulator.state_dict(),
                                           "json": {"stats": stats, "model": tiny_dataset["model"]}})
    table = tiny_dataset["split_table"]
    return tmp_path / "best.pt", table.loc[table["split"] == "test", "path"].iloc[0], stats
