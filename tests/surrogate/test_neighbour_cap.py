"""The neighbour cap through the pipeline: the dataset's neighbour counts, the config key, the same capped
graph in training and rollout, and what it cut counted in history.csv, the rollout and the evaluation."""

import json

import numpy as np
import pandas as pd
import pytest
import torch

from evaluation import evaluate, metrics_table
from generators import config, h5md
from graphdem import cli
from surrogate import checkpoint, dataset, train
from surrogate import runtime as rt
from surrogate.graph import neighbour_edges, radius_graph
from surrogate.rollout import rollout
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator
from tests.surrogate import synthetic

CAP = 5
PRUNED = rt.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                    sleep_speed=None, keep_in_domain=True, compile=False)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return synthetic.build(tmp_path_factory.mktemp("synthetic"))


def frames_cut(position: torch.Tensor, kinematic: torch.Tensor, frames) -> tuple[int, int, int]:
    """Receivers capped, edges dropped and edges before the cap, summed over the graphs of ``frames``."""
    capped = dropped = edges = 0
    for t in frames:
        cut = neighbour_edges(position[t], synthetic.RADIUS, kinematic, CAP)
        capped, dropped = capped + cut.capped_receivers, dropped + cut.dropped_edges
        edges += radius_graph(position[t], synthetic.RADIUS, kinematic).shape[1]
    return capped, dropped, edges


def test_the_dataset_counts_neighbours_and_what_a_cap_cuts(tmp_path, capsys):
    """Moving A B C D at x = 0..3, kinematic K1 K2 at 4, 5 (y = 0), R = 1.5, translated each frame: senders
    A 1, B 2, C 2, D 2, K1 1, K2 0 (no pair of two kinematic particles) in each of the 4 frames a graph is
    built on."""
    frames = 5
    base = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0], [5.0, 0.0]]) + 10
    position = base[None] + np.arange(frames)[:, None, None] * np.array([0.1, 0.0])
    position[:, 4:] = base[4:]
    kinematic = np.array([False] * 4 + [True] * 2)
    h5md.write(tmp_path / "a.h5", h5md.Trajectory(
        position=position, time=np.arange(frames) * 0.5, step=np.arange(frames), species=kinematic.astype(int),
        radius=np.full(6, 0.4), mass=np.ones(6), kinematic=kinematic, box_lower=np.zeros(2),
        box_upper=np.full(2, 30.0)))
    table = pd.DataFrame({"id": ["a"], "split": ["train"], "path": [str(tmp_path / "a.h5")]})
    counted = dataset.build(table, tmp_path / "out", 1.5, max_neighbours=1)["neighbour_counts"]
    assert counted == {"receivers": 24, "max": 2, "p99": 2, "mean": pytest.approx(8 / 6),
                       "histogram": [4, 8, 12], "max_neighbours": 1, "capped_receiver_fraction": 0.5,
                       "dropped_edge_fraction": 3 / 8}
    assert json.loads((tmp_path / "out" / "stats.json").read_text())["neighbour_counts"]["histogram"] == [4, 8, 12]
    assert dataset.build(table, tmp_path / "none", 1.5)["neighbour_counts"]["max_neighbours"] is None
    table.to_csv(tmp_path / "table.csv", index=False)
    assert cli.main(["dataset", "--scene", "slide", "--table", str(tmp_path / "table.csv"), "--out-dir",
                     str(tmp_path / "cli"), "--connectivity-radius", "1.5", "--max-neighbours", "1"]) == 0
    assert ("neighbours within R = 1.5 on the train split: at most 2, 99th percentile 2, mean 1.33 per receiver; "
            "a cap of 1 truncates 50 % of the receivers and drops 37.5 % of the edges") in capsys.readouterr().out
    with pytest.raises(ValueError, match=r"max_neighbours = 0: null \(no cap\) or an integer >= 1"):
        dataset.build(table, tmp_path / "bad", 1.5, max_neighbours=0)


def test_the_config_key_defaults_to_no_cap_and_refuses_a_cap_below_one():
    cfg = config.load({"scale": "ci"})
    sections = [name for name, section in cfg.items() if isinstance(section, dict) and "model" in section]
    assert {"slide", "slide_samer", "slide_small"} <= set(sections)
    assert all(cfg[name]["model"]["max_neighbours"] is None for name in sections)
    assert config.load({"slide": {"model": {"max_neighbours": 16}}})["slide"]["model"]["max_neighbours"] == 16
    with pytest.raises(config.ConfigError, match=r"slide_samer\.model\.max_neighbours.*minimum': 1"):
        config.load({"slide_samer": {"model": {"max_neighbours": 0}}})


def test_a_capped_rollout_counts_the_cut_of_every_step_and_the_runtime_paths_agree(data):
    sim = load_sim(data["paths"]["syn_03"], data["stats"])
    torch.manual_seed(0)
    capped_model = LearnedSimulator(data["stats"], {**synthetic.MODEL, "max_neighbours": CAP}).eval()
    k = capped_model.history
    want = frames_cut(sim.position, sim.kinematic, range(k - 1, sim.n_frames - 1))
    assert want[1] > 0
    plain = rollout(capped_model, sim, forced=True)
    pruned = rollout(rt.apply(capped_model, PRUNED), sim, runtime=PRUNED, forced=True)
    for result in (plain, pruned):
        assert (result.timing["capped"], result.timing["dropped"]) == want[:2]
        assert result.max_neighbours == CAP
    np.testing.assert_allclose(pruned.position, plain.position, rtol=0, atol=1e-5)
    # the cap changes the input: the same weights without it predict otherwise
    uncapped = LearnedSimulator(data["stats"], synthetic.MODEL).eval()
    uncapped.load_state_dict(capped_model.state_dict())
    free = rollout(uncapped, sim, forced=True)
    assert free.timing["dropped"] == 0 and free.max_neighbours is None
    assert not np.array_equal(free.position[k:], plain.position[k:])


