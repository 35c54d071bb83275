import pytest
import yaml

from generators import config, scenes, sweep


def test_default_config_is_valid_and_scales_fill_sizes():
    assert config.load()["slide"]["n_sims"] == 80 and config.load()["slide"]["split"] == [0.525, 0.225, 0.25]
    assert config.load({"scale": "ci"})["slide"]["n_sims"] == 4
    assert config.load({"scale": "paper"})["slide"]["n_sims"] == 1000


def test_user_override_beats_scale_preset():
    cfg = config.load({"scale": "paper", "slide": {"n_sims": 7}})
    assert cfg["slide"]["n_sims"] == 7
    assert cfg["slide"]["radius"] == [0.42, 0.62]   # the rest of the preset still applies


def test_unknown_key_names_key_and_allowed_keys():
    with pytest.raises(config.ConfigError) as err:
        config.load({"slide": {"youngs": 1e9}})
    msg = str(err.value)
    assert "slide.youngs" in msg
    assert "allowed keys under slide" in msg and "young" in msg


@pytest.mark.parametrize("override, old, new", [
    ({"shear": {"stress_readout": {"epochs": 3}}}, "shear.stress_readout", "shear.shear_stress_readout"),
    ({"shear": {"evaluate": {"property_test": None}}}, "shear.evaluate.property_test",
     "shear.evaluate.property_sensitivity"),
    ({"slide": {"evaluate": {"property_test": None}}}, "slide.evaluate.property_test",
     "slide.evaluate.property_sensitivity"),
])
def test_a_renamed_key_is_refused_naming_its_new_name(override, old, new):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert str(err.value) == f"config key '{old}' was renamed '{new}'"


def test_a_renamed_key_in_a_configfile_is_refused_naming_its_new_name(tmp_path):
    full = config.defaults()
    full["shear"]["stress_readout"] = full["shear"].pop("shear_stress_readout")
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(full))
    with pytest.raises(config.ConfigError, match="'shear.stress_readout' was renamed 'shear.shear_stress_readout'"):
        config.load(path=path)


def test_unknown_top_level_key():
    with pytest.raises(config.ConfigError, match="'slidee'.*allowed keys: .*slide"):
        config.load({"slidee": {}})


def test_wrong_type_names_key_and_type():
    with pytest.raises(config.ConfigError, match=r"slide\.frames.*'type': 'integer'"):
        config.load({"slide": {"frames": "many"}})


def test_out_of_range_names_key_and_bounds():
    with pytest.raises(config.ConfigError, match=r"slide\.restitution.*maximum': 1"):
        config.load({"slide": {"restitution": 1.5}})


def test_pushforward_gradient_is_an_optional_boolean_absent_by_default():
    """Absent from every default train section (so no trained model's settings change), accepted as a boolean,
    refused by name otherwise."""
    defaults = config.load()
    trained = {name: section["train"] for name, section in defaults.items()
               if isinstance(section, dict) and isinstance(section.get("train"), dict)}
    assert {"slide", "meteorite", "shear", "slide_samer", "slide_small"} <= set(trained)
    assert not any("pushforward_gradient" in train for train in trained.values())
    assert config.load({"slide_samer": {"train": {"pushforward_gradient": True}}})["slide_samer"]["train"][
        "pushforward_gradient"] is True
    with pytest.raises(config.ConfigError, match=r"slide_samer\.train\.pushforward_gradient.*'type': 'boolean'"):
        config.load({"slide_samer": {"train": {"pushforward_gradient": 2}}})


def test_lr_cycles_is_an_optional_positive_integer_absent_by_default():
    """Absent from every default train section (one decay, no trained model's settings change), refused by name
    below 1."""
    defaults = config.load()
    assert not any("lr_cycles" in section["train"] for section in defaults.values()
                   if isinstance(section, dict) and isinstance(section.get("train"), dict))
    assert config.load({"slide_samer": {"train": {"lr_cycles": 3}}})["slide_samer"]["train"]["lr_cycles"] == 3
    with pytest.raises(config.ConfigError, match=r"slide_samer\.train\.lr_cycles.*'minimum': 1"):
        config.load({"slide_samer": {"train": {"lr_cycles": 0}}})


