import json

import numpy as np
import pandas as pd
import pytest

from generators import h5md
from surrogate import dataset


def constant_velocity_sim(path, velocity, accel=(0.0, 0.0), frames=6):
    """Two moving discs and one kinematic disc; moving ones follow p = p0 + v t + a t^2 / 2."""
    t = np.arange(frames)[:, None, None]
    p0 = np.array([[1.0, 1.0], [5.0, 5.0], [9.0, 9.0]])
    pos = p0[None] + np.asarray(velocity) * t + 0.5 * np.asarray(accel) * t**2
    pos[:, 2] = p0[2]                      # kinematic particle never moves
    h5md.write(path, h5md.Trajectory(
        position=pos, time=np.arange(frames) * 0.5, step=np.arange(frames), species=np.array([1, 1, 0]),
        radius=np.full(3, 0.4), mass=np.ones(3), kinematic=np.array([False, False, True]),
        box_lower=np.zeros(2), box_upper=np.full(2, 100.0)))


def test_stats_come_from_train_split_only(tmp_path):
    sims = tmp_path / "sims"
    constant_velocity_sim(sims / "a.h5", (0.1, -0.2), accel=(0.0, -0.02))
    constant_velocity_sim(sims / "b.h5", (0.3, -0.2), accel=(0.0, -0.02))
    constant_velocity_sim(sims / "c.h5", (50.0, 50.0))          # valid: must not leak into stats
    pd.DataFrame({"id": ["a", "b", "c"], "split": ["train", "train", "valid"]}).to_csv(
        tmp_path / "sweep.csv", index=False)
    table = dataset.split_table(pd.read_csv(tmp_path / "sweep.csv"), sims)
    stats = dataset.build(table, tmp_path / "out", connectivity_radius=2.5)
    assert stats["velocity_mean"][0] == pytest.approx(0.2)
    assert stats["velocity_std"][0] == pytest.approx(0.1)
    assert stats["acceleration_mean"] == pytest.approx([0.0, -0.02], abs=1e-6)
    assert stats["acceleration_std"][1] == pytest.approx(0.0, abs=1e-5)
    # y velocity: -0.2 + a t at frames 1..5 (differences), mean -0.2 - 0.02 * 2.5
    assert stats["velocity_mean"][1] == pytest.approx(-0.25, abs=1e-6)
    assert stats["dim"] == 2 and stats["n_types"] == 2 and stats["kinematic_species"] == [0]
    assert stats["frame_interval"] == pytest.approx(0.5)
    assert stats["connectivity_radius"] == 2.5
    assert stats["property_stats"]["radius"]["mean"] == pytest.approx(0.4)      # moving train particles
    written = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert written["velocity_mean"] == stats["velocity_mean"]
    splits = pd.read_csv(tmp_path / "out" / "splits.csv")
    assert list(splits["split"]) == ["train", "train", "valid"]


def test_empty_train_split_is_an_error(tmp_path):
    constant_velocity_sim(tmp_path / "a.h5", (0.1, 0.0))
    pd.DataFrame({"id": ["a"], "split": ["valid"]}).to_csv(tmp_path / "sweep.csv", index=False)
    with pytest.raises(ValueError, match="train split is empty"):
        dataset.build(dataset.split_table(pd.read_csv(tmp_path / "sweep.csv"), tmp_path), tmp_path / "out", 1.0)


def test_a_split_table_without_paths_is_an_error(tmp_path):
    with pytest.raises(ValueError, match=r"missing \['path'\]"):
        dataset.build(pd.DataFrame({"id": ["a"], "split": ["train"]}), tmp_path / "out", 1.0)


def test_stats_record_the_contact_miss_rate_of_r_on_the_train_split(tiny_dataset, tmp_path, capsys):
    """stats.json counts the train split's next-frame contacts and the share a graph of radius R misses, by the
    same function as surrogate/contacts.py; a radius that misses many warns, naming R."""
    from graphdem import cli
    from surrogate import contacts
    stats = json.loads(tiny_dataset["stats_path"].read_text())
    table = pd.read_csv(tiny_dataset["splits"])
    missed = total = 0
    trajectories = [h5md.read(path) for path in table.loc[table["split"] == "train", "path"]]
    for traj in trajectories:
        m, c = contacts.contact_misses(traj.position, traj.radius, stats["connectivity_radius"], traj.kinematic)
        missed, total = missed + m, total + c
    assert total > 0 and stats["next_frame_contacts"] == total
    assert stats["contact_miss_rate"] == pytest.approx(missed / total)
    # the floors: just above each, the train split's contacts missed are at most that share; at it, more
    for rate, floor in stats["contact_miss_floor"].items():
        for r, most in ((np.nextafter(floor, np.inf), True), (floor, False)):
            m = sum(contacts.contact_misses(t.position, t.radius, r, t.kinematic)[0] for t in trajectories)
            assert (m <= float(rate) * total) == most, (rate, r, m, total)
    assert list(stats["contact_miss_floor"]) == ["0.01", "0.001", "0.0001", "0"]
    tight = dataset.build(table, tmp_path / "tight", 1.0e-3)        # no pair is closer than 1 mm
    assert tight["contact_miss_rate"] == 1.0
    assert cli.main(["dataset", "--scene", "slide", "--table", str(tiny_dataset["splits"]),
                     "--out-dir", str(tmp_path / "cli"), "--connectivity-radius", "0.001"]) == 0
    assert "WARNING: R = 0.001 misses 1e+02 % of the next frame's contacts" in capsys.readouterr().out


