"""`graphdem shear-stress-readout` (evaluation/commands/shear_stress.py) on toy shear sims written as H5MD: the train
and valid sims of the split table, the epochs' history and the readout kept at the epoch of the lowest valid error."""

import numpy as np
import pandas as pd

from evaluation import shear_stress
from evaluation.commands import shear_stress as command
from generators import h5md

from ...command_line import run

R = 0.004


def _sim(path, seed: int, frames: int = 5) -> None:
    """A held wall of 4 spheres in the plane x = 0.05 + r (species 0), a kinematic sphere moving 1 mm per frame in x
    (the box's lower half), and 8 soil spheres (species 1) pressed against the wall by a random overlap, with a
    shear stress observable of 1 kPa per 1 % of overlap."""
    rng = np.random.default_rng(seed)
    wall = np.array([[0.05 + R, y, z] for y in (0.0, 0.01) for z in (0.0, 0.01)])
    position = np.zeros((frames, 13, 3))
    position[:, :4] = wall
    position[:, 4] = np.array([0.0, 0.0, -0.02]) + np.arange(frames)[:, None] * [0.001, 0.0, 0.0]
    overlap = rng.uniform(0.0, 0.02, (frames, 8))
    for t in range(frames):
        position[t, 5:] = wall[np.arange(8) % 4] - np.outer(2 * R * (1 - overlap[t]), [1.0, 0.0, 0.0])
    species = np.array([0] * 5 + [1] * 8)
    h5md.write(path, h5md.Trajectory(
        position=position, time=0.01 * np.arange(frames), step=np.arange(frames), species=species,
        radius=np.full(13, R), mass=np.where(species == 0, 0.0, 1e-3), kinematic=species == 0,
        box_lower=np.full(3, -0.1), box_upper=np.full(3, 0.1), parameters={
            "id": path.stem, "normal_stress": 2e4, "young": 2e7, "shear_area": 0.01},
        observables={"shear_stress": 1e5 * overlap.mean(axis=1)}, observable_units={"shear_stress": "Pa"}))


def test_the_readout_is_fitted_on_the_split_s_sims_and_kept_at_its_best_epoch(tmp_path, capsys):
    rows = []
    for i, split in enumerate(["train", "train", "valid"]):
        _sim(tmp_path / f"shear_{i}.h5", i)
        rows.append({"id": f"shear_{i}", "split": split, "path": str(tmp_path / f"shear_{i}.h5")})
    pd.DataFrame(rows).to_csv(tmp_path / "splits.csv", index=False)
    settings = '{"cutoff": 0.05, "hidden": 8, "layers": 1, "epochs": 4, "lr": 0.01, "seed": 0}'
    argv = ["shear-stress-readout", "--splits", str(tmp_path / "splits.csv"), "--settings-json", settings,
            "--out", str(tmp_path / "readout.pt"), "--history", str(tmp_path / "history.csv"), "--no-progress"]
    run(command.register, argv)
    history = pd.read_csv(tmp_path / "history.csv")
    assert len(history) == 4
    model, meta = shear_stress.load(tmp_path / "readout.pt")
    assert meta["train_sims"] == ["shear_0", "shear_1"] and meta["valid_sims"] == ["shear_2"]
    assert meta["valid_mse"] == history["valid_mse"].min()
    assert meta["epoch"] == int(history["valid_mse"].idxmin()) + 1
    assert f"valid MSE of tau / sigma_n {meta['valid_mse']:.4g} (epoch {meta['epoch']}), 2 train and 1 valid" \
        in capsys.readouterr().out
    # one seed, one readout
    run(command.register, [*argv[:5], "--out", str(tmp_path / "again.pt"), "--history", str(tmp_path / "h2.csv"),
                           "--no-progress"])
    again, _ = shear_stress.load(tmp_path / "again.pt")
    for a, b in zip(model.state_dict().values(), again.state_dict().values(), strict=True):
        np.testing.assert_array_equal(a.numpy(), b.numpy())
