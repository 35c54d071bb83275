"""The items an import is given: options over a metadata file's keys, per-type values, and their refusals."""

import numpy as np
import pytest

from generators.importers import metadata
from generators.importers.metadata import ImportRefused


def test_options_win_over_the_metadata_file_and_replace_its_whole_group(tmp_path):
    path = tmp_path / "meta.yaml"
    path.write_text("radius: {1: 0.5, '2': 0.25}\ndensity: 2650\ndt: 0.001\nframe_interval: 0.1\nbox: [[0, 1], [0, 2]]"
                    "\nkinematic_types: 0\n")
    items = metadata.given({"mass": metadata.option_value("mass", ["3=1.5", "4=0"]), "dt": 0.002}, path)
    assert items.values == {"radius": {1: 0.5, 2: 0.25}, "mass": {3: 1.5, 4: 0.0}, "kinematic_types": [0],
                            "box": [[0.0, 1.0], [0.0, 2.0]], "dt": 0.002}     # no density, no frame_interval
    assert items.where("mass") == "--mass" and items.where("radius") == f"{path} key 'radius'"
    assert items.record()["radius"] == {"value": {"1": 0.5, "2": 0.25}, "from": f"{path} key 'radius'"}
    assert metadata.option_value("radius", ["0.01"]) == 0.01


@pytest.mark.parametrize("text, message", [
    ("radius: 0.01\nfriction: 0.5\n", r"unknown key\(s\) \['friction'\]; allowed: radius, density, mass"),
    ("radius: -1\n", "key 'radius': radius must be a positive finite number, got -1"),
    ("mass: {1.5: 2}\n", "key 'mass': mass: particle type 1.5 must be a whole number >= 0"),
    ("box: [[0, 1], [2, 1]]\n", "box must be 2 or 3 finite"),
    ("dim: 4\n", "dim must be 2 or 3, got 4"),
    ("mass: 1\ndensity: 2\n", "give the mass or the density of the particles, not both"),
    ("- radius\n", "a metadata file holds a mapping of items"),
    ("radius: [0.1\n", "not a readable YAML metadata file"),
])
def test_a_bad_metadata_file_is_refused_naming_the_file_and_key(tmp_path, text, message):
    path = tmp_path / "meta.yaml"
    path.write_text(text)
    with pytest.raises(ImportRefused, match=message) as caught:
        metadata.given({}, path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_per_type_option_is_one_number_or_types_and_numbers():
    with pytest.raises(ImportRefused, match=r"--radius '0.2': give one number for every particle, or TYPE=VALUE"):
        metadata.option_value("radius", ["1=0.1", "0.2"])
    with pytest.raises(ImportRefused, match=r"--density 'x': not a number"):
        metadata.option_value("density", ["1=x"])


def test_per_particle_values_follow_the_types_and_kinematic_ones_may_lack_a_mass():
    species = np.array([2, 0, 2, 1])
    np.testing.assert_array_equal(metadata.per_particle("radius", {0: 1.0, 1: 2.0, 2: 3.0}, species, "--radius"),
                                  [3.0, 1.0, 3.0, 2.0])
    np.testing.assert_array_equal(metadata.per_particle("mass", {2: 5.0, 1: 4.0}, species, "--mass",
                                                        kinematic=species == 0), [5.0, 0.0, 5.0, 4.0])
    with pytest.raises(ImportRefused, match=r"--mass: no mass for particle type\(s\) \[0\] \(given for \[1, 2\]\): "
                                            r"give one per type, e.g. --mass 0=VALUE"):
        metadata.per_particle("mass", {2: 5.0, 1: 4.0}, species, "--mass")
    np.testing.assert_allclose(metadata.volume([1.0, 2.0], 2), [np.pi, 4 * np.pi])
    np.testing.assert_allclose(metadata.volume([1.0], 3), [4 / 3 * np.pi])
