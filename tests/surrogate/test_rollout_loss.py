"""The loss of rollout fine-tuning: the rollout MSE of a batch of rollouts, with the gradient through the steps."""

import json

import numpy as np
import pytest
import torch

from surrogate.graph import Graph, build_graph
from surrogate.rollout import rollout
from surrogate.rollout_loss import rollout_loss, rollout_starts
from surrogate.samples import load_sim
from surrogate.simulator import LearnedSimulator

pytestmark = pytest.mark.engine


def simulator_and_sims(tiny, **model_changes):
    stats = json.loads(tiny["stats_json"])
    table = tiny["split_table"]
    torch.manual_seed(0)
    simulator = LearnedSimulator(stats, {**tiny["model"], **model_changes})
    return simulator, [load_sim(p, stats) for p in table.loc[table["split"] == "train", "path"]]


def squared_error(result, sim):
    moving = ~sim.kinematic.numpy()
    k = result.history
    return ((result.position[k:, moving] - sim.position.numpy()[k:, moving]) ** 2).sum(-1)


@pytest.mark.parametrize("bundle", [1, 4])
def test_the_loss_is_the_batchs_rollout_mse_over_the_acceleration_variance(tiny_dataset, bundle):
    """Two train sims rolled out from their first K frames: the loss is their squared position error summed over
    every predicted particle-frame, over that count and the summed acceleration variance; the same with four frames
    per call (the second call's last two dropped)."""
    simulator, sims = simulator_and_sims(tiny_dataset, bundle=bundle)
    loss = rollout_loss(simulator, sims, None, torch.Generator().manual_seed(0))
    errors = np.concatenate([squared_error(rollout(simulator, sim), sim).ravel() for sim in sims])
    variance = float((simulator.acceleration_std.double() ** 2).sum())
    assert float(loss) == pytest.approx(errors.mean() / variance, rel=1e-5)


def test_the_gradient_runs_through_the_predicted_frames(tiny_dataset):
    """Over two predicted frames the gradient is that of the rollout, not of two one-step errors: with the first
    predicted frame detached before the second step, the gradient differs."""
    simulator, sims = simulator_and_sims(tiny_dataset)
    sim, k = sims[0], simulator.history
    loss = rollout_loss(simulator, [sim], 2, torch.Generator().manual_seed(0))
    start = rollout_starts([sim], k, 2, torch.Generator().manual_seed(0))[0]

    def by_hand(detach):
        window, total = sim.position[start:start + k], 0.0
        for t in range(start + k, start + k + 2):
            edges = build_graph(window.detach(), sim.types, sim.kinematic, simulator.radius)
            frame = simulator.step(Graph(window, edges.types, edges.kinematic, edges.edge_index, None),
                                   sim.position[t])[0]
            total = total + ((frame[~sim.kinematic] - sim.position[t][~sim.kinematic]) ** 2).sum()
            window = torch.cat([window[1:], (frame.detach() if detach else frame).unsqueeze(0)])
        variance = (simulator.acceleration_std ** 2).sum()
        return total / (2 * int((~sim.kinematic).sum()) * variance)

    torch.testing.assert_close(loss, by_hand(False))

    def gradient(value):
        simulator.zero_grad()
        value.backward()
        return torch.cat([p.grad.flatten() for p in simulator.parameters() if p.grad is not None])

    through = gradient(rollout_loss(simulator, [sim], 2, torch.Generator().manual_seed(0)))
    torch.testing.assert_close(through, gradient(by_hand(False)))
    assert not torch.allclose(through, gradient(by_hand(True)))


def test_starts_leave_the_frames_asked_for():
    """With ``frames`` a start leaves the history and that many frames; without it every rollout starts at 0."""
    class Fake:
        n_frames = 10
    sims, generator = [Fake()] * 50, torch.Generator().manual_seed(1)
    assert rollout_starts(sims, 4, None, generator) == [0] * 50
    starts = rollout_starts(sims, 4, 2, generator)
    assert set(starts) == {0, 1, 2, 3, 4}                             # 4 + 4 + 2 = 10: the last start is 4
    assert rollout_starts(sims, 4, 20, generator) == [0] * 50          # more frames than the sim has: from 0
    with pytest.raises(ValueError, match=r"train.finetune.frames = 0: allowed an integer >= 1 or null"):
        rollout_starts(sims, 4, 0, generator)
