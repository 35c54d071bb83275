"""The shear-stress readout: which walls are held, the soil-wall pairs against brute force, the readout's sum, and
a fit that recovers a known linear-spring pair law from frames it generated."""

import math

import numpy as np
import pytest
import torch

from evaluation import shear_stress as stress

AREA = 0.01          # m^2


def _box(rng, frames=6, soil=24, pressed=True):
    """A toy shear box in [T, N, 3]: a held wall of spheres in the plane x = 0.05 (species 0), a lower-half
    particle moving 1 mm per frame in x (species 0), a platen sphere moving in z only (species 2), and soil spheres
    (species 1) jittering against the wall, overlapping it by up to 2 % of the pair's reach when ``pressed``."""
    r = 0.004
    wall = np.array([[0.05 + r, y, z] for y in (0.0, 0.01, 0.02) for z in (0.0, 0.01, 0.02)])
    n_wall = len(wall)
    position = np.zeros((frames, n_wall + 2 + soil, 3))
    position[:, :n_wall] = wall
    position[:, n_wall] = [0.0, 0.0, -0.02] + np.arange(frames)[:, None] * [0.001, 0, 0]
    position[:, n_wall + 1] = [0.02, 0.01, 0.03] + np.arange(frames)[:, None] * [0, 0, 1e-5]
    for t in range(frames):
        j = rng.integers(0, n_wall, soil)
        overlap = rng.uniform(-0.02, 0.02 if pressed else -0.001, soil) * 2 * r
        position[t, n_wall + 2:] = wall[j] - np.outer(2 * r - overlap, [1.0, 0.0, 0.0])
    species = np.array([0] * (n_wall + 1) + [2] + [1] * soil)
    kinematic = species != 1
    return position, np.full(len(species), r), species, kinematic


def _sample(position, radius, species, kinematic, normal_stress=2e4, young=2e7, shear_stress=None):
    return stress.Sample("toy", position, radius, ~kinematic, stress.held_mask(position, kinematic), species,
                         normal_stress, young, AREA, 3,
                         np.full(len(position), np.nan) if shear_stress is None else shear_stress)


def test_held_walls_are_the_kinematic_particles_that_do_not_move_along_the_shear():
    position, _, species, kinematic = _box(np.random.default_rng(0))
    held = stress.held_mask(position, kinematic)
    n_wall = 9
    assert held[:n_wall].all() and not held[n_wall] and held[n_wall + 1]     # wall, lower half, platen
    assert not held[n_wall + 2:].any()                                          # no soil
    with pytest.raises(ValueError, match="no kinematic particle moves in x"):
        stress.held_mask(np.zeros((3, 4, 3)), np.array([True, True, False, False]))


def test_pairs_match_brute_force_and_their_features_are_the_geometry():
    rng = np.random.default_rng(1)
    position, radius, species, kinematic = _box(rng)
    sample = _sample(position, radius, species, kinematic)
    cutoff = 0.05
    found = stress.pairs(sample, cutoff, 3)
    soil, held = np.flatnonzero(~kinematic), np.flatnonzero(sample.held)
    expected = []
    for t in range(1, len(position)):
        for i in soil:
            for j in held:
                d = position[t, j] - position[t, i]
                gap = np.linalg.norm(d) / (radius[i] + radius[j]) - 1
                if gap < cutoff:
                    dv = (position[t, j] - position[t - 1, j] - position[t, i] + position[t - 1, i]) / (2 * radius[i])
                    kappa = sample.young / sample.normal_stress
                    expected.append([t - 1, *np.eye(3)[species[j]], *(d / np.linalg.norm(d)), gap,
                                     kappa * max(-gap, 0.0), *dv, math.log10(kappa)])
    expected = np.array(sorted(expected, key=lambda row: tuple(row)))
    got = np.column_stack([found.frame, found.features])
    got = got[np.lexsort(got.T[::-1])]
    assert len(got) == len(expected) > 0
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(found.weight, (2 * radius[0]) ** 2 / AREA)


class SpringLaw(torch.nn.Module):
    """A linear spring's x-force on the held wall, in units of sigma_n (r_i + r_j)^2: s n_x / 2 (a = n_x / 2,
    b = 0)."""

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return torch.stack([0.5 * features[:, 3], torch.zeros(len(features))], dim=-1)