def test_weight_decay_is_an_optional_number_in_0_1_set_only_for_slide_small():
    """0.1 in Slide-Small's defaults (where three seeds measured it lower), absent from every other default train
    section (Adam), accepted in [0, 1] in a scene and a benchmark, refused by name outside it."""
    defaults = config.load()
    assert defaults["slide_small"]["train"]["weight_decay"] == 0.1
    assert not any("weight_decay" in section["train"] for name, section in defaults.items()
                   if name != "slide_small" and isinstance(section, dict) and isinstance(section.get("train"), dict))
    assert config.load({"slide_small": {"train": {"weight_decay": 0.1}}})["slide_small"]["train"]["weight_decay"] == 0.1
    assert config.load({"slide": {"train": {"weight_decay": 0.01}}})["slide"]["train"]["weight_decay"] == 0.01
    with pytest.raises(config.ConfigError, match=r"slide_small\.train\.weight_decay.*'maximum': 1"):
        config.load({"slide_small": {"train": {"weight_decay": 2}}})


def test_bundle_is_an_optional_positive_integer_absent_from_every_default():
    """No default sets model.bundle (one frame per call, the article's model); 2 is accepted in a scene and a
    benchmark, 0 and a word are refused by key."""
    defaults = config.load()
    assert not any("bundle" in section["model"] for section in defaults.values()
                   if isinstance(section, dict) and isinstance(section.get("model"), dict))
    assert config.load({"slide_samer": {"model": {"bundle": 2}}})["slide_samer"]["model"]["bundle"] == 2
    assert config.load({"slide": {"model": {"bundle": 3}}})["slide"]["model"]["bundle"] == 3
    with pytest.raises(config.ConfigError, match=r"slide_small\.model\.bundle.*'minimum': 1"):
        config.load({"slide_small": {"model": {"bundle": 0}}})
    with pytest.raises(config.ConfigError, match=r"slide\.model\.bundle"):
        config.load({"slide": {"model": {"bundle": "two"}}})


def test_edge_features_are_an_optional_list_of_known_names_and_gap_needs_the_radius_property():
    """A list of known names is accepted; an unknown name, and a gap without the radius property, are refused by
    key when the config is read, before anything runs."""
    loaded = config.load({"slide_small": {"model": {"edge_features": ["relative_velocity", "gap"]}}})
    assert loaded["slide_small"]["model"]["edge_features"] == ["relative_velocity", "gap"]
    with pytest.raises(config.ConfigError, match=r"slide\.model\.edge_features\.0.*'spin' is not one of"):
        config.load({"slide": {"model": {"edge_features": ["spin"]}}})
    with pytest.raises(config.ConfigError, match=r"'slide_samer\.model\.edge_features' lists gap.*must list radius"):
        config.load({"slide_samer": {"model": {"edge_features": ["gap"]}}})
    with pytest.raises(config.ConfigError, match=r"'slide\.model\.edge_features' lists gap"):
        config.load({"slide": {"model": {"edge_features": ["gap"]}}})


def test_contact_correction_is_null_or_its_two_keys_and_a_tolerance():
    defaults = config.load()
    for scene in ("slide", "meteorite", "shear"):         # chosen on each scene's valid split (docs/surrogate.md)
        assert defaults[scene]["runtime"]["contact_correction"] == {"allowed_overlap": 0.05, "iterations": 50}
    assert defaults["collapse"]["runtime"]["contact_correction"] == {"allowed_overlap": 0.05, "iterations": 1000,
                                                                     "tolerance": 0.001}
    assert config.load({"slide": {"runtime": {"contact_correction": None}}})["slide"]["runtime"]["contact_correction"] \
        is None
    on = {"allowed_overlap": 0.01, "iterations": 20}
    runtime = config.load({"slide": {"runtime": {"contact_correction": on}}})["slide"]["runtime"]
    assert runtime["contact_correction"] == on
    with pytest.raises(config.ConfigError, match=r"unknown config key 'slide\.runtime\.contact_correction\.iteration'.*"
                                                 r"allowed_overlap, iterations"):
        config.load({"slide": {"runtime": {"contact_correction": {"allowed_overlap": 0.01, "iteration": 20}}}})
    with pytest.raises(config.ConfigError, match=r"contact_correction\.allowed_overlap' = -0\.1.*minimum of 0"):
        config.load({"slide": {"runtime": {"contact_correction": {"allowed_overlap": -0.1, "iterations": 20}}}})
    with pytest.raises(config.ConfigError, match=r"contact_correction\.tolerance' = -0\.01.*minimum of 0"):
        config.load({"slide": {"runtime": {"contact_correction": {"allowed_overlap": 0.1, "iterations": 20,
                                                                  "tolerance": -0.01}}}})


