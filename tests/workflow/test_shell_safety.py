"""No config string reaches a shell unquoted: names are validated when the config is read, paths are quoted.

Every string the schema allows is found by walking the schema, so a new free string fails here until it is
either a validated name (pattern or enum) or a path that every rule quotes.
"""

import json
import pickle
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from generators import config

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
INJECTIONS = ("x$(touch pwned)", "x; touch pwned", "two words", "`touch pwned`")
PATHS = {"solidgn_root"}          # free strings that are paths: accepted, and quoted wherever used


def string_keys(node: dict, root: dict, path: tuple = ()) -> dict[tuple, dict]:
    """Every config key path (list items as 0) whose schema allows a string, with its schema node."""
    while "$ref" in node:
        node = config._resolve(node["$ref"], root)
    found = {}
    for member in node.get("allOf", []):
        found.update(string_keys(member, root, path))
    types = node.get("type", [])
    if "string" in (types if isinstance(types, list) else [types]):
        found[path] = node
    for key, child in node.get("properties", {}).items():
        found.update(string_keys(child, root, (*path, key)))
    if isinstance(node.get("additionalProperties"), dict):
        found.update(string_keys(node["additionalProperties"], root, (*path, "*")))
    if isinstance(node.get("items"), dict):
        found.update(string_keys(node["items"], root, (*path, 0)))
    return found


STRING_KEYS = string_keys(config.schema(), config.schema())


def override(path: tuple, value) -> dict:
    """A --config override setting ``path`` (list items as one-item lists) to ``value``."""
    for part in reversed(path):
        value = [value] if part == 0 else {part: value}
    return value


def test_the_schema_walk_finds_the_free_strings():
    names = {".".join(str(p) for p in k) for k in STRING_KEYS}
    assert {"solidgn_root", "slide.performance.main", "slide.performance.reference", "slide.model.properties.0",
            "slide_samer.source", "shear.model.properties.0"} <= names


def test_every_string_key_is_a_validated_name_or_a_quoted_path():
    for path, node in STRING_KEYS.items():
        name = ".".join(str(p) for p in path)
        assert "pattern" in node or "enum" in node or "const" in node, f"{name} is an unchecked free string"
        if path[0] in PATHS:
            continue
        for bad in INJECTIONS:
            with pytest.raises(config.ConfigError) as err:
                config.load(override(path, bad))
            assert name in str(err.value), (name, bad, str(err.value))


def test_contender_names_must_exist_when_the_config_is_read():
    with pytest.raises(config.ConfigError, match=r"'slide.performance.main' = 'tpyo' is not a surrogate contender"):
        config.load({"slide": {"performance": {"main": "tpyo"}}})
    with pytest.raises(config.ConfigError, match=r"'slide.performance.reference' = 'graphdem' is not a dem contender"):
        config.load({"slide": {"performance": {"reference": "graphdem"}}})


SHELL_PLACEHOLDER = re.compile(r"\{(params|input|output)[^}]*\}")


def test_every_config_derived_placeholder_in_a_shell_command_is_quoted():
    for rule_file in sorted((ROOT / "workflow" / "rules").glob("*.smk")):
        text = rule_file.read_text()
        for block in re.findall(r"shell:\n((?:\s+\".*\"\n?)+)", text):
            for placeholder in SHELL_PLACEHOLDER.finditer(block):
                assert placeholder.group(0).endswith(":q}"), f"{rule_file.name}: {placeholder.group(0)} is unquoted"


def fake_solidgn(root: Path) -> None:
    rng = np.random.default_rng(0)
    (root / "Slide_Same_R").mkdir(parents=True)
    (root / "Slide_Same_R" / "metadata.json").write_text(json.dumps(
        {"bounds": [[0, 100], [0, 80]], "dim": 2, "dt": 0.001, "default_connectivity_radius": 9.75}))
    for split in ("train", "valid", "test"):
        (root / "Slide_Same_R" / split).mkdir()
        traj = {"particle_type": np.array([0.0, 0, 1, 1, 2]), "particle_r": np.full(5, 1.5),
                "particle_m": np.array([0.0, 0, 5, 5, 5]), "position": rng.uniform(0, 80, (4, 5, 2))}
        (root / "Slide_Same_R" / split / "0.pkl").write_bytes(pickle.dumps(traj))


@pytest.mark.engine
def test_a_path_with_shell_syntax_is_one_argument_and_runs_nothing(tmp_path):
    evil = tmp_path / "data $(touch pwned); `touch pwned` x"
    fake_solidgn(evil)
    work = tmp_path / "work"
    work.mkdir()
    cmd = [SNAKEMAKE, "-c1", "-p", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(work),
           "results/slide_samer/import/splits.csv", "--config", "scale=ci", f"solidgn_root={evil}"]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    shell = next(line for line in (proc.stdout + proc.stderr).splitlines() if "graphdem import-solidgn" in line)
    words = shlex.split(shell[shell.index("graphdem import-solidgn"):])
    assert words[2] == str(evil / "Slide_Same_R")
    assert (work / "results" / "slide_samer" / "import" / "splits.csv").is_file()
    assert not list(tmp_path.rglob("pwned")) and not list(ROOT.glob("pwned"))
