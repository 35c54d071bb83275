"""Contact correction: too-deep overlaps are pushed apart to the allowed one, kinematic particles stay."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from generators.blowup import max_overlap_fraction
from generators.blowup import overlap_fractions as overlap_fractions_np
from surrogate import correction, runtime
from surrogate.batched import rollout_batch
from surrogate.correction import correct_overlaps, overlap_pairs, stop_at_kinematic
from surrogate.rollout import correct_step, new_counts, rollout


def overlap_fractions(x: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
    """(r_i + r_j - d) / min(r_i, r_j) of every pair i < j (negative: apart)."""
    i, j = torch.triu_indices(len(x), len(x), offset=1)
    d = (x[i] - x[j]).norm(dim=-1)
    return (r[i] + r[j] - d) / torch.minimum(r[i], r[j])


def squeezed_packing(n: int, dim: int, seed: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """A jittered lattice of ``n`` particles squeezed to 0.9 of its spacing (radii 0.5-0.55), the first
    tenth kinematic: many overlaps, pushes large enough to move particles past the Verlet skin."""
    generator = torch.Generator().manual_seed(seed)
    side = int(round(n ** (1 / dim))) + 1
    lattice = torch.stack(torch.meshgrid(*[torch.arange(side)] * dim, indexing="ij"), -1).reshape(-1, dim)[:n]
    x = (lattice.double() + 0.15 * torch.randn((n, dim), generator=generator, dtype=torch.float64)) * 0.9
    r = 0.5 * (1 + 0.1 * torch.rand(n, generator=generator, dtype=torch.float64))
    moving = torch.ones(n, dtype=torch.bool)
    moving[: n // 10] = False
    return x, r, moving


@pytest.mark.parametrize("dim", [2, 3])
def test_overlap_pairs_are_every_pair_within_reach_with_a_moving_particle_once(dim):
    x, r, moving = squeezed_packing(120, dim, seed=dim)
    moving[:40] = False
    pairs = overlap_pairs(x, r, moving, reach=1.7)
    found = {tuple(sorted(pair)) for pair in pairs.T.tolist()}
    assert len(found) == pairs.shape[1]                                            # each pair once
    i, j = torch.triu_indices(len(x), len(x), offset=1)
    close = ((x[i] - x[j]).norm(dim=-1) < 1.7) & (moving[i] | moving[j])            # brute force
    assert found == set(zip(i[close].tolist(), j[close].tolist(), strict=True))
    assert pairs.shape[1] > 0 and int((~moving[i] & ~moving[j] & ((x[i] - x[j]).norm(dim=-1) < 1.7)).sum()) > 0


@pytest.mark.parametrize("dim", [2, 3])
def test_the_verlet_list_finds_what_a_search_every_sweep_finds(dim, monkeypatch):
    """The skin only saves searches: with no skin (a search before every sweep that follows any motion)
    the corrected positions are the same to rounding, and the default skin searches far less often, yet
    more than once (particles moved past half the skin, so the list was renewed)."""
    x, r, moving = squeezed_packing(300, dim, seed=10 + dim)
    box = (x.min(dim=0).values - 1, x.max(dim=0).values + 1)
    searches = []

    def counted(*args):
        searches.append(1)
        return overlap_pairs(*args)

    monkeypatch.setattr(correction, "overlap_pairs", counted)
    listed, found = correct_overlaps(x, r, moving, 0.05, 60, *box)
    listed_searches = len(searches)
    searches.clear()
    every_sweep, found_every = correct_overlaps(x, r, moving, 0.05, 60, *box, skin=0.0)
    assert found == found_every > 100
    torch.testing.assert_close(listed, every_sweep, rtol=0, atol=1e-12)
    assert 1 < listed_searches < len(searches) / 3
    i, j = torch.triu_indices(len(x), len(x), offset=1)
    corrected = moving[i] | moving[j]                                   # two kinematic particles stay as they are
    deepest = float(overlap_fractions(x, r)[corrected].max())
    assert float(overlap_fractions(listed, r)[corrected].max()) < deepest / 2


def test_two_equal_discs_are_separated_to_the_allowed_overlap_around_their_centre_of_mass():
    x = torch.tensor([[0.0, 0.0], [1.2, 1.6]], dtype=torch.float64)        # d = 2, r = 1.5 each: overlap 1
    r = torch.tensor([1.5, 1.5], dtype=torch.float64)
    out, found = correct_overlaps(x, r, torch.tensor([True, True]), allowed_overlap=0.1, iterations=1)
    assert found == 1
    assert float((out[1] - out[0]).norm()) == pytest.approx(3.0 - 0.1 * 1.5, abs=1e-12)     # d = 2.85
    torch.testing.assert_close(out.mean(dim=0), x.mean(dim=0))
    torch.testing.assert_close(out[1] - out[0], (x[1] - x[0]) * 2.85 / 2.0)                  # along the centre line
    torch.testing.assert_close(x, torch.tensor([[0.0, 0.0], [1.2, 1.6]], dtype=torch.float64))  # input untouched


def test_a_kinematic_partner_stays_and_the_moving_one_takes_the_whole_push():
    x = torch.tensor([[0.0, 0.0], [1.0, 0.0]], dtype=torch.float64)
    r = torch.tensor([1.0, 0.5], dtype=torch.float64)                        # overlap 0.5 = 1 smaller radius
    out, found = correct_overlaps(x, r, torch.tensor([False, True]), allowed_overlap=0.0, iterations=1)
    assert found == 1
    torch.testing.assert_close(out[0], x[0], rtol=0, atol=0)
    torch.testing.assert_close(out[1], torch.tensor([1.5, 0.0], dtype=torch.float64))


def test_unequal_moving_discs_share_the_push_inversely_to_their_mass():
    x = torch.tensor([[0.0, 0.0], [2.0, 0.0]], dtype=torch.float64)
    r = torch.tensor([2.0, 1.0], dtype=torch.float64)                        # masses 4 : 1 in 2D, excess 1
    out, _ = correct_overlaps(x, r, torch.tensor([True, True]), allowed_overlap=0.0, iterations=1)
    torch.testing.assert_close(out, torch.tensor([[-0.2, 0.0], [2.8, 0.0]], dtype=torch.float64))


def test_separated_and_allowed_pairs_do_not_move():
    x = torch.tensor([[0.0, 0.0, 0.0], [2.5, 0.0, 0.0], [0.0, 1.95, 0.0]])    # apart; overlap 0.05 < 0.1 allowed
    r = torch.ones(3)
    out, found = correct_overlaps(x, r, torch.ones(3, dtype=torch.bool), allowed_overlap=0.1, iterations=5)
    assert found == 0
    assert torch.equal(out, x)


def test_a_3d_cluster_converges_below_the_allowed_overlap():
    generator = torch.Generator().manual_seed(0)
    x = torch.rand((40, 3), generator=generator, dtype=torch.float64) * 3.0    # 40 particles in a 3 m cube
    r = 0.4 + 0.2 * torch.rand(40, generator=generator, dtype=torch.float64)
    moving = torch.ones(40, dtype=torch.bool)
    moving[:4] = False
    before = overlap_fractions(x, r).max()
    out, found = correct_overlaps(x, r, moving, allowed_overlap=0.01, iterations=200)
    assert before > 0.5 and found > 10
    assert float(overlap_fractions(out, r).max()) < 0.01 + 1e-3
    torch.testing.assert_close(out[:4], x[:4], rtol=0, atol=0)


def test_a_3d_tetrahedral_cluster_converges_in_20_iterations():
    x = torch.tensor([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.75, 1.3, 0.0], [0.75, 0.43, 1.22]], dtype=torch.float64)
    r = torch.ones(4, dtype=torch.float64)                                   # every pair overlaps about 0.5 radii
    assert float(overlap_fractions(x, r).min()) > 0.49
    out, found = correct_overlaps(x, r, torch.ones(4, dtype=torch.bool), allowed_overlap=0.01, iterations=20)
    assert found == 6
    assert float(overlap_fractions(out, r).max()) < 0.01 + 1e-6


def test_a_3d_chain_against_a_kinematic_wall_converges():
    x = torch.tensor([[0.0, 0.0, 0.0], [1.5, 0.1, 0.0], [3.0, 0.0, 0.1], [4.5, -0.1, 0.0]], dtype=torch.float64)
    r = torch.ones(4, dtype=torch.float64)                                   # each neighbour overlaps 0.5 radii
    moving = torch.tensor([False, True, True, True])
    out, _ = correct_overlaps(x, r, moving, allowed_overlap=0.01, iterations=40)
    assert float(overlap_fractions(out, r).max()) < 0.01 + 1e-3
    assert torch.equal(out[0], x[0])


def test_coincident_particles_give_no_nan():
    x = torch.tensor([[0.5, 0.5], [0.5, 0.5], [0.5, 0.5]])
    r = torch.full((3,), 0.1)
    out, found = correct_overlaps(x, r, torch.tensor([True, True, False]), allowed_overlap=0.0, iterations=1)
    assert found == 3 and bool(torch.isfinite(out).all())
    assert not torch.equal(out[0], out[1]) and torch.equal(out[2], x[2])


def test_the_box_keeps_pushed_particles_in():
    x = torch.tensor([[0.0, 0.5], [0.1, 0.5]], dtype=torch.float64)
    r = torch.full((2,), 0.1, dtype=torch.float64)
    out, _ = correct_overlaps(x, r, torch.tensor([True, True]), 0.0, 50, torch.zeros(2, dtype=torch.float64),
                              torch.ones(2, dtype=torch.float64))
    assert float(out[:, 0].min()) >= 0.0
    assert float((out[1] - out[0]).norm()) == pytest.approx(0.2, abs=1e-6)


def test_bad_settings_are_refused():
    x, r, moving = torch.zeros((2, 2)), torch.ones(2), torch.ones(2, dtype=torch.bool)
    with pytest.raises(ValueError, match="allowed_overlap = -0.1"):
        correct_overlaps(x, r, moving, -0.1, 1)
    with pytest.raises(ValueError, match="iterations = 0"):
        correct_overlaps(x, r, moving, 0.1, 0)
    with pytest.raises(ValueError, match="skin = -0.5"):
        correct_overlaps(x, r, moving, 0.1, 1, skin=-0.5)
    with pytest.raises(ValueError, match="tolerance = -0.01"):
        correct_overlaps(x, r, moving, 0.1, 1, tolerance=-0.01)


def test_the_tolerance_ends_the_sweeps_at_the_first_sweep_within_it():
    """A pile pressed together: without a tolerance the sweeps run to the last (a pushed pair lands on
    the allowance and its neighbours move it back); with one, they end after the first sweep that leaves
    no pair deeper than allowed + tolerance, every sweep until then being the exact one (a search before
    every sweep, skin 0, so that one sweep at a time is the same arithmetic)."""
    n, allowed, tolerance, most = 40, 0.05, 0.01, 1000
    x, r, moving = squeezed_packing(n, 2, seed=3)
    sweeps, deepest = [x], []
    for _ in range(most):
        sweeps.append(correct_overlaps(sweeps[-1], r, moving, allowed, 1, skin=0.0)[0])
        deepest.append(max_overlap_fraction(sweeps[-1].numpy(), r.numpy(), ~moving.numpy()))
    first = next(k for k, value in enumerate(deepest, start=1) if value <= allowed + tolerance)
    assert 10 < first < most and deepest[-1] > allowed                # never exactly within the allowance
    exact, _ = correct_overlaps(x, r, moving, allowed, most, skin=0.0)
    assert torch.equal(exact, sweeps[-1])
    assert torch.equal(correct_overlaps(x, r, moving, allowed, most, skin=0.0, tolerance=0.0)[0], exact)
    ended, _ = correct_overlaps(x, r, moving, allowed, most, skin=0.0, tolerance=tolerance)
    assert torch.equal(ended, sweeps[first])


def test_a_single_or_resting_set_is_returned_unchanged():
    x = np.array([[0.0, 0.0]])
    out, found = correct_overlaps(torch.tensor(x), torch.ones(1), torch.ones(1, dtype=torch.bool), 0.0, 3)
    assert found == 0 and np.array_equal(out.numpy(), x)


RT = runtime.Runtime(split_edge_mlp=True, skip_kinematic_pairs=True, prune_isolated=True, precision="float32",
                     sleep_speed=None, keep_in_domain=False, compile=False)


def floor_and_faller(top: tuple[float, float], end: tuple[float, float]):
    """A row of fixed unit discs on the floor y = 0 (centres at y = 1, 1.8 apart: touching pairs leave no
    gap a unit disc fits through), a moving unit disc going from ``top`` to ``end`` in one step, and the
    box [-10, 10] x [0, 10]."""
    floor = torch.tensor([[x, 1.0] for x in np.arange(-5.4, 5.5, 1.8)], dtype=torch.float64)
    previous = torch.cat([floor, torch.tensor([top], dtype=torch.float64)])
    position = torch.cat([floor, torch.tensor([end], dtype=torch.float64)])
    moving = torch.zeros(len(previous), dtype=torch.bool)
    moving[-1] = True
    box = torch.tensor([-10.0, 0.0], dtype=torch.float64), torch.tensor([10.0, 10.0], dtype=torch.float64)
    return previous, position, torch.ones(len(previous), dtype=torch.float64), moving, box


def deepest_on_floor(x: torch.Tensor) -> float:
    """The largest overlap (in radii) of the moving disc (the last) with the floor's (the floor's own
    overlaps are its geometry)."""
    kinematic = np.ones(len(x), dtype=bool)
    kinematic[-1] = False
    return max_overlap_fraction(x.numpy(), np.ones(len(x)), kinematic)


def test_a_disc_that_falls_through_the_floor_in_one_step_is_stopped_on_it():
    """The collapse's failure: a disc predicted 3.5 radii down in one step ends under the floor's fixed
    discs; the box puts it back at y = 0, where the sweeps alone push it down along the wrong centre
    lines and leave it stuck inside the floor. The path test stops it where it met the floor first."""
    previous, position, r, moving, (lo, hi) = floor_and_faller((0.7, 3.2), (0.7, -0.3))
    position[-1, 1] = 0.0                                            # keep_in_domain's clamp
    alone, _ = correct_overlaps(position, r, moving, 0.05, 200, lo, hi)
    assert float(alone[-1, 1]) < 1.0                                 # under the floor's centres: through it
    assert deepest_on_floor(alone) > 0.3                             # and deep in it, for good
    stopped, count = stop_at_kinematic(previous, position, r, moving, 0.05, lo, hi)
    assert count == 1
    # the first disc met is the one at x = 0 (0.7 from the path, the next 1.1): contact at distance c = 1.95
    assert float((stopped[-1] - torch.tensor([0.0, 1.0], dtype=torch.float64)).norm()) >= 1.95 - 1e-9
    out, _ = correct_overlaps(stopped, r, moving, 0.05, 200, lo, hi)
    assert float(out[-1, 1]) > 2.5                                   # on top of the floor, in the notch
    assert deepest_on_floor(out) <= 0.05 + 1e-6
    torch.testing.assert_close(out[:-1], position[:-1], rtol=0, atol=0)   # the floor stays


def test_a_disc_resting_on_the_floor_within_the_tolerance_is_stopped_too():
    """A disc left by the sweeps just inside the allowed distance (their rounding, or their tolerance)
    starts the step in contact: a step through the floor from there is stopped where it was."""
    c = 2.0 - 0.05
    resting = (0.9, 1.0 + ((c - 1e-4) ** 2 - 0.81) ** 0.5)          # in the notch, 1e-4 inside c of both
    previous, position, r, moving, (lo, hi) = floor_and_faller(resting, (0.9, 0.0))
    stopped, count = stop_at_kinematic(previous, position, r, moving, 0.05, lo, hi)
    assert count == 1
    out, _ = correct_overlaps(stopped, r, moving, 0.05, 200, lo, hi)
    assert float(out[-1, 1]) > 2.5 and deepest_on_floor(out) <= 0.05 + 1e-6
    alone, _ = correct_overlaps(position, r, moving, 0.05, 200, lo, hi)
    assert float(alone[-1, 1]) < 1.0                                 # without the test: through the floor


def test_several_stopped_discs_are_each_stopped_as_alone():
    previous, position, r, moving, (lo, hi) = floor_and_faller((0.7, 3.2), (0.7, 0.0))
    second_before = torch.tensor([[-2.9, 4.0]], dtype=torch.float64)
    second_after = torch.tensor([[-2.5, 0.2]], dtype=torch.float64)
    both, count = stop_at_kinematic(torch.cat([previous, second_before]), torch.cat([position, second_after]),
                                    torch.ones(len(r) + 1, dtype=torch.float64), torch.cat([moving, moving[-1:]]),
                                    0.05, lo, hi)
    assert count == 2
    first, _ = stop_at_kinematic(previous, position, r, moving, 0.05, lo, hi)
    floor = torch.cat([previous[:-1], second_before]), torch.cat([position[:-1], second_after])
    second, _ = stop_at_kinematic(*floor, r, moving, 0.05, lo, hi)
    torch.testing.assert_close(both[-2], first[-1], rtol=0, atol=0)
    torch.testing.assert_close(both[-1], second[-1], rtol=0, atol=0)


def test_the_stop_keeps_the_motion_along_the_contact():
    """A path through a fixed disc's reach that ends past it, out of its reach again (no overlap at its
    end, so the sweeps would not see it), is stopped where it entered and slides on along the contact:
    at the contact p(s*) with normal n, the rest of the step (1 - s*) d without its normal part."""
    previous = torch.tensor([[0.0, 0.0], [-3.0, 1.5]], dtype=torch.float64)
    position = torch.tensor([[0.0, 0.0], [3.0, 1.5]], dtype=torch.float64)
    r, moving = torch.ones(2, dtype=torch.float64), torch.tensor([False, True])
    c = 2.0 - 0.05
    s = (6.0 - 2 * (c**2 - 1.5**2) ** 0.5) / 2 / 6.0                 # where |(-3 + 6 s, 1.5)| = c, entering
    contact = torch.tensor([-3.0 + 6.0 * s, 1.5], dtype=torch.float64)
    n = contact / c
    d = torch.tensor([6.0, 0.0], dtype=torch.float64)
    expected = contact + (1 - s) * (d - (d @ n) * n)
    out, count = stop_at_kinematic(previous, position, r, moving, 0.05)
    assert count == 1
    torch.testing.assert_close(out[1], expected)
    assert float(out[1].norm()) > c and float(out[1, 0]) > 0       # past the disc, never inside its reach
    graze = torch.tensor([[0.0, 0.0], [-1.0, 1.95 - 1e-3]], dtype=torch.float64)             # a sliding step
    untouched, count = stop_at_kinematic(graze, graze + torch.tensor([[0.0, 0.0], [2.0, 0.0]], dtype=torch.float64),
                                         r, moving, 0.0)
    assert count == 0 and float(untouched[1, 0]) == 1.0


def test_a_moving_wall_pushes_the_disc_it_passes_ahead_of_it():
    """Relative motion: a fixed (kinematic) disc moving 5 radii in one step through a resting disc
    leaves it in front, at the allowed distance, not behind."""
    previous = torch.tensor([[0.0, 0.0], [2.5, 0.0]], dtype=torch.float64)
    position = torch.tensor([[5.0, 0.0], [2.5, 0.0]], dtype=torch.float64)
    out, count = stop_at_kinematic(previous, position, torch.ones(2, dtype=torch.float64),
                                   torch.tensor([False, True]), 0.05)
    assert count == 1
    torch.testing.assert_close(out, torch.tensor([[5.0, 0.0], [6.95, 0.0]], dtype=torch.float64))


def test_a_disc_pressed_into_a_wall_or_free_of_walls_is_left_to_the_sweeps():
    """A path that ends inside the allowed distance on the near side, a path that misses, and a set with
    no kinematic particle are not touched (the sweeps' case; the meteorite has no kinematic particle)."""
    previous, position, r, moving, (lo, hi) = floor_and_faller((0.7, 3.2), (0.7, 2.4))     # pressed in
    out, count = stop_at_kinematic(previous, position, r, moving, 0.05, lo, hi)
    assert count == 0 and torch.equal(out, position)
    previous, position, r, moving, _ = floor_and_faller((0.7, 3.2), (4.0, 6.0))             # away
    out, count = stop_at_kinematic(previous, position, r, moving, 0.05)
    assert count == 0 and torch.equal(out, position)
    out, count = stop_at_kinematic(previous, position, r, torch.ones(len(r), dtype=torch.bool), 0.05)
    assert count == 0 and torch.equal(out, position)
    previous, position, r, moving, _ = floor_and_faller((0.2, 3.2), (0.2, 1.3))            # deep, but
    out, count = stop_at_kinematic(previous, position, r, moving, 2.5)      # an allowance past any contact
    assert count == 0 and torch.equal(out, position)


def test_the_rollout_step_stops_paths_only_where_it_has_the_frame_before():
    previous, position, r, moving, (lo, hi) = floor_and_faller((0.7, 3.2), (0.7, -0.3))
    walls = replace(RT, keep_in_domain=True, contact_correction={"allowed_overlap": 0.05, "iterations": 200})
    box = SimpleNamespace(lower=lo, upper=hi)
    counts = new_counts()
    out = correct_step(position, moving, r, walls, box, counts, previous)
    assert counts["clamped"] == 1 and counts["stopped"] == 1 and float(out[-1, 1]) > 2.5
    counts = new_counts()
    out = correct_step(position, moving, r, walls, box, counts)
    assert counts["stopped"] == 0 and float(out[-1, 1]) < 1.0


def test_runtime_takes_contact_correction_as_an_optional_key():
    assert RT.contact_correction is None
    assert runtime.Runtime.from_config(RT.as_dict()) == RT
    legacy = {key: value for key, value in RT.as_dict().items() if key != "contact_correction"}
    assert runtime.Runtime.from_config(legacy) == RT                     # a config written before the switch
    on = runtime.Runtime.from_config({**RT.as_dict(), "contact_correction": {"allowed_overlap": 0.01, "iterations": 5}})
    assert on.contact_correction == {"allowed_overlap": 0.01, "iterations": 5}
    with pytest.raises(ValueError, match="exactly the keys allowed_overlap, iterations"):
        replace(RT, contact_correction={"allowed_overlap": 0.01, "iteration": 5})
    with pytest.raises(ValueError, match="iterations = 0"):
        replace(RT, contact_correction={"allowed_overlap": 0.01, "iterations": 0})
    with pytest.raises(ValueError, match="allowed_overlap = -1"):
        replace(RT, contact_correction={"allowed_overlap": -1, "iterations": 3})
    tolerant = {"allowed_overlap": 0.01, "iterations": 5, "tolerance": 0.001}
    assert runtime.Runtime.from_config({**RT.as_dict(), "contact_correction": tolerant}).contact_correction == tolerant
    with pytest.raises(ValueError, match="tolerance = -0.001"):
        replace(RT, contact_correction={**tolerant, "tolerance": -0.001})


def max_overlap(position: np.ndarray, sim, start: int) -> float:
    """The largest overlap / smaller radius over the frames from ``start``."""
    radius, kinematic = np.asarray(sim.traj.radius, float), sim.kinematic.numpy()
    return max(float(overlap_fractions_np(np.asarray(x, float), radius, kinematic).max(initial=0.0))
               for x in position[start:])


@pytest.mark.engine
def test_a_rollout_with_the_switch_keeps_overlaps_at_the_allowed_one(untrained):
    """A model at rest (no acceleration) started from a history whose moving particles are squeezed
    towards their centre: off, the overlaps stay; on, every predicted frame is within the allowed one."""
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)
        simulator.acceleration_mean.zero_()
    k = simulator.history
    moving = ~sim.kinematic
    frame = sim.position[0].clone()
    centre = frame[moving].mean(dim=0)
    frame[moving] = centre + 0.85 * (frame[moving] - centre)
    start = frame.repeat(k, 1, 1)
    allowed = 0.02
    off = rollout(simulator, sim, runtime=RT, start=start)
    on_rt = replace(RT, contact_correction={"allowed_overlap": allowed, "iterations": 2000})
    on = rollout(simulator, sim, runtime=on_rt, start=start)
    assert off.first_nonfinite is None and on.first_nonfinite is None
    assert max_overlap(off.position, sim, k) > 0.2
    assert max_overlap(on.position, sim, k) <= allowed + 1e-3
    assert off.timing["corrected"] == 0 and on.timing["corrected"] > 0
    assert np.all(on.position[:, sim.kinematic.numpy()] == off.position[:, sim.kinematic.numpy()])