def test_unknown_scale_lists_allowed_scales():
    with pytest.raises(config.ConfigError, match=r"'scale' = 'huge'.*\['ci', 'default', 'paper'\]"):
        config.load({"scale": "huge"})


def test_inverted_ranges_are_refused():
    with pytest.raises(config.ConfigError, match=r"slide\.sweep\.weak_dip"):
        config.load({"slide": {"sweep": {"weak_dip": [20.0, 10.0]}}})
    with pytest.raises(config.ConfigError, match=r"slide\.split.*sum to 1"):
        config.load({"slide": {"split": [0.5, 0.2, 0.1]}})


def test_yaml11_exponent_strings_become_numbers():
    # PyYAML (and so `snakemake --config slide='{young: 5.0e9}'`) reads 5.0e9 as a string.
    assert config.load({"slide": {"young": "5.0e9"}})["slide"]["young"] == 5.0e9
    assert config.load({"slide": {"frames": "12"}})["slide"]["frames"] == 12


def test_true_and_false_strings_become_booleans_and_other_strings_stay():
    # Snakemake reads every scalar inside `--config slide='{...}'` as a string, and `x=true` too.
    assert config.load({"overwrite_scale": "true"})["overwrite_scale"] is True
    assert config.load({"overwrite_scale": "False"})["overwrite_scale"] is False
    assert config.coerce_scalars({"a": ["TRUE", "yes", "12", "truth"]}) == {"a": [True, "yes", 12, "truth"]}
    assert config.coerce_scalars({"ema_decay": "null", "b": "~", "c": "Null", "d": "nullable"}) == \
        {"ema_decay": None, "b": None, "c": None, "d": "nullable"}


def test_meteorite_contact_outside_the_history_is_refused():
    paper = config.load({"scale": "paper"})["meteorite"]
    assert paper["contact_frame"] < paper["model"]["history"]
    with pytest.raises(config.ConfigError,
                       match=r"meteorite\.contact_frame' = 6 must be below 'meteorite\.model\.history' = 6"):
        config.load({"meteorite": {"contact_frame": 6}})


def test_shear_walls_with_holes_wider_than_the_soil_are_refused():
    with pytest.raises(config.ConfigError, match=r"shear\.wall_radius.*shear\.wall_spacing.*holes"):
        config.load({"shear": {"wall_spacing": 2.0, "wall_radius": 0.009}})   # holes 3.7 mm > 3.5 mm soil


@pytest.mark.parametrize("override, key", [
    ({"slide": {"young": float("nan")}}, "slide.young"),
    ({"slide": {"split": [float("nan"), 0.5, 0.5]}}, r"slide.split\[0\]"),
    ({"meteorite": {"radius": [2.0, float("inf")]}}, r"meteorite.radius\[1\]"),
    ({"crosscheck": {"tolerance": float("-inf")}}, "crosscheck.tolerance"),
])
def test_non_finite_numbers_are_refused_by_key(override, key):
    with pytest.raises(config.ConfigError, match=rf"config key '{key}' = .* every number must be finite"):
        config.load(override)


def test_a_nan_in_a_configfile_is_refused_by_key(tmp_path):
    path = tmp_path / "nan.yaml"
    text = yaml.safe_dump(config.defaults())
    assert "young: 1000000000.0" in text
    path.write_text(text.replace("young: 1000000000.0", "young: .nan", 1))
    with pytest.raises(config.ConfigError, match=r"config key '\w+\.young' = nan"):
        config.load(path=path)


