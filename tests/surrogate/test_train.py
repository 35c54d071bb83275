"""Training on a tiny real dataset: the loss falls, a stopped run resumes, divergence is named."""

import json

import pandas as pd
import pytest
import torch

from surrogate import checkpoint, devices, train
from surrogate.graph import build_graph
from surrogate.samples import load_sim, sample_index

pytestmark = pytest.mark.engine


def run(tiny, out, **kwargs):
    return train.train(tiny["stats_path"], tiny["splits"], tiny["model"], tiny["train"], out, progress=False,
                       **kwargs)


def test_tiny_training_lowers_the_loss_and_keeps_the_best_checkpoint(tiny_dataset, tmp_path):
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "epochs": 20, "patience": 20, "lr": 3e-3}}
    state = run(tiny, tmp_path)
    history = pd.read_csv(tmp_path / "history.csv")
    assert list(history["epoch"]) == list(range(1, 21)) and state["finished"]
    assert history["train_loss"].iloc[-3:].mean() < 0.92 * history["train_loss"].iloc[0]
    best = checkpoint.load(tmp_path / "best.pt")["json"]
    assert best["valid_rollout_mse"] == pytest.approx(history["valid_rollout_mse"].min())
    assert best["stats"] == tiny["stats"] and best["model"] == tiny["model"]   # carries what it was trained with
    # where each epoch ran: what a benchmark card's training cost is computed from
    assert (history["threads"] == 1).all() and (history["processes"] == 1).all()          # train's default
    where = devices.resolve("auto")
    assert set(history["device"]) == {str(where)} and set(history["device_name"]) == {devices.name(where)}


def test_same_seed_reproduces_the_run(tiny_dataset, tmp_path):
    run(tiny_dataset, tmp_path / "a")
    run(tiny_dataset, tmp_path / "b")
    a, b = pd.read_csv(tmp_path / "a" / "history.csv"), pd.read_csv(tmp_path / "b" / "history.csv")
    pd.testing.assert_frame_equal(a.drop(columns="seconds"), b.drop(columns="seconds"))


def test_stopped_run_resumes_with_the_step_count_and_the_uninterrupted_result(tiny_dataset, tmp_path):
    whole = run(tiny_dataset, tmp_path / "whole")
    stopped = run(tiny_dataset, tmp_path / "parts", max_steps=3)
    assert stopped["step"] == 3 and not stopped["finished"]
    resumed = run(tiny_dataset, tmp_path / "parts")
    assert resumed["step"] == whole["step"]                       # continued, not restarted
    a = pd.read_csv(tmp_path / "whole" / "history.csv").drop(columns="seconds")
    b = pd.read_csv(tmp_path / "parts" / "history.csv").drop(columns="seconds")
    pd.testing.assert_frame_equal(a, b)
    wa = checkpoint.load(tmp_path / "whole" / "best.pt")["model"]
    wb = checkpoint.load(tmp_path / "parts" / "best.pt")["model"]
    assert all(torch.equal(wa[k], wb[k]) for k in wa)


def test_finished_run_is_not_resumed_but_restarted(tiny_dataset, tmp_path):
    run(tiny_dataset, tmp_path)
    again = run(tiny_dataset, tmp_path)
    assert again["step"] == pd.read_csv(tmp_path / "history.csv")["step"].iloc[-1]
    assert len(pd.read_csv(tmp_path / "history.csv")) == tiny_dataset["train"]["epochs"]


def test_non_finite_loss_stops_training_naming_step_and_samples(tiny_dataset, tmp_path, monkeypatch):
    real = train.batch_loss
    calls = {"n": 0}

    def poisoned(*args, **kwargs):
        calls["n"] += 1
        loss = real(*args, **kwargs)
        return loss * float("nan") if calls["n"] == 3 else loss

    monkeypatch.setattr(train, "batch_loss", poisoned)
    with pytest.raises(train.TrainingDiverged, match=r"at step 3 \(epoch 1, batch 3\) on samples: slide_\d+ frame \d"):
        run(tiny_dataset, tmp_path)


def test_random_walk_noise_changes_the_target_consistently(tiny_dataset):
    """With noise, the target still lands on the true next position (relative to the noisy last one)."""
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    split = tiny_dataset["split_table"]
    sim = load_sim(split.loc[split["split"] == "train", "path"].iloc[0], stats)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    g = torch.Generator().manual_seed(0)
    clean = train.batch_loss(simulator, [sim], [(0, 3)], 0.0, g)
    noisy = train.batch_loss(simulator, [sim], [(0, 3)], 0.05, torch.Generator().manual_seed(0))
    assert torch.isfinite(clean) and torch.isfinite(noisy) and not torch.isclose(clean, noisy)


def test_mirror_reflects_positions_and_the_target_acceleration_in_x(tiny_dataset):
    """x -> x_lo + x_hi - x keeps distances and vertical motion and negates horizontal acceleration."""
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    split = tiny_dataset["split_table"]
    sim = load_sim(split.loc[split["split"] == "train", "path"].iloc[0], stats)
    frames = sim.position[0:5]
    flipped = train.mirror_x(frames, simulator.lower, simulator.upper)
    torch.testing.assert_close(train.mirror_x(flipped, simulator.lower, simulator.upper), frames)
    exact = "donot_use_mm_for_euclid_dist"
    torch.testing.assert_close(torch.cdist(flipped[-1], flipped[-1], compute_mode=exact),
                               torch.cdist(frames[-1], frames[-1], compute_mode=exact), atol=1e-4, rtol=1e-5)
    acc = frames[-1] - 2 * frames[-2] + frames[-3]
    acc_flipped = flipped[-1] - 2 * flipped[-2] + flipped[-3]
    torch.testing.assert_close(acc_flipped[:, 0], -acc[:, 0], atol=1e-3, rtol=0)
    torch.testing.assert_close(acc_flipped[:, 1], acc[:, 1], atol=1e-3, rtol=0)
    # in the loss: some samples of a batch are flipped, so the loss differs from the unflipped one
    batch = [(0, t) for t in range(3, 8)]
    plain = train.batch_loss(simulator, [sim], batch, 0.0, torch.Generator().manual_seed(1))
    mirrored = train.batch_loss(simulator, [sim], batch, 0.0, torch.Generator().manual_seed(1), mirror=True)
    assert torch.isfinite(mirrored) and not torch.isclose(plain, mirrored)


