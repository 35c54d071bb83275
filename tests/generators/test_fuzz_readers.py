"""Seeded fuzz of every reader: malformed H5MD files through `graphdem inspect` and `graphdem evaluate`, malformed
Solid-GN pickles and metadata through `graphdem import-solidgn` (checkpoints: tests/surrogate/test_fuzz_checkpoint.py).

Each must end in a one-line error that names the file (exit status 1) or, for the few valid files among them, in a
valid read: no traceback, nothing left behind (no output, no half import). The H5MD files run in a child process
(tests/fuzz_worker.py) whose memory may grow by at most 512 MiB over its warm baseline and which must answer within
a time limit, so a reader that follows a link to a FIFO fails the test instead of hanging it; the pickles run in
this process, their allocations traced (ALLOCATION_BOUND).
"""

from __future__ import annotations

import functools
import json
import os
import pickle
import shutil
import tracemalloc
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from generators import h5md
from graphdem import cli
from surrogate import checkpoint, dataset
from surrogate.simulator import LearnedSimulator
from tests import fuzz_worker

ALLOCATION_BOUND = 64 * 2**20
SEEDS = range(6)
#: what the allocators say when the worker's memory cap stops them: such a refusal is not the reader's own
OUT_OF_MEMORY = ("can't allocate", "Unable to allocate", "MemoryError", "memory allocation failed", "Traceback")
WORKER_TIMEOUT = 300        # s for every file of a run; one FIFO opened for reading blocks until it passes


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
DATASETS = (POS, "particles/all/position/time", "particles/all/position/step", SPECIES, "particles/all/radius",
            "particles/all/mass", "particles/all/kinematic", EDGES, "particles/all/box/lower")
GROUPS = ("particles", "particles/all", "particles/all/position", "particles/all/box", "h5md", "parameters",
          "observables")


def _fifo(f: h5py.File) -> str:
    """The FIFO beside the file being edited (made by the fixture with os.mkfifo): opened for reading, it blocks."""
    return str(Path(f.filename).parent / "fifo")


def _pick(rng, names):
    return names[int(rng.integers(0, len(names)))]


def _to_external_link(f: h5py.File, key: str, target: str, inside: str = "/x") -> None:
    if key in f:
        del f[key]
    f[key] = h5py.ExternalLink(target, inside)


def _to_soft(f: h5py.File, key: str, target: str) -> None:
    del f[key]
    f[key] = h5py.SoftLink(target)


def _to_virtual(f: h5py.File, key: str, source: str) -> None:
    shape, dtype = f[key].shape, f[key].dtype
    layout = h5py.VirtualLayout(shape=shape, dtype=dtype)
    layout[...] = h5py.VirtualSource(source, key, shape=shape)
    del f[key]
    f.create_virtual_dataset(key, layout, fillvalue=0)


def _valid_copy(f: h5py.File) -> str:
    """A valid file beside the one being edited: a source that exists and reads fine."""
    path = Path(f.filename).parent / "valid_source.h5"
    if not path.exists():
        h5md.write(path, valid_trajectory(np.random.default_rng(1)))
    return str(path)


@functools.cache
def _inflating(nbytes: int) -> bytes:
    """A deflate stream of ``nbytes`` zero bytes (about a thousandth of that)."""
    return zlib.compress(bytes(nbytes), 9)


def _deflate_bomb(f: h5py.File, rng) -> None:
    """Every chunk of the positions (96 bytes each) replaced by a stream that inflates to 16 to 64 MiB."""
    value = f[POS]
    for frame in range(value.shape[0]):
        value.id.write_direct_chunk((frame, 0, 0), _inflating(2 ** int(rng.integers(24, 27))))


def _soft_link_inside(f: h5py.File, rng) -> None:
    key = _pick(rng, DATASETS)
    f.move(key, f"/moved_{key.replace('/', '_')}")
    f[key] = h5py.SoftLink(f"/moved_{key.replace('/', '_')}")


def _declared_together(f: h5py.File, rng) -> None:
    """Radius and mass each declare 150 to 250 MiB (under the budget alone, over it together); nothing stored."""
    for key in ("particles/all/radius", "particles/all/mass"):
        n = int(rng.integers(150, 250)) * 2**18
        _replace(f, key, None, shape=(n,), dtype="f4", chunks=(2**16,), compression="gzip")


