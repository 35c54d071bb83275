"""Seeded fuzz of the checkpoint reader (surrogate.checkpoint.simulator_from, what evaluate, rollout and the
benchmarks load a model with): malformed archives, compressed and oversized records, tensors that repeat a few
stored bytes over a huge shape, model sizes out of the config schema's ranges or out of step with the weights.

Each file must end in a one-line CheckpointError that names it, or in a valid load; they run in a child process
(tests/fuzz_worker.py) whose memory may grow by at most 512 MiB over its warm baseline and which must answer within a
time limit. No case may run code (the pickles that try leave a file behind if they do).
"""

from __future__ import annotations

import collections
import functools
import io
import json
import os
import pickle
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from generators import h5md
from surrogate import checkpoint, dataset
from surrogate.simulator import LearnedSimulator
from tests import fuzz_worker
from tests.generators.test_fuzz_readers import OUT_OF_MEMORY, valid_trajectory

SEEDS = range(6)
WORKER_TIMEOUT = 300
MODEL = {"history": 3, "embed": 4, "mlp_layers": 2, "properties": [], "latent": 8, "hidden": 8, "message_passing": 1}
SIZE_KEYS = ("history", "embed", "mlp_layers", "latent", "hidden", "message_passing", "bundle")


class RunsACommand:
    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


class _Record:
    """A storage the crafted pickle names by its record key and declares ``numel`` floats long."""

    def __init__(self, key: str, numel: int):
        self.key, self.numel = key, numel


class _Tensor:
    """A float tensor over a _Record, with any shape and strides (torch's own rebuild function)."""

    def __init__(self, record: _Record, shape: tuple, stride: tuple):
        self.record, self.shape, self.stride = record, shape, stride

    def __reduce__(self):
        return (torch._utils._rebuild_tensor_v2,
                (self.record, 0, self.shape, self.stride, False, collections.OrderedDict()))


class _Pickler(pickle.Pickler):
    def persistent_id(self, obj):
        return ("storage", torch.FloatStorage, obj.key, "cpu", obj.numel) if isinstance(obj, _Record) else None