def test_the_readout_sums_the_pair_forces_over_the_area():
    """With g set to a linear spring's x-force (the module's equation), the readout is the spring forces' sum
    over the area: tau = sum_ij (k delta_ij) n_x / A with k (r_i + r_j)^2 sigma_n = E (r_i + r_j) / 2."""
    position, radius, species, kinematic = _box(np.random.default_rng(2))
    sample = _sample(position, radius, species, kinematic)
    n_features = 3 + len(stress.FEATURES)
    model = stress.StressReadout(n_features, 8, 1, torch.zeros(n_features), torch.ones(n_features))
    model.mlp = SpringLaw()
    tau = stress.read(model, sample, cutoff=0.05)
    soil, held = np.flatnonzero(~kinematic), np.flatnonzero(sample.held)
    for t in range(1, len(position)):
        force = 0.0
        for i in soil:
            for j in held:
                d = position[t, j] - position[t, i]
                reach = radius[i] + radius[j]
                overlap = reach - np.linalg.norm(d)
                if overlap > 0:
                    force += sample.young * reach / 2 * overlap * d[0] / np.linalg.norm(d)
        assert tau[t] == pytest.approx(force / AREA, rel=1e-5)
        assert tau[t] > 0                              # the soil pushes the held wall along +x
    assert np.isnan(tau[0])                            # no velocity at the first frame
    broken = position.copy()
    broken[3, -1] = np.nan
    tau = stress.read(model, _sample(broken, radius, species, kinematic), cutoff=0.05)
    assert np.isnan(tau[3]) and np.isnan(tau[4]) and np.isfinite(tau[[1, 2, 5]]).all()


def _spring_sims(n, rng):
    samples = []
    for k in range(n):
        position, radius, species, kinematic = _box(rng, frames=8)
        normal_stress, young = [5e3, 2e4, 5e4][k % 3], [1e7, 3e7, 1e8][k // 3 % 3]
        sample = _sample(position, radius, species, kinematic, normal_stress, young)
        n_features = 3 + len(stress.FEATURES)
        truth = stress.StressReadout(n_features, 8, 1, torch.zeros(n_features), torch.ones(n_features))
        truth.mlp = SpringLaw()
        observed = stress.read(truth, sample, cutoff=0.05)
        observed[0] = 0.0
        samples.append(_sample(position, radius, species, kinematic, normal_stress, young, observed))
    return samples


def test_a_fit_recovers_a_linear_spring_law_from_the_frames_it_made():
    rng = np.random.default_rng(3)
    train, valid = _spring_sims(9, rng), _spring_sims(3, rng)
    cfg = {"cutoff": 0.05, "hidden": 32, "layers": 2, "epochs": 300, "lr": 1e-2, "seed": 0}
    model, meta, history = stress.fit(train, valid, cfg, progress=False)
    assert meta["epoch"] == int(history["valid_mse"].idxmin()) + 1 and meta["valid_mse"] == history["valid_mse"].min()
    # the train sims' tau / sigma_n per frame, kept for the shear-stress check's Coulomb floor
    assert len(meta["train_stress_ratio"]) == len(train)
    np.testing.assert_allclose(meta["train_stress_ratio"][4], train[4].shear_stress / train[4].normal_stress)
    for sample in valid:
        tau = stress.read(model, sample, cfg["cutoff"])[1:]
        truth = sample.shear_stress[1:]
        # the valid sims' stress to 10 % RMS, from a law the readout was not told (a constant: 30-40 %)
        assert np.sqrt(np.mean((tau - truth) ** 2)) < 0.1 * truth.mean()
        assert np.sqrt(np.mean((truth - truth.mean()) ** 2)) > 0.2 * truth.mean()
    # one seed, one result
    again, _, _ = stress.fit(train, valid, cfg, progress=False)
    assert all(torch.equal(a, b) for a, b in zip(model.state_dict().values(), again.state_dict().values(),
                                                  strict=True))


def test_a_readout_round_trips_and_a_foreign_checkpoint_is_refused(tmp_path):
    rng = np.random.default_rng(4)
    train, valid = _spring_sims(3, rng), _spring_sims(1, rng)
    cfg = {"cutoff": 0.05, "hidden": 8, "layers": 1, "epochs": 5, "lr": 1e-3, "seed": 0}
    model, meta, _ = stress.fit(train, valid, cfg, progress=False)
    stress.save(tmp_path / "readout.pt", model, meta)
    loaded, loaded_meta = stress.load(tmp_path / "readout.pt")
    assert loaded_meta == meta
    np.testing.assert_array_equal(stress.read(model, valid[0], 0.05), stress.read(loaded, valid[0], 0.05))
    from surrogate import checkpoint
    checkpoint.save(tmp_path / "other.pt", {"model": {"w": torch.zeros(1)}, "json": {"epoch": 1}})
    with pytest.raises(ValueError, match="not a shear-stress readout"):
        stress.load(tmp_path / "other.pt")


def test_training_without_the_observable_is_refused_by_sim():
    rng = np.random.default_rng(5)
    position, radius, species, kinematic = _box(rng)
    bare = _sample(position, radius, species, kinematic)
    with pytest.raises(ValueError, match="sims toy: no finite shear_stress observable"):
        stress.fit([bare], [bare], {"cutoff": 0.05, "hidden": 4, "layers": 1, "epochs": 1, "lr": 1e-3, "seed": 0},
                   progress=False)
