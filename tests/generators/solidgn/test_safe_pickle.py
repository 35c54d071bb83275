"""The numpy-only unpickler: arrays in dicts and lists load back equal; any other global, and a corrupt file, are
refused naming the file (the command-running pickle: tests/generators/solidgn/test_import.py)."""

import pickle

import numpy as np
import pytest

from generators.solidgn import safe_pickle


def test_arrays_dicts_lists_and_scalars_load_back_equal(tmp_path):
    data = {"position": np.arange(12, dtype=np.float64).reshape(2, 3, 2), "particle_type": np.array([0, 1, 2]),
            "names": ["a", "b"], "dt": 0.0025}
    path = tmp_path / "0.pkl"
    path.write_bytes(pickle.dumps(data))
    back = safe_pickle.load(path)
    np.testing.assert_array_equal(back["position"], data["position"])
    assert back["position"].dtype == np.float64 and back["particle_type"].dtype == data["particle_type"].dtype
    assert back["names"] == ["a", "b"] and back["dt"] == 0.0025


def test_any_other_global_and_a_corrupt_file_are_refused_naming_the_file(tmp_path):
    path = tmp_path / "1.pkl"
    path.write_bytes(pickle.dumps({"when": __import__("datetime").date(2025, 1, 1)}))
    with pytest.raises(safe_pickle.UnsafePickle, match=r"1.pkl: refused to load datetime.date"):
        safe_pickle.load(path)
    path.write_bytes(pickle.dumps(np.zeros(3))[:-5])
    with pytest.raises(pickle.UnpicklingError, match=r"1.pkl: not a readable pickle"):
        safe_pickle.load(path)
