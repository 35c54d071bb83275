"""One message-passing round (article 4.3, eqs. 8-11) against its formula written out edge by edge: each edge's
message from its sender, itself and its receiver, each node's update from the sum of the messages it receives,
both added to what they update."""

import torch

from surrogate.model.updater import Updater


def _graph():
    torch.manual_seed(0)
    v = torch.randn(4, 3, dtype=torch.float64)
    # senders (row 0) to receivers (row 1): node 0 receives two messages, node 2 one, nodes 1 and 3 none
    edge_index = torch.tensor([[1, 2, 0], [0, 0, 2]])
    e = torch.randn(edge_index.shape[1], 3, dtype=torch.float64)
    return v, e, edge_index


def test_a_round_is_the_formula_written_out_edge_by_edge():
    v, e, edge_index = _graph()
    for split in (False, True):
        torch.manual_seed(1)
        updater = Updater(latent=3, hidden=5, layers=2, split_edge_mlp=split).double()
        v_out, e_out = updater(v, e, edge_index)
        messages = torch.stack([updater.edge_mlp(torch.cat([v[i], e[k], v[j]]))
                                for k, (i, j) in enumerate(edge_index.T.tolist())])
        received = torch.zeros_like(v)
        for k, j in enumerate(edge_index[1].tolist()):
            received[j] += messages[k]
        torch.testing.assert_close(e_out, e + messages)
        torch.testing.assert_close(v_out, v + updater.node_mlp(torch.cat([v, received], dim=-1)))
        # node 3 receives nothing: its update sees a zero sum
        nothing = torch.zeros(3, dtype=v.dtype)
        torch.testing.assert_close(v_out[3], v[3] + updater.node_mlp(torch.cat([v[3], nothing])))


def test_the_split_first_layer_is_the_same_arithmetic_regrouped():
    v, e, edge_index = _graph()
    torch.manual_seed(2)
    plain = Updater(3, 5, 3, split_edge_mlp=False).double()
    split = Updater(3, 5, 3, split_edge_mlp=True).double()
    split.load_state_dict(plain.state_dict())
    for a, b in zip(plain(v, e, edge_index), split(v, e, edge_index), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12)
