"""Seeded fuzz of every reader: malformed H5MD files through `graphdem inspect` and `graphdem evaluate`, malformed
Solid-GN pickles and metadata through `graphdem import-solidgn`.

Each must end in a one-line error that names the file (exit status 1): no traceback, no allocation above
ALLOCATION_BOUND, and nothing left behind (no output, no half import).
"""

from __future__ import annotations

import json
import pickle
import shutil
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest

from generators import h5md
from graphdem import cli
from surrogate import checkpoint, dataset
from surrogate.simulator import LearnedSimulator

ALLOCATION_BOUND = 64 * 2**20
SEEDS = range(6)


def valid_trajectory(rng: np.random.Generator) -> h5md.Trajectory:
    t, n = 6, 12
    position = 5.0 + np.cumsum(rng.normal(0, 0.05, (t, n, 2)), axis=0)
    species = np.array([0, 0] + [1] * (n - 2))
    return h5md.Trajectory(position=position, time=np.arange(t) * 0.1, step=np.arange(t) * 10, species=species,
                           radius=np.full(n, 0.2), mass=np.where(species == 0, 0.0, 1.0), kinematic=species == 0,
                           box_lower=np.zeros(2), box_upper=np.full(2, 10.0), boundary=("none", "none"),
                           parameters={"scene": "fuzz"})


def _replace(f: h5py.File, key: str, data, **kwargs) -> None:
    del f[key]
    f.create_dataset(key, data=data, **kwargs)


# Each mutation edits a copy of a valid file (path) with the seeded generator rng.
def truncate(path: Path, rng) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(rng.integers(0, len(data) - 1))])


def flip_bytes(path: Path, rng) -> None:
    data = bytearray(path.read_bytes())
    for i in rng.integers(0, 512, 40):           # the superblock and root objects
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))


def edit(fn):
    def mutate(path: Path, rng) -> None:
        with h5py.File(path, "r+") as f:
            fn(f, rng)
    mutate.__name__ = fn.__name__
    return mutate


POS, SPECIES, EDGES = "particles/all/position/value", "particles/all/species", "particles/all/box/edges/value"
# name -> mutation; the last ones are valid H5MD that only the model refuses (evaluate, not inspect)
H5MD_MUTATIONS = {
    "truncated": truncate, "flipped_bytes": flip_bytes,
    "no_position": edit(lambda f, rng: f.__delitem__(POS)),
    "no_species": edit(lambda f, rng: f.__delitem__(SPECIES)),
    "no_box_edges": edit(lambda f, rng: f.__delitem__("particles/all/box/edges")),
    "no_h5md_group": edit(lambda f, rng: f.__delitem__("h5md")),
    "h5md_version_2+": edit(lambda f, rng: f["h5md"].attrs.__setitem__("version", [int(rng.integers(2, 9)), 0])),
    "string_positions": edit(lambda f, rng: _replace(f, POS, np.full((6, 12, 2), "x", dtype="S4"))),
    "positions_2_axes": edit(lambda f, rng: _replace(f, POS, rng.normal(size=(6, 24)))),
    "positions_1d_or_4d": edit(lambda f, rng: _replace(f, POS, rng.normal(size=(6, 12, int(rng.choice([1, 4])))))),
    "one_frame": edit(lambda f, rng: _replace(f, POS, rng.normal(size=(1, 12, 2)))),
    "zero_particles": edit(lambda f, rng: _replace(f, POS, rng.normal(size=(6, 0, 2)))),
    "nan_positions": edit(lambda f, rng: _replace(f, POS, np.where(rng.random((6, 12, 2)) < 0.1, np.nan, 1.0))),
    "declares_7_GiB": edit(lambda f, rng: _replace(f, POS, shape=(20, 50_000_000, 2), dtype="f4",
                                                   chunks=(1, 100_000, 2), compression="gzip", data=None)),
    "negative_species": edit(lambda f, rng: _replace(f, SPECIES, -rng.integers(1, 5, 12))),
    "float_species": edit(lambda f, rng: _replace(f, SPECIES, rng.random(12) + 0.5)),
    "short_species": edit(lambda f, rng: _replace(f, SPECIES, np.arange(int(rng.integers(1, 11))))),
    "integer_kinematic": edit(lambda f, rng: _replace(f, "particles/all/kinematic", rng.integers(0, 2, 12))),
    "negative_radius": edit(lambda f, rng: _replace(f, "particles/all/radius", -rng.random(12))),
    "time_backwards": edit(lambda f, rng: _replace(f, "particles/all/position/time", np.arange(6)[::-1] * 1.0)),
    "negative_box": edit(lambda f, rng: _replace(f, "particles/all/box/edges", np.array([-1.0, 10.0]))),
    "negative_box_every_frame": edit(lambda f, rng: f[EDGES].__setitem__(Ellipsis, [-rng.uniform(0.1, 5), 10.0])),
    "box_changes_over_time": edit(lambda f, rng: f[EDGES].__setitem__(int(rng.integers(0, 6)), rng.uniform(1, 9, 2))),
    "box_edges_no_value": edit(lambda f, rng: f.__delitem__(EDGES)),
    "box_edges_short_of_frames": edit(lambda f, rng: _replace(f, EDGES, np.full((int(rng.integers(1, 6)), 2), 10.0))),
    "box_edges_one_row": edit(lambda f, rng: _replace(f, EDGES, np.full(2, 10.0))),
    "string_box_edges": edit(lambda f, rng: _replace(f, EDGES, np.full((6, 2), "x", dtype="S4"))),
    "box_edges_declare_4_GiB": edit(lambda f, rng: _replace(f, EDGES, shape=(6, 100_000_000), dtype="f8",
                                                            chunks=(1, 100_000), compression="gzip", data=None)),
    "box_edges_a_group": edit(lambda f, rng: (f.__delitem__("particles/all/box/edges"),
                                              f.create_group("particles/all/box/edges"))),
    "short_observable": edit(lambda f, rng: f.create_dataset("observables/energy/value",
                                                             data=rng.random(int(rng.integers(1, 5))))),
    "string_properties": edit(lambda f, rng: f.create_dataset("particles/all/properties",
                                                              data=np.array([["a"] * 2] * 12, dtype="S2"))),
    "species_beyond_the_model": edit(lambda f, rng: _replace(f, SPECIES, np.full(12, 1000 + int(rng.integers(0, 5))))),
    "another_scene": edit(lambda f, rng: f["parameters"].attrs.__setitem__("scene", "meteorite")),
}
EVALUATE_ONLY = {"species_beyond_the_model", "another_scene"}