@pytest.mark.parametrize("scale", ["ci", "default", "paper"])
def test_the_particle_estimate_follows_the_loose_packings(scale):
    """The estimate (geometry and radii only) is within [0.8, 2] of the particles the loose packing holds; edge
    effects make it an overestimate on the small presets."""
    cfg = config.load({"scale": scale})
    for name, scene in scenes.registry().items():
        built = max(len(scene.settle_setup(p).particles.radius) for p in scene.packings(cfg[name]))
        assert 0.8 <= scene.particle_estimate(cfg[name]) / built <= 2.0, (name, scale)


def test_a_huge_particle_count_is_refused_before_anything_is_built():
    with pytest.raises(config.ConfigError, match=r"'slide': radius \[0.005, 0.005\] gives about 1[0-9],\d{3},\d{3} "
                                                 r"particles .* MiB .* above 'limits.particles' = 1,000,000"):
        config.load({"slide": {"radius": [0.005, 0.005]}})
    config.load({"slide": {"radius": [0.005, 0.005]}, "limits": {"particles": 20_000_000}, "scale": "ci"})


def test_a_contender_set_to_null_is_left_out_and_a_removed_main_is_refused():
    nulls = {"dem": {"dt_5pct": None}, "surrogate": {"sleep": "null"}}
    perf = config.load({"scale": "ci", "slide": {"performance": nulls}})["slide"]["performance"]
    assert "dt_5pct" not in perf["dem"] and "sleep" not in perf["surrogate"]      # the ci preset's sleep too
    assert {"reference", "dt_2pct", "dt_10pct"} <= set(perf["dem"]) and "graphdem" in perf["surrogate"]
    with pytest.raises(config.ConfigError, match=r"'slide.performance.main' = 'graphdem' is not a surrogate contender"):
        config.load({"slide": {"performance": {"surrogate": {"graphdem": None}}}})


def test_rollout_finetuning_is_the_benchmarks_default_scale_only_and_overridable_by_key():
    """Both public benchmarks fine-tune on 14-frame rollouts from random starts at the default scale (Slide-SameR
    16 epochs at 8e-5 with four sims per step and a weight average of 0.995, Slide-Small 20, about the cost of its
    former whole-rollout epochs, at 4e-5 with two sims per step and 0.99); the ci and paper scales and every scene
    train one-step only; a partial override keeps the preset's other keys, null turns it off, and a
    bad value is refused by key."""
    defaults = config.load()
    assert defaults["slide_samer"]["train"]["finetune"]["epochs"] == 16
    assert defaults["slide_samer"]["train"]["finetune"]["frames"] == 14
    assert defaults["slide_small"]["train"]["finetune"]["epochs"] == 20
    assert defaults["slide_small"]["train"]["finetune"]["frames"] == 14
    samer, small = (defaults[name]["train"]["finetune"] for name in ("slide_samer", "slide_small"))
    assert samer["lr"] == 8e-5 and samer["batch_size"] == 4 and samer["warmup"] == 175
    assert small["lr"] == 4e-5 and small["batch_size"] == 2 and small["warmup"] == 175   # twice the updates and rate
    assert samer["ema_decay"] == 0.995 and small["ema_decay"] == 0.99     # measured on Slide-SameR only
    # only the epochs that held every best are validated: Slide-SameR's last 6 one-step epochs, both sets' last 10
    # fine-tuning epochs; Slide-Small validates every one-step epoch (a seed's best came at its 8th of 12)
    assert defaults["slide_samer"]["train"]["validate_last"] == 6 and "validate_last" not in defaults[
        "slide_small"]["train"]
    assert samer["validate_last"] == 10 and small["validate_last"] == 10
    assert not any("finetune" in section["train"] for name, section in defaults.items()
                   if name not in ("slide_samer", "slide_small") and isinstance(section, dict)
                   and isinstance(section.get("train"), dict))
    for scale in ("ci", "paper"):
        assert "finetune" not in config.load({"scale": scale})["slide_samer"]["train"]
    partial = config.load({"slide_small": {"train": {"finetune": {"epochs": 3}}}})["slide_small"]["train"]["finetune"]
    assert partial == {**defaults["slide_small"]["train"]["finetune"], "epochs": 3}
    assert config.load({"slide_small": {"train": {"finetune": None}}})["slide_small"]["train"]["finetune"] is None
    with pytest.raises(config.ConfigError, match=r"slide_samer\.train\.finetune"):
        config.load({"slide_samer": {"train": {"finetune": {"lr": -1.0}}}})
    scheduled = config.load({"slide_small": {"train": {"finetune": {"warmup": 100, "lr_final": 1.0e-6}}}})
    assert scheduled["slide_small"]["train"]["finetune"] == {**defaults["slide_small"]["train"]["finetune"],
                                                             "warmup": 100, "lr_final": 1.0e-6}
    assert not any("lr_final" in defaults[name]["train"]["finetune"]
                   for name in ("slide_samer", "slide_small"))          # absent: constant after the warm-up
    with pytest.raises(config.ConfigError, match=r"slide_small\.train\.finetune"):
        config.load({"slide_small": {"train": {"finetune": {"warmup": -1}}}})
    for key, bad in (("lr", 2.0), ("lr_final", 1.5)):       # the key inside the mapping form is named, not the form
        with pytest.raises(config.ConfigError, match=rf"'slide_small\.train\.finetune\.{key}' = {bad} is not "
                                                     rf"allowed: {bad} is greater than the maximum of 1"):
            config.load({"slide_small": {"train": {"finetune": {key: bad}}}})
    with pytest.raises(config.ConfigError, match=r"'slide_small\.train\.finetune' = 'on' is not allowed; allowed: "
                                                 r"null or a mapping of epochs, lr, batch_size"):
        config.load({"slide_small": {"train": {"finetune": "on"}}})


