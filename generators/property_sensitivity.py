"""The property values of a scene's property-sensitivity test (article Fig. 14; the test itself is
evaluation/property_sensitivity.py): which value of one swept node property each of the two DEM reruns takes.

``evaluate.property_sensitivity: {property: P, at: [a, b]}`` sets P to the points a < b of its swept range
``sweep.P = [lo, hi]``, log-interpolated as the sweep spaces a modulus or a stress:

    value(a) = lo * (hi / lo) ** a,     0 <= a <= 1

The shear's points 0.1 and 0.9 lie on a sweep grid of n log-spaced values from min to max only when n - 1 is
a multiple of 10 (not at the ci's 2, the default's 6 or the paper's 20 moduli): the model meets property values
it was not trained on, and the DEM reruns are sims it never saw.
"""

from __future__ import annotations

from generators.errors import ConfigError


def values(section: str, cfg: dict) -> list[float]:
    """The two rerun values (low, high) of config section ``section`` (a scene's); ConfigError naming the key
    where the test is set but its property is not a swept node property of the model."""
    test = cfg["evaluate"].get("property_sensitivity")
    if test is None:
        return []
    name, (a, b) = test["property"], test["at"]
    key = f"'{section}.evaluate.property_sensitivity'"
    if name not in (cfg["model"].get("properties") or []):
        raise ConfigError(f"config key {key}: property {name!r} is not a node property of the model "
                          f"('{section}.model.properties' = {cfg['model'].get('properties') or []})")
    swept = (cfg.get("sweep") or {}).get(name)
    if not (isinstance(swept, list) and len(swept) == 2):
        raise ConfigError(f"config key {key}: property {name!r} has no swept range '{section}.sweep.{name}' = "
                          f"[min, max]; allowed: a swept property, one of {sorted(cfg.get('sweep') or {})}")
    if not a < b:
        raise ConfigError(f"config key {key}: at = {[a, b]} must be two points a < b of the swept range (0..1)")
    lo, hi = float(swept[0]), float(swept[1])
    if not 0.0 < lo < hi:
        raise ConfigError(f"config key '{section}.sweep.{name}' = {swept}: the property-sensitivity test "
                          f"log-interpolates in it, so it needs 0 < min < max")
    return [float(f"{lo * (hi / lo) ** float(t):.6g}") for t in (a, b)]