def _untrained_simulator_and_first_train_sim(tiny_dataset):
    """A seed-0 untrained simulator of the tiny dataset's model and its first train sim."""
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    split = tiny_dataset["split_table"]
    return simulator, load_sim(split.loc[split["split"] == "train", "path"].iloc[0], stats)


def test_pushforward_sample_starts_from_the_models_own_prediction(tiny_dataset):
    """At p = 1 (no noise) the last input frame is the one-step prediction from the window one frame
    earlier and the target is the true next frame; a sample with no earlier frame is left as it is."""
    simulator, sim = _untrained_simulator_and_first_train_sim(tiny_dataset)
    k, t = simulator.history, simulator.history + 1
    earlier = sim.position[t - k:t]
    with torch.no_grad():
        predicted = simulator.step(build_graph(earlier, sim.types, sim.kinematic, simulator.radius), sim.position[t])
    window = torch.cat([sim.position[t - k + 1:t], predicted])
    graph = build_graph(window, sim.types, sim.kinematic, simulator.radius)
    expected = ((simulator(graph) - simulator.target(window, sim.position[t + 1])) ** 2)[~sim.kinematic].mean()
    got = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0), pushforward=1.0)
    torch.testing.assert_close(got, expected)
    plain = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0))
    assert not torch.isclose(got, plain)          # an untrained model's prediction is not the data
    first = [(0, k - 1)]                          # no frame before the window: never pushed
    torch.testing.assert_close(train.batch_loss(simulator, [sim], first, 0.0, torch.Generator(), pushforward=1.0),
                               train.batch_loss(simulator, [sim], first, 0.0, torch.Generator()))


def test_type_weights_average_one_and_balance_the_types_by_their_counts():
    """b = 0: every particle 1; b = 1: each type the same total weight; b = 0.5: weights in the ratio of
    the counts' inverse square roots; always a mean of 1; outside [0, 1] refused by name."""
    types = torch.tensor([0, 0, 0, 1])
    torch.testing.assert_close(train.type_weights(types, 0.0), torch.ones(4))
    torch.testing.assert_close(train.type_weights(types, 1.0), torch.tensor([2 / 3, 2 / 3, 2 / 3, 2.0]))
    half = train.type_weights(types, 0.5)
    torch.testing.assert_close(half.mean(), torch.tensor(1.0))
    torch.testing.assert_close(half[3] / half[0], torch.tensor(3.0 ** 0.5))
    with pytest.raises(ValueError, match=r"train.type_balance = 1.5.*\[0, 1\]"):
        train.type_weights(types, 1.5)


def test_type_balance_weights_each_particles_squared_error_in_the_loss(tiny_dataset):
    """With two moving types, the loss is the mean of the squared errors weighted by type_weights; b = 0 is the
    plain mean; the multi-step loss refuses it by name."""
    from dataclasses import replace
    simulator, sim = _untrained_simulator_and_first_train_sim(tiny_dataset)
    moving = (~sim.kinematic).nonzero().squeeze(1)
    types = sim.types.clone()
    types[moving[:3]] = 1 - types[moving[0]]           # three moving particles of the other type
    sim = replace(sim, types=types)
    t = simulator.history + 1
    window = sim.position[t - simulator.history + 1:t + 1]
    graph = build_graph(window, sim.types, sim.kinematic, simulator.radius)
    squared = ((simulator(graph) - simulator.target(window, sim.position[t + 1])) ** 2)[~sim.kinematic]
    weights = train.type_weights(sim.types[~sim.kinematic], 1.0)
    got = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0), type_balance=1.0)
    torch.testing.assert_close(got, (squared * weights.unsqueeze(1)).mean())
    plain = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0))
    torch.testing.assert_close(plain, squared.mean())
    assert not torch.isclose(got, plain)
    with pytest.raises(ValueError, match="type_balance.*pushforward_gradient"):
        train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator(), pushforward=1.0,
                         pushforward_gradient=True, type_balance=0.5)


def test_multi_step_pushforward_feeds_m_predicted_frames(tiny_dataset):
    """With pushforward_steps = 2 a pushed sample's history ends in 1 or 2 of the model's own frames
    (each drawn over seeds), each predicted from the window before it; where only one frame precedes
    the window, m is capped at 1."""
    simulator, sim = _untrained_simulator_and_first_train_sim(tiny_dataset)
    k = simulator.history

    def pushed_loss(t, m):
        window = sim.position[t - k + 1 - m:t + 1 - m]
        with torch.no_grad():
            for j in range(m):
                nxt = simulator.step(build_graph(window, sim.types, sim.kinematic, simulator.radius),
                                     sim.position[t + 1 - m + j])
                window = torch.cat([window[1:], nxt])
        graph = build_graph(window, sim.types, sim.kinematic, simulator.radius)
        return ((simulator(graph) - simulator.target(window, sim.position[t + 1])) ** 2)[~sim.kinematic].mean()

    t = k + 1
    one, two = pushed_loss(t, 1), pushed_loss(t, 2)
    assert not torch.isclose(one, two)
    seen = set()
    for seed in range(12):
        got = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(seed),
                               pushforward=1.0, pushforward_steps=2)
        matches = [m for m, ref in ((1, one), (2, two)) if torch.allclose(got, ref)]
        assert len(matches) == 1
        seen.add(matches[0])
    assert seen == {1, 2}
    capped = train.batch_loss(simulator, [sim], [(0, k)], 0.0, torch.Generator().manual_seed(0),
                              pushforward=1.0, pushforward_steps=5)
    torch.testing.assert_close(capped, pushed_loss(k, 1))