def write_archive(target, payload, records: dict[str, bytes], deflated: dict[str, int] | None = None) -> None:
    """torch.save's layout written by hand to ``target`` (a path or a file object): ``payload`` pickled with _Record
    storages, ``records`` stored as they are and ``deflated`` (key -> bytes of zeros) as deflated records."""
    buf = io.BytesIO()
    _Pickler(buf, protocol=2).dump(payload)
    with zipfile.ZipFile(target, "w") as archive:
        archive.writestr("archive/data.pkl", buf.getvalue())
        archive.writestr("archive/byteorder", "little")
        archive.writestr("archive/version", "3\n")
        for key, data in records.items():
            archive.writestr(f"archive/data/{key}", data)
        for key, nbytes in (deflated or {}).items():
            info = zipfile.ZipInfo(f"archive/data/{key}")
            info.compress_type = zipfile.ZIP_DEFLATED
            with archive.open(info, "w", force_zip64=True) as out:
                block = bytes(2**22)
                for _ in range(nbytes // len(block)):
                    out.write(block)


@functools.cache
def _deflated_archive(json_text: str, numel: int) -> bytes:
    """An archive whose only weight declares ``numel`` floats, stored as one deflated record (a few hundred times
    smaller than it inflates): written once, copied for each seed."""
    buf = io.BytesIO()
    write_archive(buf, {"model": {"w": _Tensor(_Record("0", numel), (numel,), (1,))}, "json": json_text}, {},
                  {"0": numel * 4})
    return buf.getvalue()


def _good(base: dict, **json_changes) -> dict:
    meta = {**base["json"], **json_changes}
    return {"model": dict(base["model"]), "json": json.dumps(meta)}


def _save(path: Path, payload: dict) -> None:
    torch.save(payload, path)


def _other_sizes(path, rng, base):
    """A valid checkpoint of a model of other (small) sizes."""
    model = {**MODEL, "latent": int(rng.integers(1, 17)), "hidden": int(rng.integers(1, 17)),
             "message_passing": int(rng.integers(1, 4)), "mlp_layers": int(rng.integers(2, 4))}
    stats = base["json"]["stats"]
    _save(path, {"model": LearnedSimulator(stats, model).state_dict(),
                 "json": json.dumps({"stats": stats, "model": model, "train": {}})})


def _out_of_range(path, rng, base):
    key = SIZE_KEYS[int(rng.integers(0, len(SIZE_KEYS)))]
    value = [0, -int(rng.integers(1, 100)), 60000, 10**int(rng.integers(5, 12))][int(rng.integers(0, 4))]
    _save(path, _good(base, model={**MODEL, key: value}))


def _not_an_integer(path, rng, base):
    key = SIZE_KEYS[int(rng.integers(0, len(SIZE_KEYS)))]
    value = [8.0, 8.5, True, "8", None, [8]][int(rng.integers(0, 6))]
    _save(path, _good(base, model={**MODEL, key: value}))


def _largest_sizes(path, rng, base):
    """Sizes within the schema's ranges whose model would take gigabytes: refused as not the weights' shapes."""
    model = {**MODEL, "latent": int(rng.integers(1024, 4097)), "hidden": int(rng.integers(1024, 4097)),
             "message_passing": int(rng.integers(2, 10)), "mlp_layers": int(rng.integers(2, 5))}
    _save(path, _good(base, model=model))


def _many_types(path, rng, base):
    stats = {**base["json"]["stats"], "n_types": int(10 ** rng.uniform(5, 7))}
    _save(path, _good(base, stats=stats, model={**MODEL, "embed": 1024}))


def _weight_reshaped(path, rng, base):
    payload = _good(base)
    name = sorted(payload["model"])[int(rng.integers(0, len(payload["model"])))]
    payload["model"][name] = torch.zeros(*(int(n) + 100 for n in rng.integers(1, 9, int(rng.integers(1, 3)))))
    _save(path, payload)


def _expanded(key: str):
    def mutate(path, rng, base):
        payload = _good(base)
        view = torch.zeros(1).expand(2 ** int(rng.integers(26, 31)))
        if key == "model":
            payload["model"]["repeated"] = view
        else:
            payload[key] = {"state": {0: {"exp_avg": view}}}
        _save(path, payload)
    return mutate


def _crafted(kind: str):
    """A hand-written archive whose only weight declares 2^24 floats: deflated, or over a short stored record."""
    def mutate(path, rng, base):
        numel = 2**24
        if kind == "deflated":
            path.write_bytes(_deflated_archive(base["json_text"], numel))
        else:
            payload = {"model": {"w": _Tensor(_Record("0", numel), (numel,), (1,))}, "json": base["json_text"]}
            write_archive(path, payload, {"0": bytes(int(rng.integers(0, 64)) * 4)})
    return mutate


def _recompressed(path, rng, base):
    with zipfile.ZipFile(base["path"]) as source, zipfile.ZipFile(path, "w") as out:
        for info in source.infolist():
            out.writestr(info.filename, source.read(info), compress_type=zipfile.ZIP_DEFLATED)


def _bytes(fn):
    def mutate(path, rng, base):
        path.write_bytes(fn(base["path"].read_bytes(), rng))
    return mutate


def _flip(data: bytes, rng) -> bytes:
    data = bytearray(data)
    for i in rng.integers(0, len(data), 20):
        data[i] ^= 0xFF
    return bytes(data)


def _exploit_in_zip(path, rng, base):
    evil = pickle.dumps({"model": RunsACommand(path.parent / "PWNED"), "json": "{}"}, protocol=2)
    with zipfile.ZipFile(base["path"]) as source, zipfile.ZipFile(path, "w") as out:
        for info in source.infolist():
            out.writestr(info.filename, evil if info.filename.endswith("data.pkl") else source.read(info))


def _json(text_of):
    def mutate(path, rng, base):
        _save(path, {"model": dict(base["model"]), "json": text_of(rng, base)})
    return mutate


# name -> mutation(path, rng, base); VALID: loads
CHECKPOINT_MUTATIONS = {
    "other_sizes": _other_sizes,
    "nan_weights": lambda path, rng, base: _save(path, {**_good(base), "model": {
        k: torch.full_like(v, float("nan")) if v.is_floating_point() else v for k, v in base["model"].items()}}),
    "truncated": _bytes(lambda data, rng: data[: int(rng.integers(0, len(data)))]),
    "flipped_bytes": _bytes(_flip),
    "random_bytes": _bytes(lambda data, rng: rng.bytes(int(rng.integers(1, 5000)))),
    "legacy_format": lambda path, rng, base: torch.save(_good(base), path, _use_new_zipfile_serialization=False),
    "raw_pickle_runs_a_command": lambda path, rng, base: path.write_bytes(
        pickle.dumps({"model": RunsACommand(path.parent / "PWNED"), "json": "{}"})),
    "zip_pickle_runs_a_command": _exploit_in_zip,
    "records_deflated": _recompressed,
    "deflated_tensor_of_64_MiB": _crafted("deflated"),
    "tensor_longer_than_its_record": _crafted("short"),
    "expanded_view_of_gigabytes": _expanded("model"),
    "expanded_view_in_the_optimiser": _expanded("optimiser"),
    "model_size_out_of_range": _out_of_range,
    "model_size_not_an_integer": _not_an_integer,
    "latent_60000": lambda path, rng, base: _save(path, _good(base, model={**MODEL, "latent": 60000})),
    "largest_sizes_in_range": _largest_sizes,
    "millions_of_types": _many_types,
    "dim_7": lambda path, rng, base: _save(path, _good(base, stats={**base["json"]["stats"], "dim": 7})),
    "weight_of_another_shape": _weight_reshaped,
    "weight_missing": lambda path, rng, base: _save(path, {**_good(base), "model": dict(
        list(base["model"].items())[: int(rng.integers(0, len(base["model"])))])}),
    "thousands_of_extra_tensors": lambda path, rng, base: _save(path, {**_good(base), "model": {
        **base["model"], **{f"extra.{i}": torch.zeros(1) for i in range(int(rng.integers(1000, 5000)))}}}),
    "nine_MB_extra_weight": lambda path, rng, base: _save(path, {**_good(base), "model": {
        **base["model"], "extra": torch.zeros(int(rng.integers(2_000_000, 2_400_000)))}}),
    "text_among_the_weights": lambda path, rng, base: _save(path, {**_good(base), "model": {
        **base["model"], "note": "x" * int(rng.integers(1, 100))}}),
    "json_not_json": _json(lambda rng, base: "{" + rng.bytes(8).hex()),
    "json_deeply_nested": _json(lambda rng, base: "[" * int(rng.integers(10_000, 1_000_000))),
    "json_a_list": _json(lambda rng, base: json.dumps([base["json"]] * int(rng.integers(1, 5)))),
    "json_without_stats": _json(lambda rng, base: json.dumps({"model": MODEL})),
    "json_model_a_list": _json(lambda rng, base: json.dumps({**base["json"], "model": [1, 2]})),
    "no_json_entry": lambda path, rng, base: _save(path, {"model": dict(base["model"])}),
}
VALID = {"other_sizes", "nan_weights"}


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("checkpoints")
    good = h5md.write(root / "good.h5", valid_trajectory(np.random.default_rng(0)))
    stats = dataset.statistics([good], 1.0)
    weights = LearnedSimulator(stats, MODEL).state_dict()
    meta = {"stats": stats, "model": MODEL, "train": {}}
    checkpoint.save(root / "model.pt", {"model": weights, "json": meta})
    return {"root": root, "path": root / "model.pt", "model": weights, "json": meta, "json_text": json.dumps(meta)}


@pytest.fixture(scope="module")
def loaded(base):
    """Every mutation of every seed loaded in the bounded worker: outcomes by case and the peak memory growth."""
    cases = []
    for mutation, mutate in CHECKPOINT_MUTATIONS.items():
        for seed in SEEDS:
            folder = base["root"] / f"{mutation}-{seed}"
            folder.mkdir()
            mutate(folder / "model.pt", np.random.default_rng(seed), base)
            cases.append({"name": f"{mutation}-{seed}", "reader": "checkpoint", "path": str(folder / "model.pt")})
    warmup = {"name": "good", "reader": "checkpoint", "path": str(base["path"])}
    return fuzz_worker.run(cases, warmup, base["root"], WORKER_TIMEOUT)


@pytest.mark.parametrize("mutation", CHECKPOINT_MUTATIONS)
def test_a_malformed_checkpoint_is_refused_by_name_or_loads(loaded, base, mutation):
    outcomes, _ = loaded
    for seed in SEEDS:
        folder = base["root"] / f"{mutation}-{seed}"
        status, message = outcomes[f"{mutation}-{seed}"]
        if mutation in VALID:
            assert status == "ok", (seed, message)
        else:
            assert status == "refused" and message.startswith(f"{folder / 'model.pt'}: "), (seed, message)
            assert "\n" not in message and not any(word in message for word in OUT_OF_MEMORY), (seed, message)
        assert sorted(p.name for p in folder.iterdir()) == ["model.pt"]          # no command ran


@pytest.mark.parametrize("mutation, words", [
    ("records_deflated", "is compressed"), ("deflated_tensor_of_64_MiB", "is compressed"),
    ("expanded_view_of_gigabytes", "repeats its data"), ("expanded_view_in_the_optimiser", "repeats its data"),
    ("latent_60000", "model.latent"), ("model_size_out_of_range", "outside the config schema's range"),
    ("model_size_not_an_integer", "outside the config schema's range"), ("legacy_format", "zip archive"),
    ("largest_sizes_in_range", "weights do not fit"), ("millions_of_types", "embedding"),
])
def test_each_oversized_checkpoint_is_refused_before_it_allocates(loaded, mutation, words):
    outcomes, _ = loaded
    messages = [outcomes[f"{mutation}-{seed}"][1] for seed in SEEDS]
    assert all(words in message for message in messages), messages


def test_loading_every_fuzzed_checkpoint_stays_within_the_memory_bound(loaded):
    outcomes, peak = loaded
    assert peak < fuzz_worker.ALLOWED_GROWTH, f"peak resident growth {peak / 2**20:.0f} MiB"
    assert len(outcomes) == len(CHECKPOINT_MUTATIONS) * len(SEEDS) >= 150