@pytest.mark.engine
def test_the_switch_off_or_idle_leaves_the_rollout_bit_identical(untrained):
    """Off, the rollout is the one without the switch; on with an overlap allowance no pair reaches, too."""
    simulator, sim = untrained
    reference = rollout(simulator, sim, runtime=RT)
    idle = rollout(simulator, sim, runtime=replace(RT, contact_correction={"allowed_overlap": 1e6, "iterations": 3}))
    np.testing.assert_array_equal(idle.position, reference.position)
    assert idle.timing["corrected"] == 0
    walls = replace(RT, keep_in_domain=True)
    batch = rollout_batch(simulator, [sim, sim], walls)
    single = rollout(simulator, sim, runtime=walls)
    assert all(b.timing["corrected"] == 0 for b in batch)
    np.testing.assert_allclose(batch[0].position, single.position, rtol=0, atol=1e-5)


@pytest.mark.engine
@pytest.mark.parametrize("forced", [False, True])
def test_rollouts_give_the_correction_the_step_start_and_the_tolerance(untrained, monkeypatch, forced):
    """Each step's path test starts from the frame the step started from (the predicted one, or the
    data's in a forced rollout), and the sweeps get the configured tolerance, alone and batched."""
    import surrogate.rollout as rollout_module
    simulator, sim = untrained
    seen = {"previous": [], "tolerance": []}

    def stop(previous, position, *args):
        seen["previous"].append(previous.clone())
        return correction.stop_at_kinematic(previous, position, *args)

    def sweeps(*args, tolerance=0.0, **kwargs):
        seen["tolerance"].append(tolerance)
        return correction.correct_overlaps(*args, tolerance=tolerance, **kwargs)

    monkeypatch.setattr(rollout_module, "stop_at_kinematic", stop)
    monkeypatch.setattr(rollout_module, "correct_overlaps", sweeps)
    on_rt = replace(RT, contact_correction={"allowed_overlap": 0.05, "iterations": 3, "tolerance": 0.002})
    k = simulator.history
    for run in (lambda: rollout(simulator, sim, runtime=on_rt, forced=forced),
                lambda: rollout_batch(simulator, [sim], on_rt, forced=forced)[0]):
        seen["previous"].clear(), seen["tolerance"].clear()
        result = run()
        starts = sim.position.numpy() if forced else result.position
        assert len(seen["previous"]) == sim.n_frames - k
        for t, previous in enumerate(seen["previous"], start=k):
            np.testing.assert_array_equal(previous.numpy(), starts[t - 1])
        assert seen["tolerance"] == [0.002] * (sim.n_frames - k)


@pytest.mark.engine
def test_batched_rollouts_correct_each_sim(untrained):
    simulator, sim = untrained
    with torch.no_grad():
        simulator.acceleration_std.mul_(1e-6)
        simulator.acceleration_mean.zero_()
    moving = ~sim.kinematic
    frame = sim.position[0].clone()
    centre = frame[moving].mean(dim=0)
    frame[moving] = centre + 0.85 * (frame[moving] - centre)
    squeezed = replace(sim, position=frame.repeat(sim.n_frames, 1, 1))
    on_rt = replace(RT, contact_correction={"allowed_overlap": 0.02, "iterations": 2000})
    batch = rollout_batch(simulator, [squeezed, sim], on_rt)
    alone = rollout(simulator, squeezed, runtime=on_rt)
    assert batch[0].timing["corrected"] == alone.timing["corrected"] > 0
    assert max_overlap(batch[0].position, sim, simulator.history) <= 0.02 + 1e-3