def test_pushforward_gradient_is_the_multi_step_loss_through_the_rollout(tiny_dataset):
    """With pushforward_gradient (p = 1, M = 1, no noise) the loss is the mean of the pushed step's and the last
    step's squared errors, each against the true next frame, and its gradient flows through the predicted frame:
    it differs from the gradient of the same terms with that frame detached. Off, the loss is pushforward's.
    Several training processes are refused by name."""
    from surrogate.distributed import World
    simulator, sim = _untrained_simulator_and_first_train_sim(tiny_dataset)
    k, t = simulator.history, simulator.history + 1
    moving = ~sim.kinematic

    def hand_made(detach):
        earlier = sim.position[t - k:t]
        first = simulator(build_graph(earlier, sim.types, sim.kinematic, simulator.radius))
        first_error = ((first - simulator.target(earlier, sim.position[t])) ** 2)[moving]
        predicted = sim.position[t].clone()
        predicted[moving] = simulator.integrate(earlier, first)[0, moving]
        if detach:
            predicted = predicted.detach()
        window = torch.cat([sim.position[t - k + 1:t], predicted.unsqueeze(0)])
        last = simulator(build_graph(window, sim.types, sim.kinematic, simulator.radius))
        last_error = ((last - simulator.target(window, sim.position[t + 1])) ** 2)[moving]
        return torch.cat([first_error, last_error]).mean()

    def loss(gradient, world=None):
        return train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0), pushforward=1.0,
                                pushforward_gradient=gradient, world=world)

    got = loss(True)
    torch.testing.assert_close(got, hand_made(False))
    torch.testing.assert_close(_gradient(simulator, loss(True)), _gradient(simulator, hand_made(False)))
    assert not torch.allclose(_gradient(simulator, hand_made(False)), _gradient(simulator, hand_made(True)))
    assert not torch.isclose(got, loss(False))                      # off: only the last step's error
    with pytest.raises(ValueError, match="pushforward_gradient.*one training process"):
        loss(True, World(0, 2))


def test_weight_average_follows_the_ema_formula():
    model = torch.nn.Linear(2, 1)
    average = {k: v.clone() for k, v in model.state_dict().items()}
    start = average["weight"].clone()
    with torch.no_grad():
        model.weight.add_(1.0)
    train.ema_update(average, model, decay=0.99, step=0)          # warm-up: d = 1/10
    torch.testing.assert_close(average["weight"], start + 0.9)
    train.ema_update(average, model, decay=0.5, step=1000)        # d = 0.5 once warm
    torch.testing.assert_close(average["weight"], start + 0.95)


def _resumes_exactly(config: dict, folder, max_steps: int = 3, which: str = "last.pt"):
    """Trains ``config`` without a stop and, in another folder, stopped after ``max_steps`` and resumed; asserts
    both end at the same step with the same weights in ``which``; returns the whole run's state and weights."""
    whole = run(config, folder / "whole")
    run(config, folder / "parts", max_steps=max_steps)
    resumed = run(config, folder / "parts")
    assert resumed["step"] == whole["step"]
    wa = checkpoint.load(folder / "whole" / which)["model"]
    wb = checkpoint.load(folder / "parts" / which)["model"]
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    return whole, wa


def test_run_with_pushforward_and_weight_average_resumes_exactly(tiny_dataset, tmp_path):
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "pushforward": 0.5, "ema_decay": 0.9}}
    _, wa = _resumes_exactly(tiny, tmp_path, which="best.pt")
    last = checkpoint.load(tmp_path / "whole" / "last.pt")
    assert not all(torch.equal(last["model"][k], last["average_model"][k]) for k in wa)   # the average is kept apart


def test_activity_weighted_run_resumes_exactly_and_trains_on_other_draws(tiny_dataset, tmp_path):
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "activity_weight": 4.0}}
    whole, wa = _resumes_exactly(tiny, tmp_path)
    run(tiny_dataset, tmp_path / "uniform")
    uniform = checkpoint.load(tmp_path / "uniform" / "last.pt")
    assert uniform["json"]["state"]["step"] == whole["step"]
    assert not all(torch.equal(wa[k], uniform["model"][k]) for k in wa)


def test_a_decaying_activity_weight_resumes_exactly_and_differs_from_the_constant_one(tiny_dataset, tmp_path):
    """activity_weight 4 -> activity_weight_final 0: a stopped run resumes to the uninterrupted run's weights (the
    epoch's weight is a function of the epoch), and the run trains on other draws than the constant weight 4."""
    base = {**tiny_dataset["train"], "epochs": 2, "patience": 2}
    decaying = {**tiny_dataset, "train": {**base, "activity_weight": 4.0, "activity_weight_final": 0.0}}
    _, wa = _resumes_exactly(decaying, tmp_path, max_steps=1)
    constant = {**tiny_dataset, "train": {**base, "activity_weight": 4.0}}
    run(constant, tmp_path / "constant")
    assert not all(torch.equal(wa[k], checkpoint.load(tmp_path / "constant" / "last.pt")["model"][k]) for k in wa)