@pytest.mark.parametrize("value", [2.5, "two", -1, True])
def test_ensemble_members_is_a_count_per_scale_and_anything_else_is_refused_by_key(value):
    """The DEM ensemble's members per test sim: 2 at the ci scale, 5 at the default and paper scales, a user's
    count (0: none) over either; a non-integer is refused, naming the key."""
    for scale, members in (("ci", 2), ("default", 5), ("paper", 5)):
        loaded = config.load({"scale": scale})
        assert {loaded[name]["evaluate"]["ensemble_members"] for name in scenes.names()} == {members}
    assert config.load({"scale": "ci", "shear": {"evaluate": {"ensemble_members": 0}}})["shear"]["evaluate"][
        "ensemble_members"] == 0
    with pytest.raises(config.ConfigError, match=r"config key 'slide\.evaluate\.ensemble_members' = "):
        config.load({"slide": {"evaluate": {"ensemble_members": value}}})


def _key_paths(node: dict, prefix: tuple = ()) -> dict[tuple, tuple]:
    """Every leaf of a parsed YAML mapping by its key path: a non-empty mapping's keys are walked into, anything
    else (a scalar, a list, an empty mapping) is a leaf, kept with its type name so that 1 and 1.0 differ."""
    paths = {}
    for key, value in node.items():
        if isinstance(value, dict) and value:
            paths.update(_key_paths(value, (*prefix, key)))
        else:
            paths[(*prefix, key)] = (type(value).__name__, value)
    return paths


def test_no_default_is_repeated_in_every_scene_yaml_and_the_base_reaches_every_scene():
    """A key whose default is the same in every scene's YAML belongs in generators/scenes/base.yaml (no scene
    repeats a base key with the base's value), and every key of the base, scale presets included, is in each
    resolved scene section, with the base's value where the scene's YAML does not set its own."""
    own = {name: _key_paths(config.scene_own(name)) for name in scenes.names()}
    first, *rest = own.values()
    assert [".".join(map(str, p)) for p, v in first.items() if all(o.get(p) == v for o in rest)] == []
    base = _key_paths(config.scene_base())
    assert [f"{name}: {'.'.join(map(str, p))}" for name, paths in own.items() for p, v in base.items()
            if paths.get(p) == v] == []
    for scale in ("ci", "default", "paper"):
        loaded = config.load({"scale": scale})
        for name, paths in own.items():
            resolved = _key_paths(loaded[name])
            for path, value in base.items():
                if path[0] == "scales" and path[1] != scale:
                    continue
                key = path[2:] if path[0] == "scales" else path
                assert key in resolved, f"{name} at scale {scale}: base key {'.'.join(map(str, key))} missing"
                if path not in paths and key not in paths:
                    assert resolved[key] == value, f"{name} at scale {scale}: {'.'.join(map(str, key))}"


# ---- exact types and the cross-key checks (generators/config_checks.py) --------------------------------------