def test_training_builds_the_capped_graph_and_records_what_it_cut(data, tmp_path):
    """No noise, no mirror, no pushforward: the training graphs are the data's frames K-1 .. T-2 of every train
    sim, so history.csv's sums are those of the capped graphs of these frames."""
    model_cfg = {**synthetic.MODEL, "max_neighbours": CAP}
    train.train(data["stats_path"], data["splits"], model_cfg, synthetic.TRAIN, tmp_path / "capped", progress=False)
    history = pd.read_csv(tmp_path / "capped" / "history.csv")
    assert list(history.columns) == list(train.HISTORY_COLUMNS) + train.CAP_HISTORY
    want = np.zeros(3, dtype=int)
    for name, split in data["split_of"].items():
        if split == "train":
            sim = load_sim(data["paths"][name], data["stats"])
            want += frames_cut(sim.position, sim.kinematic, range(model_cfg["history"] - 1, sim.n_frames - 1))
    assert history[train.CAP_HISTORY].iloc[0].tolist() == want.tolist() and want[1] > 0
    meta = checkpoint.load(tmp_path / "capped" / "best.pt")["json"]
    assert meta["model"]["max_neighbours"] == CAP
    assert LearnedSimulator(meta["stats"], meta["model"]).max_neighbours == CAP
    train.train(data["stats_path"], data["splits"], synthetic.MODEL, synthetic.TRAIN, tmp_path / "free", progress=False)
    assert list(pd.read_csv(tmp_path / "free" / "history.csv").columns) == list(train.HISTORY_COLUMNS)


def test_the_evaluation_reports_the_caps_counts_per_frame(data, tmp_path, capsys):
    torch.manual_seed(0)
    for name, cfg in (("capped", {**synthetic.MODEL, "max_neighbours": CAP}), ("free", synthetic.MODEL)):
        simulator = LearnedSimulator(data["stats"], cfg)
        checkpoint.save(tmp_path / f"{name}.pt", {"model": simulator.state_dict(), "json": {
            "model": cfg, "train": {}, "stats": data["stats"]}})
    test_sim = data["paths"]["syn_03"]
    assert cli.main(["evaluate", "--checkpoint", str(tmp_path / "capped.pt"), "--data", str(test_sim),
                     "--history", "3", "--out", str(tmp_path / "m.csv"), "--no-progress", "--device", "cpu",
                     "--table-html", str(tmp_path / "m.html")]) == 0
    assert "capped receivers per frame" in capsys.readouterr().out
    table = pd.read_csv(tmp_path / "m.csv")
    rows = table.set_index("metric")["mean_prediction"]
    simulator, _ = checkpoint.simulator_from(tmp_path / "capped.pt")
    result = rollout(simulator, load_sim(test_sim, data["stats"]))
    frames = result.n_predicted
    assert rows[evaluate.CAPPED] == pytest.approx(result.timing["capped"] / frames)
    assert rows[evaluate.DROPPED] == pytest.approx(result.timing["dropped"] / frames) and rows[evaluate.DROPPED] > 0
    page = (tmp_path / "m.html").read_text()
    assert "dropped edges per frame" in page and "the neighbour cap" in page
    # rollouts written with the cap carry the counts, and an evaluation of them reads them back
    assert cli.main(["rollout", "--checkpoint", str(tmp_path / "capped.pt"), "--data", str(test_sim),
                     "--out-dir", str(tmp_path / "rollouts"), "--device", "cpu"]) == 0
    assert "edges dropped over the predicted frames" in capsys.readouterr().out
    params = h5md.read(tmp_path / "rollouts" / "syn_03.h5").parameters
    assert (params["rollout_max_neighbours"], params["rollout_dropped_edges"]) == (CAP, result.timing["dropped"])
    assert cli.main(["evaluate", "--checkpoint", str(tmp_path / "capped.pt"), "--data", str(test_sim),
                     "--history", "3", "--out", str(tmp_path / "r.csv"), "--rollouts", str(tmp_path / "rollouts"),
                     "--no-progress", "--device", "cpu"]) == 0
    again = pd.read_csv(tmp_path / "r.csv").set_index("metric")["mean_prediction"]
    assert again[evaluate.DROPPED] == pytest.approx(rows[evaluate.DROPPED])
    # without a cap: no such rows, nothing recorded
    assert cli.main(["evaluate", "--checkpoint", str(tmp_path / "free.pt"), "--data", str(test_sim),
                     "--history", "3", "--out", str(tmp_path / "f.csv"), "--no-progress", "--device", "cpu"]) == 0
    assert not set(pd.read_csv(tmp_path / "f.csv")["metric"]) & metrics_table.CAP_COUNTS