# name -> mutation; EVALUATE_ONLY: valid H5MD that only the model refuses (evaluate, not inspect); VALID: valid files
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
    # links, virtual datasets and external storage: refused before HDF5 opens anything outside the file
    "dataset_external_link_to_a_fifo": edit(lambda f, rng: _to_external_link(f, _pick(rng, DATASETS), _fifo(f))),
    "group_external_link_to_a_fifo": edit(lambda f, rng: _to_external_link(f, _pick(rng, GROUPS), _fifo(f))),
    "external_link_to_a_missing_file": edit(lambda f, rng: _to_external_link(
        f, _pick(rng, DATASETS), str(Path(f.filename).parent / "absent.h5"), "/" + _pick(rng, DATASETS))),
    "external_link_to_a_valid_file": edit(lambda f, rng: _to_external_link(
        f, (key := _pick(rng, DATASETS)), _valid_copy(f), "/" + key)),
    "dangling_soft_link": edit(lambda f, rng: _to_soft(f, _pick(rng, DATASETS), f"/nothing_{rng.integers(9)}")),
    "soft_link_loop": edit(lambda f, rng: _to_soft(f, (key := _pick(rng, DATASETS)), "/" + key)),
    "soft_link_through_an_external_link": edit(lambda f, rng: (
        _to_external_link(f, "elsewhere", _fifo(f), "/"),
        _to_soft(f, (key := _pick(rng, DATASETS)), f"/elsewhere/{key}"))),
    "virtual_dataset_of_a_fifo": edit(lambda f, rng: _to_virtual(f, _pick(rng, DATASETS), _fifo(f))),
    "virtual_dataset_of_a_missing_file": edit(lambda f, rng: _to_virtual(f, _pick(rng, DATASETS),
                                                                         str(Path(f.filename).parent / "absent.h5"))),
    "virtual_dataset_of_a_valid_file": edit(lambda f, rng: _to_virtual(f, _pick(rng, DATASETS), _valid_copy(f))),
    "external_storage_in_a_fifo": edit(lambda f, rng: _replace(
        f, (key := _pick(rng, DATASETS)), None, shape=f[key].shape, dtype=f[key].dtype,
        external=[(_fifo(f), 0, f[key].nbytes)])),
    # sizes: every dataset's decompressed size and every chunk bounded before reading
    "deflate_bomb_within_the_declared_size": edit(_deflate_bomb),
    "declared_within_the_limit_alone_not_together": edit(_declared_together),
    "chunk_larger_than_its_dataset": edit(lambda f, rng: _replace(
        f, POS, None, shape=(6, 12, 2), dtype="f4", maxshape=(None, 12, 2),
        chunks=(2 ** int(rng.integers(22, 26)), 12, 2), compression="gzip")),
    "contiguous_unallocated_1_GiB": edit(lambda f, rng: _replace(f, "particles/all/radius", None,
                                                                 shape=(2**28,), dtype="f4")),
    "lzf_filter": edit(lambda f, rng: _replace(f, POS, f[POS][()], compression="lzf")),
    "variable_length_attribute_array": edit(lambda f, rng: f["particles/all/box"].attrs.__setitem__(
        "boundary", np.array(["none"] * int(rng.integers(1500, 3500)), dtype=h5py.string_dtype()))),
    # non-finite geometry
    "infinite_box_edge": edit(lambda f, rng: f[EDGES].__setitem__(Ellipsis, [np.inf, rng.uniform(1, 10)])),
    "nan_box_edge": edit(lambda f, rng: f[EDGES].__setitem__(Ellipsis, [rng.uniform(1, 10), np.nan])),
    "zero_box_edge": edit(lambda f, rng: f[EDGES].__setitem__(Ellipsis, [0.0, rng.uniform(1, 10)])),
    "nan_box_lower": edit(lambda f, rng: f["particles/all/box/lower"].__setitem__(int(rng.integers(0, 2)), np.nan)),
    "infinite_radius": edit(lambda f, rng: f["particles/all/radius"].__setitem__(int(rng.integers(0, 12)), np.inf)),
    # valid H5MD the model refuses
    "species_beyond_the_model": edit(lambda f, rng: _replace(f, SPECIES, np.full(12, 1000 + int(rng.integers(0, 5))))),
    "another_scene": edit(lambda f, rng: f["parameters"].attrs.__setitem__("scene", "meteorite")),
    # valid files
    "soft_link_inside_the_file": edit(_soft_link_inside),
    "deeply_nested_json_parameter": edit(lambda f, rng: f["parameters"].attrs.__setitem__(
        "notes", "[" * int(rng.integers(10_000, 100_000)))),
}
EVALUATE_ONLY = {"species_beyond_the_model", "another_scene"}
VALID = {"soft_link_inside_the_file", "deeply_nested_json_parameter"}


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


@pytest.fixture(scope="module")
def h5md_cases(fuzz_root) -> dict[str, Path]:
    """Every mutation of every seed, written once: case name -> file (beside a FIFO)."""
    folder = fuzz_root / "cases"
    folder.mkdir()
    os.mkfifo(folder / "fifo")
    cases = {}
    for mutation, mutate in H5MD_MUTATIONS.items():
        for seed in SEEDS:
            path = folder / f"{mutation}-{seed}.h5"
            shutil.copy(fuzz_root / "good.h5", path)
            mutate(path, np.random.default_rng(seed))
            cases[f"{mutation}-{seed}"] = path
    return cases