@pytest.mark.parametrize("override, key, words", [
    ({"slide": {"n_sims": 10.0}}, "slide.n_sims", "it must be an integer (10, not 10.0)"),
    ({"slide": {"frames": 20.0}}, "slide.frames", "it must be an integer (20, not 20.0)"),
    ({"slide": {"train": {"valid_sims": 3.0}}}, "slide.train.valid_sims", "it must be an integer or null (3, not 3.0)"),
    ({"crosscheck": {"sims": 4.0}}, "crosscheck.sims", "an integer >= 2"),
    ({"slide_samer": {"sims": {"train": 6.0}}}, "slide_samer.sims.train", "an integer"),
])
def test_a_float_for_an_integer_key_is_refused_naming_the_key(override, key, words):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert f"'{key}' = " in str(err.value) and words in str(err.value)


def test_integers_stay_accepted_where_numbers_are_allowed():
    cfg = config.load({"scale": "ci", "slide": {"young": 1000000000, "frame_interval": 1}})
    assert cfg["slide"]["young"] == 1000000000 and cfg["slide"]["frame_interval"] == 1


@pytest.mark.parametrize("override, keys, allowed", [
    ({"slide": {"frames": 6}}, ["slide.frames", "slide.model.history"], "at least 7"),
    ({"slide": {"model": {"history": 20}}}, ["slide.frames", "slide.model.history"], "at least 21"),
    ({"slide": {"model": {"bundle": 15}}}, ["slide.model.bundle"], "at least 21"),
    ({"slide": {"evaluate": {"frames": [15, 30]}}}, ["slide.evaluate.frames", "slide.frames"], "taus among 1..14"),
])
def test_the_history_and_the_evaluated_frames_must_lie_in_the_recorded_window(override, keys, allowed):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert all(f"'{key}' = " in str(err.value) for key in keys) and allowed in str(err.value)


def test_evaluated_frames_partly_in_the_window_are_kept():
    """The ci meteorite lists Table 2's taus (5..30) and predicts 6 frames: the Acc averages tau 5."""
    cfg = config.load({"scale": "ci"})["meteorite"]
    assert cfg["frames"] - cfg["model"]["history"] == 6 and cfg["evaluate"]["frames"] == [5, 10, 15, 20, 30]


@pytest.mark.parametrize("override, keys, empty", [
    ({"slide": {"split": [1.0, 0.0, 0.0]}}, ["slide.split"], "valid and test split empty"),
    ({"slide": {"split": [0.5, 0.5, 0.0]}}, ["slide.split"], "test split empty"),
    ({"slide": {"n_sims": 2}}, ["slide.split", "slide.n_sims"], "test split empty"),
    ({"collapse": {"sweep": {"n_aspects": 1}}}, ["collapse.sweep.n_aspects", "collapse.sweep.friction"],
     "split empty"),
    ({"shear": {"sweep": {"n_young": 1, "n_normal_stress": 1}}}, ["shear.sweep.n_young", "shear.sweep.displacements"],
     "split empty"),
])
def test_a_split_that_leaves_a_split_empty_is_refused_naming_the_sweep_size(override, keys, empty):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert all(f"'{key}' = " in str(err.value) for key in keys) and empty in str(err.value)


def test_the_split_check_follows_the_sweep_rule_at_its_smallest():
    cfg = config.load({"scale": "ci", "slide": {"n_sims": 3}})["slide"]
    assert sweep.split_counts(3, cfg["split"]) == [1, 1, 1]
    assert sorted(sweep.build("slide", cfg)["split"]) == ["test", "train", "valid"]


def test_a_sweep_larger_than_n_sims_allows_is_refused():
    with pytest.raises(config.ConfigError, match=r"1,000,000 sims \('meteorite.sweep.n_angles' = 1000"):
        config.load({"scale": "ci", "meteorite": {"sweep": {"n_angles": 1000, "n_speeds": 1000}}})


