"""The Scene base: a packing's parameters are derived from what its settling reads, not listed by hand."""

from generators import config, scenes
from generators.packing import packing_key


def test_packing_parameters_are_what_settling_reads():
    cfg = config.load({"scale": "ci"})["slide"]
    slide = scenes.get("slide")
    params = slide.packing_params(cfg, 0)
    # read by the settling: geometry, material, time step, settling, seeds
    assert {"domain", "bedrock_profile", "radius", "young", "dt_safety", "settle_time", "seed",
            "packing_index"} <= set(params)
    # never read by it: the trigger, the recording and the blow-up energy limit of the recorded run
    assert not {"weak_friction", "frames", "frame_interval", "record_start", "max_energy_gain", "sweep"} & set(params)


def test_a_key_only_the_recorded_run_reads_keeps_the_packing_and_one_settling_reads_changes_it():
    base = config.load({"scale": "ci"})
    key = scenes.get("slide").packing_keys_of(base["slide"])
    weaker = config.load({"scale": "ci", "slide": {"weak_friction": 0.01, "frames": 12}})
    stiffer = config.load({"scale": "ci", "slide": {"young": 2.0e9}})
    assert scenes.get("slide").packing_keys_of(weaker["slide"]) == key
    assert scenes.get("slide").packing_keys_of(stiffer["slide"]) != key


def test_every_scene_derives_keys_its_settling_can_rebuild_from():
    """Each packing's parameters alone describe the same settling (nothing it reads is left out)."""
    cfg = config.load({"scale": "ci"})
    for name, scene in scenes.registry().items():
        for params in scene.packings(cfg[name]):
            setup = scene.settle_setup(dict(params))        # a plain dict: a missing key would raise
            assert setup.particles.x.shape[0] > 0 and packing_key(params).startswith("p")
