"""`graphdem rollout` (surrogate/commands/rollout.py) of an untrained model on a synthetic sim: the file it writes
holds the K given frames and the rollout stage's predictions, with the checkpoint's digest."""

import numpy as np

from generators import h5md
from surrogate import provenance
from surrogate import rollout as rollouts
from surrogate.commands import rollout
from surrogate.samples import load_sim

from ...command_line import run
from .. import saved


def test_the_rollout_file_is_the_rollout_of_the_checkpoint(tmp_path, capsys):
    data = saved.untrained(tmp_path / "data")
    sim_path = data["paths"]["syn_03"]
    run(rollout.register, ["rollout", "--checkpoint", str(data["checkpoint"]), "--data", str(sim_path),
                           "--out-dir", str(tmp_path / "rollouts")])
    out = tmp_path / "rollouts" / "syn_03.h5"
    predicted, sim = h5md.read(out), h5md.read(sim_path)
    k = data["simulator"].history
    np.testing.assert_array_equal(predicted.position[:k], sim.position[:k])
    expected = rollouts.rollout(data["simulator"], load_sim(sim_path, data["stats"]))
    np.testing.assert_allclose(predicted.position, expected.position, rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(predicted.position[:, sim.kinematic], sim.position[:, sim.kinematic])
    assert predicted.parameters["rollout_checkpoint_sha"] == provenance.digest(data["checkpoint"])
    assert f"{out}: {sim.n_frames - k} frames predicted" in capsys.readouterr().out