@pytest.mark.parametrize("override, key", [
    ({"slide": {"frame_interval": 1.0e6}}, "slide.frame_interval"),
    ({"slide": {"dt": 1.0e-12}}, "slide.dt"),
    ({"slide": {"dt_safety": 1.0e-9}}, "slide.dt_safety"),
    ({"slide": {"stability": {"dem_dt_factors": [1.0e-9]}}}, "slide.stability.dem_dt_factors"),
    ({"slide": {"performance": {"dem": {"dt_5pct": {"dt_safety": 1.0e-9}}}}},
     "slide.performance.dem.dt_5pct.dt_safety"),
    ({"slide": {"performance": {"dem": {"x": {"stiffness_factor": 1.0e20}}}}},
     "slide.performance.dem.x.stiffness_factor"),
    ({"shear": {"sweep": {"displacements": [1.0e6]}}}, "shear.sweep.displacements"),
    ({"shear": {"load_time": 1.0e9}}, "shear.load_time"),
    ({"shear": {"shear_speed": None, "max_inertial_number": 1.0e-9}}, "shear.max_inertial_number"),
])
def test_a_run_whose_steps_overflow_lammps_counts_is_refused(override, key):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert f"'{key}' = " in str(err.value) and "32-bit" in str(err.value)


def test_a_settling_whose_steps_overflow_is_refused():
    with pytest.raises(config.ConfigError, match=r"'slide.settle_time' = 1000000000.0 and 'slide.settle_check'.*32"):
        config.load({"scale": "ci", "slide": {"settle_time": 1.0e9}})


def test_an_explicit_step_above_the_stable_limit_is_refused_when_read():
    with pytest.raises(config.ConfigError, match=r"'slide.dt' = 1.0 exceeds the stable limit"):
        config.load({"scale": "ci", "slide": {"dt": 1.0}})


def test_the_step_bound_matches_the_decks_at_its_edge():
    """The largest frame interval the check lets through gives a recorded run LAMMPS counts in 32 bits."""
    from generators.config_checks import MAX_STEPS
    from generators.lammps import deck

    cfg = config.load({"scale": "ci", "slide": {"frame_interval": 3000.0}})["slide"]
    scene, row = scenes.get("slide"), sweep.build("slide", cfg).iloc[0].to_dict()
    params = scene.packings(cfg)[0]
    setup = scene.simulate_setup(row, scene.settle_setup(params).particles)
    runs = [int(line.split()[1]) for line in deck.record_deck(setup).splitlines() if line.startswith("run ")]
    assert 10 ** 9 < max(runs) <= MAX_STEPS
    with pytest.raises(config.ConfigError, match="32-bit"):
        config.load({"scale": "ci", "slide": {"frame_interval": 9000.0}})


@pytest.mark.parametrize("value", [1.0, 0.99999, 0.01])
def test_a_restitution_lammps_damping_cannot_reach_is_refused(value):
    with pytest.raises(config.ConfigError, match=r"'slide.restitution' = .*Tsuji"):
        config.load({"scale": "ci", "slide": {"restitution": value}})


@pytest.mark.parametrize("override, keys", [
    ({"slide": {"seed": 2 ** 32}}, ["slide.seed"]),
    ({"slide": {"train": {"seed": 2 ** 32}}}, ["slide.train.seed"]),
    ({"slide": {"stability": {"seed": -1}}}, ["slide.stability.seed"]),
    ({"shear": {"shear_stress_readout": {"seed": 2 ** 40}}}, ["shear.shear_stress_readout.seed"]),
    ({"seeds": 3, "slide_small": {"train": {"seed": 2 ** 32 - 2}}}, ["slide_small.train.seed", "seeds"]),
])
def test_seeds_beyond_numpys_range_are_refused_by_key(override, keys):
    with pytest.raises(config.ConfigError) as err:
        config.load({"scale": "ci", **override})
    assert all(f"'{key}' = " in str(err.value) for key in keys)


def test_an_integer_beyond_64_bits_is_refused_by_key():
    with pytest.raises(config.ConfigError, match=r"'meteorite.sweep.speed\[1\]' = 10{30}.*within 64 bits"):
        config.load({"scale": "ci", "meteorite": {"sweep": {"speed": [60.0, 10 ** 30]}}})


def test_the_particle_limit_names_the_geometry_keys():
    with pytest.raises(config.ConfigError, match=r"'slide.domain' = \[80000000000000.0, 80.0\].*limits.particles"):
        config.load({"scale": "ci", "slide": {"domain": [8.0e13, 80.0]}})