def test_weight_decay_is_adams_step_plus_a_decoupled_shrink_and_zero_is_adam():
    """AdamW's first step by hand: theta (1 - lr lambda) - lr g / (|g| + eps) (Adam's first step is lr sign(g) up to
    eps); a weight without gradient shrinks by (1 - lr lambda) per step; lambda absent or 0 is torch's plain Adam;
    a value outside [0, 1] is refused by name."""
    lr, lam = 1e-2, 0.1
    theta0 = torch.tensor([2.0, -1.0, 0.5])
    grad = torch.tensor([0.3, -4.0, 0.0])
    theta = torch.nn.Parameter(theta0.clone())
    optimiser = train.make_optimiser([theta], {"lr": lr, "weight_decay": lam})
    assert isinstance(optimiser, torch.optim.AdamW)
    for step in range(3):
        theta.grad = grad.clone() if step == 0 else torch.zeros(3)
        optimiser.step()
        if step == 0:
            expected = theta0 * (1 - lr * lam) - lr * grad / (grad.abs() + 1e-8)
            assert torch.allclose(theta.detach(), expected, rtol=1e-6, atol=1e-7)
    assert theta[2].item() == pytest.approx(0.5 * (1 - lr * lam) ** 3, rel=1e-6)      # never had a gradient
    for cfg in ({"lr": lr}, {"lr": lr, "weight_decay": 0}):
        optimiser = train.make_optimiser([torch.nn.Parameter(theta0.clone())], cfg)
        assert type(optimiser) is torch.optim.Adam and optimiser.defaults["weight_decay"] == 0
    for bad in (-0.1, 1.5, True, "0.1"):
        with pytest.raises(ValueError, match=r"train\.weight_decay = .*allowed a number in \[0, 1\]"):
            train.make_optimiser([torch.nn.Parameter(theta0.clone())], {"lr": lr, "weight_decay": bad})


def test_weight_decay_run_trains_other_weights_and_resumes_exactly(tiny_dataset, tmp_path):
    """A run with weight_decay resumes to the uninterrupted run's weights (the optimiser's state is AdamW's) and
    ends with smaller weights than the same run without decay."""
    decayed = {**tiny_dataset, "train": {**tiny_dataset["train"], "weight_decay": 0.5}}
    _, weights = _resumes_exactly(decayed, tmp_path, max_steps=1)
    run(tiny_dataset, tmp_path / "plain")
    plain = checkpoint.load(tmp_path / "plain" / "last.pt")["model"]
    norm = {name: sum(float(w[k].float().norm()) for k in w if w[k].is_floating_point())
            for name, w in (("decayed", weights), ("plain", plain))}
    assert norm["decayed"] < norm["plain"]


def test_learning_rate_cycles_restart_the_same_decay():
    """lr_cycles = 3 over 90 steps: three copies of the one-cycle decay over 30 steps, each from lr towards lr_final;
    absent, the one decay over all steps; past the planned steps, the final rate."""
    one = {"lr": 1e-3, "lr_final": 1e-5}
    three = {**one, "lr_cycles": 3}
    for step in range(30):
        expected = 1e-3 * (1e-5 / 1e-3) ** (step / 30)
        for cycle in range(3):
            assert train.learning_rate(three, cycle * 30 + step, 90) == pytest.approx(expected, rel=1e-12)
    assert [train.learning_rate(one, s, 90) for s in range(90)] == \
        [train.learning_rate({**one, "lr_cycles": 1}, s, 90) for s in range(90)]
    assert train.learning_rate(one, 45, 90) == pytest.approx(1e-4)                  # halfway in log: sqrt(1e-3 1e-5)
    assert train.learning_rate(three, 90, 90) == train.learning_rate(three, 500, 90) == pytest.approx(1e-5)
    assert train.learning_rate({"lr": 1e-3, "lr_final": None, "lr_cycles": 3}, 10, 90) == 1e-3


def test_snapshot_epochs_end_the_cycles_and_bad_cycle_counts_are_named():
    assert train.snapshot_epochs({"epochs": 18, "lr_final": 3e-5, "lr_cycles": 3}) == [6, 12, 18]
    assert train.snapshot_epochs({"epochs": 18, "lr_final": 3e-5}) == []
    with pytest.raises(ValueError, match=r"lr_cycles = 4 must divide train.epochs = 18"):
        train.snapshot_epochs({"epochs": 18, "lr_final": 3e-5, "lr_cycles": 4})
    with pytest.raises(ValueError, match=r"lr_cycles = 3 .*lr_final is null"):
        train.snapshot_epochs({"epochs": 18, "lr_final": None, "lr_cycles": 3})


def test_cyclic_run_keeps_a_snapshot_per_cycle_and_restarts_the_rate(tiny_dataset, tmp_path):
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "epochs": 4, "patience": 4, "lr_final": 1e-5,
                                      "lr_cycles": 2, "ema_decay": 0.9}}
    run(tiny, tmp_path)
    history = pd.read_csv(tmp_path / "history.csv")
    # the rate of each epoch's last step: low at each cycle's end, high again after the restart
    lr = list(history["lr"])
    assert lr[1] < lr[0] and lr[2] > 5 * lr[1] and lr[2] == pytest.approx(lr[0]) and lr[3] == pytest.approx(lr[1])
    assert sorted(p.name for p in tmp_path.glob("snapshot_*.pt")) == ["snapshot_1.pt", "snapshot_2.pt"]
    last = checkpoint.load(tmp_path / "last.pt")
    for c, epoch in ((1, 2), (2, 4)):
        snap = checkpoint.load(tmp_path / f"snapshot_{c}.pt")
        assert snap["json"]["epoch"] == epoch
        assert snap["json"]["valid_rollout_mse"] == pytest.approx(history["valid_rollout_mse"].iloc[epoch - 1])
    # the last cycle's snapshot is the run's final validated weights: the weight average
    final = checkpoint.load(tmp_path / "snapshot_2.pt")["model"]
    assert all(torch.equal(final[k], last["average_model"][k].cpu()) for k in final)
    with pytest.raises(ValueError, match="must divide train.epochs = 4"):
        run({**tiny, "train": {**tiny["train"], "lr_cycles": 3}}, tmp_path / "bad")
    assert not (tmp_path / "bad" / "history.csv").exists()