def _evaluate_argv(fuzz_root: Path, data: Path) -> list[str]:
    return ["evaluate", "--checkpoint", str(fuzz_root / "model.pt"), "--data", str(data), "--history", "3",
            "--out", str(data.parent / "metrics.csv"), "--no-progress"]


@pytest.fixture(scope="module")
def inspected(fuzz_root, h5md_cases):
    """`graphdem inspect` on every case, in the bounded worker: outcomes by case and the peak memory growth."""
    cases = [{"name": name, "reader": "cli", "argv": ["inspect", str(path)]} for name, path in h5md_cases.items()]
    warmup = {"name": "good", "reader": "cli", "argv": ["inspect", str(fuzz_root / "good.h5")]}
    return fuzz_worker.run(cases, warmup, fuzz_root, WORKER_TIMEOUT)


@pytest.fixture(scope="module")
def evaluated(fuzz_root, h5md_cases):
    """`graphdem evaluate` on the first seed's file of every mutation, each alone in a folder, in the bounded
    worker."""
    cases = []
    for mutation in H5MD_MUTATIONS:
        folder = fuzz_root / "evaluate" / mutation
        folder.mkdir(parents=True)
        data = Path(shutil.copy(h5md_cases[f"{mutation}-0"], folder / "case.h5"))
        cases.append({"name": mutation, "reader": "cli", "argv": _evaluate_argv(fuzz_root, data)})
    (fuzz_root / "evaluate" / "good").mkdir()
    good = Path(shutil.copy(fuzz_root / "good.h5", fuzz_root / "evaluate" / "good" / "case.h5"))
    warmup = {"name": "good", "reader": "cli", "argv": _evaluate_argv(fuzz_root, good)}
    return fuzz_worker.run(cases, warmup, fuzz_root / "evaluate", WORKER_TIMEOUT)


def test_the_valid_file_and_checkpoint_pass(fuzz_root, tmp_path, capsys):
    assert run_cli(["inspect", str(fuzz_root / "good.h5")], capsys)[0] == 0
    data = Path(shutil.copy(fuzz_root / "good.h5", tmp_path / "good.h5"))
    code, err = run_cli(_evaluate_argv(fuzz_root, data), capsys)
    assert code == 0, err
    assert (tmp_path / "metrics.csv").is_file()


@pytest.mark.parametrize("mutation", H5MD_MUTATIONS)
def test_a_malformed_h5md_file_is_refused_by_name(inspected, h5md_cases, mutation):
    outcomes, _ = inspected
    for seed in SEEDS:
        path = h5md_cases[f"{mutation}-{seed}"]
        status, err = outcomes[f"{mutation}-{seed}"]
        if mutation in EVALUATE_ONLY | VALID:
            assert status == "ok", (seed, err)
        else:
            assert status == "refused" and err.startswith("graphdem inspect: error: ") and str(path) in err, (seed, err)
            assert err.count("\n") == 1, (seed, err)
            assert not any(word in err for word in OUT_OF_MEMORY), (seed, err)


@pytest.mark.parametrize("mutation", H5MD_MUTATIONS)
def test_evaluate_refuses_a_malformed_file_by_name_and_leaves_nothing(evaluated, fuzz_root, mutation):
    outcomes, _ = evaluated
    status, err = outcomes[mutation]
    folder = fuzz_root / "evaluate" / mutation
    if mutation in VALID:
        assert status == "ok" and (folder / "metrics.csv").is_file(), err
        return
    assert status == "refused" and err.splitlines()[-1].startswith("graphdem evaluate: error: "), err
    assert str(folder / "case.h5") in err and not any(word in err for word in OUT_OF_MEMORY), err
    assert sorted(p.name for p in folder.iterdir()) == ["case.h5"]


def test_reading_every_fuzzed_file_stays_within_the_memory_bound(inspected, evaluated):
    for outcomes, peak in (inspected, evaluated):
        assert peak < fuzz_worker.ALLOWED_GROWTH, f"peak resident growth {peak / 2**20:.0f} MiB"
        assert not [name for name, (status, _) in outcomes.items() if status == "escaped"]


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


def test_the_fuzz_covers_at_least_300_files_with_links_virtual_datasets_and_bombs():
    assert len(H5MD_MUTATIONS) * len(SEEDS) + len(PICKLE_CASES) * 5 >= 300
    names = " ".join(H5MD_MUTATIONS)
    assert all(word in names for word in ("external_link", "soft_link", "fifo", "virtual", "bomb", "box_edge"))