@pytest.fixture(scope="module")
def fuzz_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    good = h5md.write(root / "good.h5", valid_trajectory(np.random.default_rng(0)))
    stats = dataset.statistics([good], 1.0)
    model = {"history": 3, "embed": 4, "mlp_layers": 2, "properties": [], "latent": 8, "hidden": 8,
             "message_passing": 1}
    checkpoint.save(root / "model.pt", {"model": LearnedSimulator(stats, model).state_dict(),
                                        "json": {"stats": stats, "model": model, "train": {}}})
    return root


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """Exit status and stderr of `graphdem argv` run in-process; fails on an escaped exception or on an
    allocation above ALLOCATION_BOUND."""
    tracemalloc.start()
    try:
        try:
            code = cli.main(argv)
        except SystemExit as exc:            # argparse and refusals exit with a message
            code = exc.code if isinstance(exc.code, int) else 1
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < ALLOCATION_BOUND, f"{argv}: allocated {peak / 2**20:.0f} MiB"
    return code, capsys.readouterr().err


def test_the_valid_file_and_checkpoint_pass(fuzz_root, capsys):
    assert run_cli(["inspect", str(fuzz_root / "good.h5")], capsys)[0] == 0
    code, err = run_cli(["evaluate", "--checkpoint", str(fuzz_root / "model.pt"), "--data", str(fuzz_root / "good.h5"),
                         "--history", "3", "--out", str(fuzz_root / "good.csv"), "--no-progress"], capsys)
    assert code == 0, err
    (fuzz_root / "good.csv").unlink()


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("mutation", H5MD_MUTATIONS)
def test_a_malformed_h5md_file_is_refused_by_name(fuzz_root, tmp_path, capsys, mutation, seed):
    path = tmp_path / f"case_{seed}.h5"
    shutil.copy(fuzz_root / "good.h5", path)
    H5MD_MUTATIONS[mutation](path, np.random.default_rng(seed))
    code, err = run_cli(["inspect", str(path)], capsys)
    if mutation in EVALUATE_ONLY:
        assert code == 0, err
    else:
        assert code == 1 and err.startswith("graphdem inspect: error: ") and str(path) in err, err
        assert err.count("\n") == 1, err
    out = tmp_path / "metrics.csv"
    code, err = run_cli(["evaluate", "--checkpoint", str(fuzz_root / "model.pt"), "--data", str(path), "--history",
                         "3", "--out", str(out), "--no-progress"], capsys)
    assert code == 1 and err.splitlines()[-1].startswith("graphdem evaluate: error: ") and str(path) in err, err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def good_pickle(rng, frames=4, n=5) -> dict:
    return {"particle_type": np.array([0.0, 0, 1, 1, 2])[:n], "particle_r": np.full(n, 1.5),
            "particle_m": np.array([0.0, 0, 5, 5, 5])[:n], "position": rng.uniform(0, 80, (frames, n, 2))}