def test_a_cyclic_run_resumed_with_more_epochs_keeps_its_cycles_and_snapshots(tiny_dataset, tmp_path):
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "epochs": 2, "patience": 4, "lr_final": 1e-5,
                                      "lr_cycles": 2}}
    stopped = run(tiny, tmp_path, max_steps=1)
    assert not stopped["finished"]
    run({**tiny, "train": {**tiny["train"], "epochs": 4}}, tmp_path)        # resumed, two epochs more
    history = pd.read_csv(tmp_path / "history.csv")
    assert list(history["epoch"]) == [1, 2, 3, 4]
    # the cycles of the 2 planned epochs: a snapshot after each; past them the final rate, no further cycle
    assert sorted(p.name for p in tmp_path.glob("snapshot_*.pt")) == ["snapshot_1.pt", "snapshot_2.pt"]
    assert [checkpoint.load(tmp_path / f"snapshot_{c}.pt")["json"]["epoch"] for c in (1, 2)] == [1, 2]
    assert list(history["lr"].iloc[2:]) == pytest.approx([1e-5] * 2)


def _gradient(simulator, loss):
    simulator.zero_grad(set_to_none=True)
    loss.backward()
    return torch.cat([p.grad.flatten() for p in simulator.parameters()])


@pytest.mark.parametrize("processes", [2, 3, 12])
def test_the_shares_of_a_batch_average_to_the_one_process_loss_and_gradient(tiny_dataset, processes):
    """11 samples in shares of 6 and 5 (2 processes), 4, 4 and 3 (3), or one each and one empty share (12): the
    processes' mean loss and mean gradient (what DDP averages) are those of one process, with the same flips,
    pushforward steps and noise per sample."""
    from surrogate.distributed import World, share
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    split = tiny_dataset["split_table"]
    sims = [load_sim(path, stats) for path in split.loc[split["split"] == "train", "path"]]
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    batch = [(s, t) for s in range(2) for t in range(3, 9)][:11]
    options = {"mirror": True, "pushforward": 0.5, "pushforward_steps": 2}

    def loss(world=None):
        return train.batch_loss(simulator, sims, batch, 3e-3, torch.Generator().manual_seed(7), **options, world=world)

    whole = loss()
    expected = _gradient(simulator, whole)
    shares = [loss(World(rank, processes)) for rank in range(processes)]
    gradients = [_gradient(simulator, share) for share in shares]
    torch.testing.assert_close(torch.stack([s.detach() for s in shares]).mean(), whole.detach(), rtol=1e-5, atol=0)
    # float32 sums in another order: measured differences up to 3e-7 against gradient components up to 0.5
    torch.testing.assert_close(torch.stack(gradients).mean(dim=0), expected, rtol=1e-4, atol=1e-6)
    if processes == 12:
        assert shares[-1].item() == 0 and not gradients[-1].any()     # the empty share: weight 0, but a gradient
    else:   # each share's own mean, averaged (plain DDP over uneven shares), weights the samples unevenly
        moving = [sum(int((~sims[batch[i][0]].kinematic).sum()) for i in share(len(batch), World(rank, processes)))
                  for rank in range(processes)]
        means = [s.detach() * sum(moving) / (processes * m) for s, m in zip(shares, moving, strict=True)]
        assert abs(torch.stack(means).mean() / whole.detach() - 1) > 1e-3


def test_bfloat16_autocast_changes_the_training_loss_by_rounding_only(tiny_dataset):
    """train.precision = bfloat16 runs the forward passes (pushforward steps included) under autocast on the
    model's device; the weights and their gradients stay float32."""
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    split = tiny_dataset["split_table"]
    sims = [load_sim(path, stats) for path in split.loc[split["split"] == "train", "path"]]
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, tiny_dataset["model"])
    batch = [(0, 3), (1, 5), (0, 7)]

    def loss(precision):
        return train.batch_loss(simulator, sims, batch, 3e-4, torch.Generator().manual_seed(1), pushforward=1.0,
                                precision=precision)

    full, half = loss("float32"), loss("bfloat16")
    assert half.dtype == torch.float32 and 0 < abs(half.item() / full.item() - 1) < 0.01    # measured 2e-4
    half.backward()
    assert all(p.grad is not None and p.grad.dtype == torch.float32 for p in simulator.parameters())


