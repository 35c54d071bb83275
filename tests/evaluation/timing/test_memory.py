import math

import pandas as pd
import pytest
import torch

from evaluation.timing import memory
from surrogate import checkpoint


@pytest.mark.parametrize(("dim", "neighbours", "radius"), [(2, 9, 14.0), (2, 3, 1.0), (3, 17, 0.012), (3, 6, 2.0)])
def test_the_packing_gives_each_particle_the_asked_neighbour_count(dim, neighbours, radius):
    density = memory.density_for(neighbours, radius, dim)
    assert density * memory.ball_volume(radius, dim) == pytest.approx(neighbours)
    pos = memory.synthetic_window(6000, dim, density, 2, torch.zeros(dim))[-1].double()
    counts = ((torch.cdist(pos, pos) < radius).sum(1) - 1).double()          # brute force, self left out
    side = (6000 / density) ** (1 / dim)
    assert pos.min() >= 0 and pos.max() <= side * (1 + 1e-6)
    interior = ((pos > radius) & (pos < side - radius)).all(1)             # a full ball of neighbours around
    assert interior.sum() > 1000
    assert counts[interior].mean().item() == pytest.approx(neighbours, rel=0.05)


def test_the_frames_move_at_the_given_velocity_spread():
    std = torch.tensor([0.5, 2.0])
    window = memory.synthetic_window(20_000, 2, 1.0, 3, std, seed=1)
    steps = (window[1:] - window[:-1]).reshape(-1, 2)
    assert steps.std(0).tolist() == pytest.approx(std.tolist(), rel=0.03)
    assert not torch.equal(window, memory.synthetic_window(20_000, 2, 1.0, 3, std, seed=2))


def test_refused_settings_are_named():
    with pytest.raises(ValueError, match="neighbour count 0"):
        memory.density_for(0, 1.0, 2)
    with pytest.raises(ValueError, match="dimension 4"):
        memory.ball_volume(1.0, 4)


def test_a_sweep_doubles_and_trains_the_model_on_the_data_neighbour_count(untrained):
    simulator, _ = untrained
    before = {k: v.clone() for k, v in simulator.state_dict().items()}
    table = memory.sweep(simulator, start=60, max_particles=300, refine=2)
    assert table["particles"].tolist() == [60, 120, 240] and table["fits"].all()
    p99 = simulator.stats["neighbour_counts"]["p99"]
    # edges include each particle's self edge; particles near the box's faces have fewer neighbours
    assert ((table["edges_per_particle"] > 0.5 * (p99 + 1)) & (table["edges_per_particle"] < 1.1 * (p99 + 1))).all()
    assert table["peak_bytes"].isna().all() and (table["seconds"] > 0).all()       # no memory figure on the CPU
    assert all(p.grad is None for p in simulator.parameters())
    assert all(torch.equal(before[k], v) for k, v in simulator.state_dict().items())   # no optimiser step
    assert memory.largest_fitting(table) == 240


def test_a_step_that_runs_out_of_memory_ends_the_doubling_and_is_bisected(untrained, monkeypatch):
    simulator, _ = untrained
    tried = []

    def step(sim, n, neighbours, seed=0):
        tried.append(n)
        if n > 300:
            raise torch.cuda.OutOfMemoryError("CUDA out of memory. Tried to allocate 2.00 GiB")
        return {"particles": n, "edges": 5 * n, "edges_per_particle": 5.0, "peak_bytes": 1e3 * n,
                "bytes_per_particle": 1e3, "seconds": 0.1, "fits": True}

    monkeypatch.setattr(memory, "training_step", step)
    table = memory.sweep(simulator, start=100, max_particles=10_000, refine=3)
    assert tried == [100, 200, 400, 300, 350, 325]
    assert table["particles"].tolist() == [100, 200, 300, 325, 350, 400]
    assert table["fits"].tolist() == [True, True, True, False, False, False]
    assert memory.largest_fitting(table) == 300


def test_an_error_other_than_memory_is_raised(untrained, monkeypatch):
    simulator, _ = untrained

    def step(sim, n, neighbours, seed=0):
        raise RuntimeError("mat1 and mat2 shapes cannot be multiplied")

    monkeypatch.setattr(memory, "training_step", step)
    with pytest.raises(RuntimeError, match="shapes cannot be multiplied"):
        memory.sweep(simulator, start=10, max_particles=100)
    with pytest.raises(ValueError, match="start = 0"):
        memory.sweep(simulator, start=0, max_particles=100)


def test_the_command_writes_the_table(untrained, tmp_path, capsys):
    simulator, _ = untrained
    path = tmp_path / "best.pt"
    checkpoint.save(path, {"model": simulator.state_dict(),
                           "json": {"stats": simulator.stats, "model": simulator.model_config}})
    memory.main(["--checkpoint", str(path), "--device", "cpu", "--start", "50", "--max-particles", "100",
                 "--out", str(tmp_path / "memory.csv")])
    table = pd.read_csv(tmp_path / "memory.csv")
    assert table["particles"].tolist() == [50, 100] and table["fits"].all()
    assert list(table.columns) == memory.COLUMNS
    out = capsys.readouterr().out
    assert "largest particle count that trained: 100" in out and f"R = {simulator.radius:g}" in out
    assert math.isclose(table["edges"].iloc[1] / 100, table["edges_per_particle"].iloc[1])
