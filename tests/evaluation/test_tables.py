"""Provenance columns survive a CSV round trip whatever their characters."""

import pandas as pd
import pytest

from evaluation.evaluate import combine
from evaluation.tables import read_csv

# digests that a CSV parser would otherwise take for numbers: a float overflowing to inf, a float, an integer
# with leading zeros
NUMBER_LIKE = ["15792618e549", "123456789e10", "001234567890"]


def _table(sha: str, mse: float) -> pd.DataFrame:
    return pd.DataFrame({"scene": ["slide"], "metric": ["rollout MSE"], "sim": ["all"], "mse": [mse],
                         "checkpoint_sha": [sha], "config_sha": [sha], "code_version": ["0.1.0"]})


@pytest.mark.parametrize("sha", NUMBER_LIKE)
def test_a_number_like_digest_reads_back_as_written(tmp_path, sha):
    _table(sha, 2.5).to_csv(tmp_path / "m.csv", index=False)
    assert pd.read_csv(tmp_path / "m.csv")["checkpoint_sha"].iloc[0] != sha      # the trap this module avoids
    table = read_csv(tmp_path / "m.csv")
    assert table["checkpoint_sha"].iloc[0] == sha and table["config_sha"].iloc[0] == sha
    assert table["mse"].iloc[0] == 2.5 and table["code_version"].iloc[0] == "0.1.0"   # numbers stay numbers


def test_combined_protocol_tables_keep_the_digest(tmp_path):
    for k, sha in enumerate(NUMBER_LIKE[:2]):
        _table(sha, float(k)).to_csv(tmp_path / f"{k}.csv", index=False)
    stacked = combine([tmp_path / "0.csv", tmp_path / "1.csv"])
    stacked.to_csv(tmp_path / "both.csv", index=False)
    assert list(read_csv(tmp_path / "both.csv")["checkpoint_sha"]) == NUMBER_LIKE[:2]


def test_dtypes_given_by_the_caller_are_kept(tmp_path):
    pd.DataFrame({"acc_frames": ["5"], "checkpoint_sha": ["000000000001"]}).to_csv(tmp_path / "t.csv", index=False)
    table = read_csv(tmp_path / "t.csv", dtype={"acc_frames": str})
    assert table["acc_frames"].iloc[0] == "5" and table["checkpoint_sha"].iloc[0] == "000000000001"
