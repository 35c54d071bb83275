"""The content key of a settled packing: identical parameters share one packing, any change makes another."""

from generators.packing import packing_key


def test_the_key_depends_on_the_content_not_the_order_and_names_the_index():
    params = {"radius": [0.9, 1.1], "seed": 3, "packing_index": 2}
    key = packing_key(params)
    assert key == packing_key(dict(reversed(list(params.items()))))         # key order does not matter
    assert key.startswith("p2-") and len(key) == len("p2-") + 10
    assert packing_key({**params, "seed": 4}) != key
    assert packing_key({**params, "radius": [0.9, 1.2]}) != key
    assert packing_key({"seed": 3}).startswith("p0-")                      # no index: packing 0