def disc_sim(path, radii, kinematic, frames=6, seed=0):
    """Discs on a line, the moving ones drifting by a seeded random walk, the kinematic ones fixed."""
    rng = np.random.default_rng(seed)
    n = len(radii)
    kinematic = np.asarray(kinematic, bool)
    pos = np.broadcast_to(np.stack([np.arange(n) * 5.0 + 5.0, np.full(n, 10.0)], -1), (frames, n, 2)).copy()
    pos[:, ~kinematic] += np.cumsum(rng.normal(0.0, 0.05, (frames, int((~kinematic).sum()), 2)), axis=0)
    h5md.write(path, h5md.Trajectory(
        position=pos, time=np.arange(frames) * 0.5, step=np.arange(frames), species=np.where(kinematic, 0, 1),
        radius=np.asarray(radii, float), mass=np.ones(n), kinematic=kinematic,
        box_lower=np.zeros(2), box_upper=np.full(2, 100.0)))


def test_a_user_folder_is_split_and_its_radius_derived_from_the_moving_train_particles(tmp_path):
    """R = connectivity_diameters x the mean diameter of the moving particles of the train sims only: the kinematic
    discs (radius 2) and the valid and test sims (radius 1) do not count."""
    from generators import sweep
    folder = tmp_path / "mine"
    labels = sweep.split_labels(5, [0.6, 0.2, 0.2], 3)
    for i, split in enumerate(labels):
        radii = [0.3, 0.5, 2.0] if split == "train" else [1.0, 1.0, 2.0]
        disc_sim(folder / f"run-{i}.h5", radii, [False, False, True], seed=i)
    stats = dataset.build_user(folder, tmp_path / "out", [0.6, 0.2, 0.2], 3, None, 2.5, 6)
    assert stats["connectivity_radius"] == pytest.approx(2.5 * 2 * 0.4)
    rule = stats["derived"]["connectivity_radius"]
    assert rule["mean_diameter"] == pytest.approx(0.8) and rule["connectivity_diameters"] == 2.5
    assert stats["user_data"] == {"folder": str(folder), "fractions": [0.6, 0.2, 0.2], "seed": 3}
    splits = pd.read_csv(tmp_path / "out" / "splits.csv")
    assert list(splits["id"]) == [f"run-{i}" for i in range(5)] and list(splits["split"]) == labels
    assert stats["n_train_sims"] == 3 == labels.count("train")
    given = dataset.build_user(folder, tmp_path / "out2", [0.6, 0.2, 0.2], 3, 7.0, 2.5, 6)
    assert given["connectivity_radius"] == 7.0 and "derived" not in given


def test_a_user_sim_too_short_for_a_training_sample_is_refused_by_name(tmp_path):
    folder = tmp_path / "mine"
    for i in range(3):
        disc_sim(folder / f"s{i}.h5", [0.5, 0.5], [False, True], frames=8 if i else 5, seed=i)
    with pytest.raises(ValueError, match=r"s0.h5: 5 frames; .* each sim needs at least 7 \(model.history \+ "
                                         r"model.bundle\)"):
        dataset.build_user(folder, tmp_path / "out", [0.4, 0.3, 0.3], 0, None, 2.5, 7)
    assert not (tmp_path / "out").exists()
    assert dataset.mean_moving_radius([folder / "s1.h5", folder / "s2.h5"]) == pytest.approx(0.5)
    only_walls = tmp_path / "walls.h5"
    disc_sim(only_walls, [0.5, 0.5], [True, True])
    with pytest.raises(ValueError, match="no moving particle in the 1 train sims"):
        dataset.mean_moving_radius([only_walls])