def test_compiled_training_follows_the_eager_run_to_float32_rounding(tiny_dataset, tmp_path):
    """train.compile runs the training and validation forward passes through torch.compile (pushforward steps
    included); the run is the eager one up to float32 rounding, and its checkpoints are the eager model's."""
    from torch._dynamo.utils import counters

    from surrogate.simulator import LearnedSimulator
    tiny = {**tiny_dataset, "train": {**tiny_dataset["train"], "epochs": 2, "patience": 2, "pushforward": 1.0,
                                      "pushforward_steps": 2}}
    run(tiny, tmp_path / "eager")
    before = counters["stats"]["unique_graphs"]
    run({**tiny, "train": {**tiny["train"], "compile": True}}, tmp_path / "compiled")
    assert counters["stats"]["unique_graphs"] > before                        # it did compile
    eager, compiled = (pd.read_csv(tmp_path / name / "history.csv") for name in ("eager", "compiled"))
    assert (eager["train_loss"] > 0).all()
    assert list(compiled["step"]) == list(eager["step"])
    for column in ("train_loss", "valid_rollout_mse"):
        assert compiled[column].to_numpy() == pytest.approx(eager[column].to_numpy(), rel=1e-3)
    saved = checkpoint.load(tmp_path / "compiled" / "best.pt")
    plain = LearnedSimulator(json.loads(tiny_dataset["stats_json"]), tiny["model"])
    plain.load_state_dict(saved["model"])                                      # the same keys as an eager model's
    reference = checkpoint.load(tmp_path / "eager" / "best.pt")["model"]
    assert max(float((saved["model"][k] - reference[k]).abs().max()) for k in reference) < 1e-3


def test_a_bundled_model_is_trained_on_the_next_b_frames(tiny_dataset):
    """bundle 2, no noise: the loss is the squared error of both next frames' normalised accelerations; at p = 1
    (one pushed call) the history ends in the two frames the model predicted from the window two frames earlier.
    A sim has T - K - B + 1 samples."""
    from surrogate.simulator import LearnedSimulator
    stats = json.loads(tiny_dataset["stats_json"])
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, {**tiny_dataset["model"], "bundle": 2})
    split = tiny_dataset["split_table"]
    sim = load_sim(split.loc[split["split"] == "train", "path"].iloc[0], stats)
    k, t = simulator.history, simulator.history + 2
    assert sample_index([sim], k, 2) == [(0, s) for s in range(k - 1, sim.n_frames - 2)]
    moving = ~sim.kinematic

    def loss_from(window):
        graph = build_graph(window, sim.types, sim.kinematic, simulator.radius)
        target = simulator.target(window, sim.position[t + 1:t + 3])
        assert target.shape == (sim.kinematic.numel(), 4)
        return ((simulator(graph) - target) ** 2)[moving].mean()

    plain = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0))
    torch.testing.assert_close(plain, loss_from(sim.position[t - k + 1:t + 1]))
    earlier = sim.position[t - k - 1:t - 1]
    with torch.no_grad():
        predicted = simulator.step(build_graph(earlier, sim.types, sim.kinematic, simulator.radius),
                                   sim.position[t - 1:t + 1])
    pushed = train.batch_loss(simulator, [sim], [(0, t)], 0.0, torch.Generator().manual_seed(0), pushforward=1.0)
    torch.testing.assert_close(pushed, loss_from(torch.cat([sim.position[t - k + 1:t - 1], predicted])))
    assert not torch.isclose(pushed, plain)
    one_frame_before = [(0, k)]                    # one frame before the window: no whole call to push
    torch.testing.assert_close(
        train.batch_loss(simulator, [sim], one_frame_before, 0.0, torch.Generator(), pushforward=1.0),
        train.batch_loss(simulator, [sim], one_frame_before, 0.0, torch.Generator()))


FINETUNE = {"epochs": 2, "lr": 1e-4, "batch_size": 1, "frames": None, "max_grad_norm": 1.0, "ema_decay": 0.5}


def _finetuned(tiny, **changes):
    return {**tiny, "train": {**tiny["train"], "epochs": 2, "patience": 2, "ema_decay": 0.9,
                              "finetune": {**FINETUNE, **changes}}}


