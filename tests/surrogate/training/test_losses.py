"""The one-step loss (surrogate/training/losses.py): the mirror image of a flow, and a batch shared by several
training processes, whose losses average to the one process's loss of the whole batch, draws included."""

import pytest
import torch

from surrogate import distributed
from surrogate.samples import load_sim
from surrogate.training import losses

from .. import saved


def test_the_mirror_reflects_x_in_the_domain_s_centre_and_keeps_the_other_axes():
    lower, upper = torch.tensor([-1.0, 0.0, 2.0]), torch.tensor([3.0, 5.0, 4.0])
    x = torch.tensor([[[-1.0, 1.0, 2.5], [0.5, 2.0, 3.0]]])
    # x -> x_lo + x_hi - x = 2 - x: -1 -> 3 and 0.5 -> 1.5; y and z as they were
    torch.testing.assert_close(losses.mirror_x(x, lower, upper), torch.tensor([[[3.0, 1.0, 2.5], [1.5, 2.0, 3.0]]]))
    torch.testing.assert_close(losses.mirror_x(losses.mirror_x(x, lower, upper), lower, upper), x)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    data = saved.untrained(tmp_path_factory.mktemp("losses"))
    sims = [load_sim(data["paths"][name], data["stats"]) for name in ("syn_00", "syn_01")]
    return data["simulator"], sims


@pytest.mark.parametrize("size", [2, 4])
def test_the_processes_shares_average_to_the_whole_batch_s_loss(data, size):
    simulator, sims = data
    batch = [(0, 3), (1, 4), (0, 5)]            # 3 samples: shares of 2 and 1, or of 1, 1, 1 and none
    options = dict(mirror=True, pushforward=0.5)

    def loss(world):
        with torch.no_grad():
            return float(losses.batch_loss(simulator, sims, batch, 0.01, torch.Generator().manual_seed(7),
                                           world=world, **options))

    whole = loss(distributed.World())
    shares = [loss(distributed.World(rank=r, size=size)) for r in range(size)]
    assert sum(shares) / size == pytest.approx(whole, rel=1e-5)
    if size == 4:
        assert shares[3] == 0.0                 # a process without a sample takes part with weight 0