class RunsACommand:
    def __reduce__(self):
        import os
        return (os.system, ("touch PWNED_BY_FUZZ",))


METADATA = {"bounds": [[0, 100], [0, 80]], "dim": 2, "dt": 0.001, "default_connectivity_radius": 9.75}
# (name, what goes into train/0.pkl: an object or raw bytes, the metadata.json text)
PICKLE_CASES = [
    ("not_a_dict", lambda rng: [1, 2, 3], None),
    ("string_position", lambda rng: {**good_pickle(rng), "position": np.full((4, 5, 2), "a")}, None),
    ("object_position", lambda rng: {**good_pickle(rng), "position": np.array([[None] * 2] * 5, dtype=object)}, None),
    ("bytes_types", lambda rng: {**good_pickle(rng), "particle_type": np.array([b"a"] * 5)}, None),
    ("missing_position", lambda rng: {k: v for k, v in good_pickle(rng).items() if k != "position"}, None),
    ("one_frame", lambda rng: good_pickle(rng, frames=1), None),
    ("zero_particles", lambda rng: good_pickle(rng, n=0), None),
    ("negative_type", lambda rng: {**good_pickle(rng), "particle_type": -np.ones(5)}, None),
    ("nan_position", lambda rng: {**good_pickle(rng), "position": np.full((4, 5, 2), np.nan)}, None),
    ("wrong_dim", lambda rng: {**good_pickle(rng), "position": rng.uniform(0, 1, (4, 5, 3))}, None),
    ("truncated", lambda rng: pickle.dumps(good_pickle(rng))[: int(rng.integers(1, 60))], None),
    ("random_bytes", lambda rng: rng.bytes(int(rng.integers(1, 200))), None),
    ("runs_a_command", lambda rng: {"position": RunsACommand()}, None),
    ("bad_json", lambda rng: good_pickle(rng), lambda rng: "{" + rng.bytes(8).hex()),
    ("metadata_without_dim", lambda rng: good_pickle(rng), lambda rng: json.dumps({**METADATA, "dim": None})),
    ("metadata_dim_4", lambda rng: good_pickle(rng), lambda rng: json.dumps({**METADATA, "dim": 4})),
    ("metadata_bad_bounds", lambda rng: good_pickle(rng), lambda rng: json.dumps({**METADATA, "bounds": [[5, 1]]})),
    ("metadata_negative_dt", lambda rng: good_pickle(rng), lambda rng: json.dumps({**METADATA, "dt": -rng.random()})),
    ("metadata_a_list", lambda rng: good_pickle(rng), lambda rng: "[1, 2]"),
]


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("case", PICKLE_CASES, ids=lambda c: c[0])
def test_a_malformed_solidgn_folder_is_refused_by_name_and_leaves_nothing(tmp_path, capsys, monkeypatch, case, seed):
    name, content, metadata = case
    rng = np.random.default_rng(seed)
    monkeypatch.chdir(tmp_path)
    src = tmp_path / "src"
    (src / "train").mkdir(parents=True)
    (src / "metadata.json").write_text(metadata(rng) if metadata else json.dumps(METADATA))
    for i in range(2):                                            # a good pickle first: no half import may stay
        (src / "train" / f"{i}.pkl").write_bytes(pickle.dumps(good_pickle(rng)))
    body = content(rng)
    (src / "train" / "7.pkl").write_bytes(body if isinstance(body, bytes) else pickle.dumps(body))
    code, err = run_cli(["import-solidgn", str(src), str(tmp_path / "dest"), "--no-progress"], capsys)
    assert code == 1 and err.startswith("graphdem import-solidgn: error: "), err
    assert str(src / ("metadata.json" if metadata else "train/7.pkl")) in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["src"] and not Path("PWNED_BY_FUZZ").exists()


def test_the_fuzz_covers_at_least_200_malformed_files():
    assert len(H5MD_MUTATIONS) * len(SEEDS) + len(PICKLE_CASES) * 5 >= 200