def test_finetuning_follows_the_one_step_epochs_from_their_best_weights(tiny_dataset, tmp_path):
    """Two one-step epochs, then two fine-tuning epochs of one rollout per step (two train sims: two steps each):
    history.csv says which is which; the first fine-tuning step starts from the one-step best weights; best.pt is
    the best validated epoch over both phases; the fine-tuning loss is the normalised rollout MSE."""
    tiny = _finetuned(tiny_dataset)
    plain = {**tiny, "train": {k: v for k, v in tiny["train"].items() if k != "finetune"}}
    run(plain, tmp_path / "plain")
    history = pd.read_csv(tmp_path / "plain" / "history.csv")
    one_step_steps = int(history["step"].iloc[-1])
    state = run(tiny, tmp_path / "tuned", max_steps=one_step_steps + 1)     # stopped after one fine-tuning step
    assert state["finetune"]["start_epoch"] == 2 and state["step"] == state["finetune"]["start_step"] + 1
    one_step = checkpoint.load(tmp_path / "plain" / "best.pt")
    last = checkpoint.load(tmp_path / "tuned" / "last.pt")
    assert all(torch.equal(one_step["model"][k], last["onestep_best"][k]) for k in one_step["model"])
    moved = [k for k in one_step["model"] if not torch.equal(one_step["model"][k], last["model"][k])]
    assert moved                                                      # one fine-tuning step from those weights
    run(tiny, tmp_path / "tuned")
    tuned = pd.read_csv(tmp_path / "tuned" / "history.csv")
    assert list(tuned["phase"]) == ["onestep", "onestep", "finetune", "finetune"]
    pd.testing.assert_frame_equal(tuned.iloc[:2].drop(columns=["seconds", "phase"]), history.drop(columns="seconds"))
    n = one_step_steps
    assert list(tuned["step"]) == [n // 2, n, n + 2, n + 4] and (tuned["lr"].iloc[2:] == FINETUNE["lr"]).all()
    best = checkpoint.load(tmp_path / "tuned" / "best.pt")["json"]
    assert best["valid_rollout_mse"] == pytest.approx(tuned["valid_rollout_mse"].min())


def test_a_finetuning_run_resumes_exactly(tiny_dataset, tmp_path):
    _resumes_exactly(_finetuned(tiny_dataset), tmp_path, max_steps=13, which="best.pt")    # in fine-tuning
    last = checkpoint.load(tmp_path / "parts" / "last.pt")
    assert {"finetune_optimiser", "finetune_average", "onestep_best"} <= set(last)


def test_a_run_stopped_at_the_one_step_end_resumes_both_phases_exactly(tiny_dataset, tmp_path):
    """Stopped after the last step of the one-step phase, before that epoch's validation: the resumed run closes the
    epoch, fine-tunes from the one-step best and ends with the uninterrupted run's history and every tensor of its
    last.pt (weights, averages, the one-step best) and best.pt."""
    tiny = _finetuned(tiny_dataset)
    run(tiny, tmp_path / "whole")
    whole = pd.read_csv(tmp_path / "whole" / "history.csv")
    one_step_steps = int(whole.loc[whole["phase"] == "onestep", "step"].iloc[-1])
    stopped = run(tiny, tmp_path / "parts", max_steps=one_step_steps)
    assert stopped["step"] == one_step_steps and stopped["epoch"] == 1 and "finetune" not in stopped
    run(tiny, tmp_path / "parts")
    parts = pd.read_csv(tmp_path / "parts" / "history.csv")
    pd.testing.assert_frame_equal(whole.drop(columns="seconds"), parts.drop(columns="seconds"))
    for which, keys in (("last.pt", ("model", "best_model", "average_model", "finetune_average", "onestep_best")),
                        ("best.pt", ("model",))):
        a, b = (checkpoint.load(tmp_path / folder / which) for folder in ("whole", "parts"))
        for key in keys:
            assert a[key].keys() == b[key].keys() and all(torch.equal(a[key][k], b[key][k]) for k in a[key]), key


def test_a_finished_run_is_continued_into_a_new_finetuning_not_retrained(tiny_dataset, tmp_path):
    """Adding train.finetune to a finished run, or changing it afterwards, gives what a run with that fine-tuning
    from the start gives; removing it ends the run where its one-step epochs ended."""
    tiny = _finetuned(tiny_dataset)
    plain = {**tiny, "train": {k: v for k, v in tiny["train"].items() if k != "finetune"}}
    other = _finetuned(tiny_dataset, lr=3e-4)
    run(tiny, tmp_path / "whole")
    run(plain, tmp_path / "added")
    one_step_steps = int(pd.read_csv(tmp_path / "added" / "history.csv")["step"].iloc[-1])
    state = run(tiny, tmp_path / "added")
    assert state["step"] == one_step_steps + 4                       # the one-step steps were not repeated
    run(other, tmp_path / "changed")
    run(tiny, tmp_path / "changed")
    for folder in ("added", "changed"):
        a = pd.read_csv(tmp_path / "whole" / "history.csv").drop(columns="seconds")
        b = pd.read_csv(tmp_path / folder / "history.csv").drop(columns="seconds")
        pd.testing.assert_frame_equal(a, b)
        wa = checkpoint.load(tmp_path / "whole" / "last.pt")["model"]
        wb = checkpoint.load(tmp_path / folder / "last.pt")["model"]
        assert all(torch.equal(wa[k], wb[k]) for k in wa)
    run(tiny, tmp_path / "removed", max_steps=one_step_steps + 3)
    state = run(plain, tmp_path / "removed")
    assert state["finished"] and state["epoch"] == 2
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "removed" / "history.csv").drop(columns="seconds"),
                                  pd.read_csv(tmp_path / "added" / "history.csv").iloc[:2].drop(
                                      columns=["seconds", "phase"]))


def test_bad_finetune_settings_are_refused_by_key_with_the_schemas_rule():
    assert train.check_finetune(None) is None and train.check_finetune(FINETUNE) == FINETUNE
    for key, bad, allowed in (("epochs", 0, "minimum"), ("lr", -1.0, "exclusiveMinimum"), ("lr", 2.0, "maximum"),
                              ("batch_size", 1.5, "integer"), ("batch_size", 5000, "maximum"), ("frames", 0, "minimum"),
                              ("max_grad_norm", 0, "exclusiveMinimum"), ("ema_decay", 1.0, "exclusiveMaximum"),
                              ("epochs", True, "integer"), ("warmup", -1, "minimum"), ("warmup", 2.5, "integer"),
                              ("lr_final", 0.0, "exclusiveMinimum"), ("lr_final", 1.5, "maximum"),
                              ("lr_final", True, "number")):
        with pytest.raises(ValueError, match=rf"'train.finetune.{key}' = {bad!r} is not allowed.*{allowed}"):
            train.check_finetune({**FINETUNE, key: bad})
    with pytest.raises(ValueError, match=r"'train.finetune.lr' = nan is not allowed: every number must be finite"):
        train.check_finetune({**FINETUNE, "lr": float("nan")})
    with pytest.raises(ValueError, match="'train.finetune' is missing 'lr'"):
        train.check_finetune({"epochs": 2})
    with pytest.raises(ValueError, match=r"unknown config key 'train.finetune.lr_decay' \(did you mean "
                                         r"'ema_decay'\?\); allowed keys under "
                                         r"train.finetune: batch_size, .*warmup"):
        train.check_finetune({**FINETUNE, "lr_decay": 0.5})
    with pytest.raises(ValueError, match=r"'train.finetune' = 3 is not allowed; allowed: null or a mapping of "
                                         r"epochs, lr"):
        train.check_finetune(3)
    scheduled = {**FINETUNE, "warmup": 3, "lr_final": None}
    assert train.check_finetune(scheduled) == scheduled


