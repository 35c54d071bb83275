"""Derived training defaults (surrogate/derived.py): each rule by hand, on the figures it was measured on, and in
a real training run whose checkpoint records the number it used."""

import json

import pytest
import torch

from generators import config
from surrogate import checkpoint, derived, train

pytestmark = pytest.mark.engine


def test_noise_is_the_ratio_times_the_rms_acceleration_std():
    # the public benchmarks: acceleration std 1.4 / 1.8 m per frame^2, where 0.1 m of noise was measured best
    benchmark = {"acceleration_std": [1.4, 1.8]}
    assert derived.noise_std(benchmark, 0.06) == pytest.approx(0.06 * (0.5 * (1.4**2 + 1.8**2)) ** 0.5)
    assert derived.noise_std(benchmark, 0.06) == pytest.approx(0.1, rel=0.05)
    assert derived.noise_std({"acceleration_std": [2e-3, 2e-3, 2e-3]}, 0.5) == pytest.approx(1e-3)
    with pytest.raises(ValueError, match=r"train.noise_ratio is 0.0; allowed: a number > 0"):
        derived.noise_std(benchmark, 0.0)


def test_ema_decay_spans_the_epochs_asked_for():
    assert derived.ema_decay(1575, 0.635) == pytest.approx(0.999, abs=1e-6)   # the benchmarks' measured 0.999
    assert derived.ema_decay(150, 0.6) == pytest.approx(1 - 1 / 90)
    assert derived.ema_decay(1, 0.6) == 0.0                                  # never longer than one step's memory
    with pytest.raises(ValueError, match="train.ema_epochs"):
        derived.ema_decay(100, -1.0)


def test_the_connectivity_radius_is_the_diameters_times_the_mean_diameter():
    # the slide's default: R = 5 m at radii 0.8-1.2 m, 2.5 mean diameters of 2 m
    assert derived.connectivity_radius(1.0, 2.5) == pytest.approx(5.0)
    assert derived.connectivity_radius(0.004, 1.5) == pytest.approx(0.012)     # the shear's 12 mm at d = 8 mm
    with pytest.raises(ValueError, match=r"connectivity_diameters is 0.0; allowed: a number > 0"):
        derived.connectivity_radius(1.0, 0.0)
    with pytest.raises(ValueError, match="the train split needs moving particles"):
        derived.connectivity_radius(float("nan"), 2.5)


def test_resolve_replaces_only_auto_values_and_records_the_rule():
    stats = {"acceleration_std": [0.3, 0.4]}
    cfg = {"noise_std": "auto", "noise_ratio": 0.1, "ema_decay": "auto", "ema_epochs": 0.5, "lr": 1e-3}
    out = derived.resolve(cfg, stats, batches_per_epoch=40)
    assert out["noise_std"] == pytest.approx(0.1 * (0.125) ** 0.5) and out["ema_decay"] == pytest.approx(0.95)
    assert out["derived"]["ema_decay"]["batches_per_epoch"] == 40 and out["lr"] == 1e-3
    assert cfg["noise_std"] == "auto"                                        # the config itself is left alone
    fixed = {"noise_std": 3e-4, "ema_decay": None}
    assert derived.resolve(fixed, stats, 40) == fixed


def test_auto_needs_its_rules_input_in_the_config():
    # the benchmarks keep their measured numbers and have no ratio: auto alone is refused by name
    with pytest.raises(config.ConfigError, match=r"'slide_samer.train' is missing 'noise_ratio'"):
        config.load(overrides={"slide_samer": {"train": {"noise_std": "auto"}}})
    with pytest.raises(config.ConfigError, match=r"'slide_small.train' is missing 'ema_epochs'"):
        config.load(overrides={"slide_small": {"train": {"ema_decay": "auto"}}})
    with pytest.raises(config.ConfigError, match=r"'slide.train.noise_std' = 'big' is not allowed; allowed: .*or auto"):
        config.load(overrides={"slide": {"train": {"noise_std": "big"}}})


def test_a_training_run_uses_and_records_the_derived_numbers(tiny_dataset, tmp_path):
    cfg = {**tiny_dataset["train"], "noise_std": "auto", "noise_ratio": 0.06, "ema_decay": "auto", "ema_epochs": 0.5,
           "epochs": 1, "patience": 1}
    train.train(tiny_dataset["stats_path"], tiny_dataset["splits"], tiny_dataset["model"], cfg, tmp_path,
                progress=False)
    stats = json.loads(tiny_dataset["stats_path"].read_text())
    saved = checkpoint.load(tmp_path / "best.pt")["json"]["train"]
    assert saved["noise_std"] == pytest.approx(derived.noise_std(stats, 0.06))
    batches = saved["derived"]["ema_decay"]["batches_per_epoch"]
    assert batches >= 1 and saved["ema_decay"] == pytest.approx(1 - 1 / max(1.0, 0.5 * batches))
    assert torch.isfinite(torch.tensor(saved["noise_std"])) and saved["noise_std"] > 0