def test_the_finetuning_rate_warms_up_linearly_then_decays_exponentially():
    """Hand-computed: lr (s + 1) / W over the first W steps, then lr (lr_final / lr)^((s - W) / (S - W - 1)),
    reaching lr_final at the last of the S steps; without the keys the rate is constant."""
    cfg = {**FINETUNE, "lr": 1e-4}
    assert [train.finetune_rate(cfg, s, 10) for s in (0, 5, 9)] == [1e-4] * 3
    warm = {**cfg, "warmup": 4}
    assert [train.finetune_rate(warm, s, 10) for s in range(6)] == pytest.approx([2.5e-5, 5e-5, 7.5e-5, 1e-4,
                                                                                 1e-4, 1e-4])
    both = {**warm, "lr_final": 1e-6}                 # 10 steps: 4 of warm-up, then 1e-4 -> 1e-6 over steps 4..9
    rates = [train.finetune_rate(both, s, 10) for s in range(10)]
    assert rates[3] == pytest.approx(1e-4) and rates[4] == pytest.approx(1e-4) and rates[9] == pytest.approx(1e-6)
    assert rates[6] == pytest.approx(1e-4 * 0.01 ** 0.4)             # (6 - 4) / (10 - 4 - 1)
    assert train.finetune_rate({**cfg, "lr_final": 1e-5}, 0, 10) == pytest.approx(1e-4)


def test_a_scheduled_finetuning_records_its_rates_and_resumes_exactly(tiny_dataset, tmp_path):
    """With a warm-up and a decay, history.csv's lr of a fine-tuning epoch is the rate of its last step (two train
    sims, one per step: 4 steps over the 2 epochs), and an interrupted run resumes on the same schedule."""
    tiny = _finetuned(tiny_dataset, warmup=1, lr_final=1e-5)
    _resumes_exactly(tiny, tmp_path, max_steps=13, which="best.pt")
    history = pd.read_csv(tmp_path / "whole" / "history.csv")
    expected = [train.finetune_rate(tiny["train"]["finetune"], s, 4) for s in (1, 3)]
    assert list(history["lr"].iloc[2:]) == pytest.approx(expected) and expected[-1] == pytest.approx(1e-5)


def test_the_epochs_to_validate_are_each_phases_last_ones():
    base = {"epochs": 18, "finetune": {**FINETUNE, "epochs": 16}}
    assert train.validated_epochs(base) == (1, 1)                                     # absent: every epoch
    assert train.validated_epochs({**base, "validate_last": 6,
                                   "finetune": {**base["finetune"], "validate_last": 10}}) == (13, 7)
    assert train.validated_epochs({"epochs": 3, "validate_last": 5}) == (1, None)   # more than the phase: all
    assert train.validated_epochs({"epochs": 3, "validate_last": None}) == (1, None)
    with pytest.raises(ValueError, match=r"'train.finetune.validate_last' = 0 is not allowed.*minimum"):
        train.check_finetune({**FINETUNE, "validate_last": 0})


def test_validating_only_the_last_epochs_trains_the_same_weights_and_skips_the_rest(tiny_dataset, tmp_path):
    """Three one-step and three fine-tuning epochs, validated every epoch or only the last two one-step and the
    last fine-tuning epoch: the training losses and weights are the same to the bit, the skipped epochs have no
    validation error and are never the best, the others score as before, and an interrupted run continues when
    only validate_last changed."""
    every = {**tiny_dataset, "train": {**tiny_dataset["train"], "epochs": 3, "patience": 3, "ema_decay": 0.9,
                                       "finetune": {**FINETUNE, "epochs": 3}}}
    last = {**every, "train": {**every["train"], "validate_last": 2,
                               "finetune": {**every["train"]["finetune"], "validate_last": 1}}}
    run(every, tmp_path / "every")
    a = pd.read_csv(tmp_path / "every" / "history.csv")
    one_step_best = int(a.loc[a["phase"] == "onestep", "valid_rollout_mse"].idxmin()) + 1
    assert one_step_best >= 2, "the tiny run's one-step best must be a validated epoch for the weights to agree"
    steps = int(a["step"].iloc[2])                                  # stopped in the first fine-tuning epoch
    run(last, tmp_path / "last", max_steps=steps + 1)
    run(every, tmp_path / "last")                                   # continued (validate_last only skips work)
    state = run(last, tmp_path / "last2")
    b = pd.read_csv(tmp_path / "last2" / "history.csv")
    pd.testing.assert_series_equal(a["train_loss"], b["train_loss"])
    skipped = [1, 4, 5]                                             # epochs before each phase's validated ones
    assert b.loc[b["epoch"].isin(skipped), "valid_rollout_mse"].isna().all()
    assert not b.loc[b["epoch"].isin(skipped), "best"].any()
    kept = ~a["epoch"].isin(skipped)
    pd.testing.assert_series_equal(a.loc[kept, "valid_rollout_mse"], b.loc[kept, "valid_rollout_mse"])
    assert state["best_epoch"] == int(b["valid_rollout_mse"].idxmin()) + 1 and state["best_epoch"] not in skipped
    for folder in ("last", "last2"):
        wa = checkpoint.load(tmp_path / "every" / "last.pt")["model"]
        wb = checkpoint.load(tmp_path / folder / "last.pt")["model"]
        assert all(torch.equal(wa[k], wb[k]) for k in wa)
    resumed = pd.read_csv(tmp_path / "last" / "history.csv")
    assert resumed["valid_rollout_mse"].notna().sum() == 6 - 1      # resumed in epoch 4: validated from there on
