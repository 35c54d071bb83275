"""The architecture: the packages' layering (docs/architecture.md, "Packages"), no import circles, one registry
of scenes and one of engines served by every stage, no scene or engine named outside its own module (or package)
and config (tests/test_packaging.py checks that a wheel carries the defaults; tests/generators/test_engine.py
registers a new engine's name), no function over 80 lines."""

import ast
import graphlib
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from generators import config, engines, scenes

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
STAGES = ("sweep", "prepare", "simulate", "convert", "dataset", "train", "rollout", "evaluate")


# The packages, lowest layer first: each may import the ones before it and itself, never one after it. generators
# (scenes, DEM engines, H5MD) knows nothing of learning; surrogate (the model, its training and use) nothing of how
# it is measured; evaluation (what measures a trained surrogate) may use both; graphdem (the public API and the
# command) all three. The workflow's own helpers (workflow/graphdem_workflow/) may import generators alone.
LAYERS = ("generators", "surrogate", "evaluation", "graphdem")
PACKAGES = (*LAYERS, "workflow/graphdem_workflow")


def _python_files(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def _imported_packages(path: Path) -> list[tuple[int, str]]:
    """(line, top-level package) of every import in ``path``: module level, in functions, under TYPE_CHECKING."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
        found += [(node.lineno, name.split(".")[0]) for name in names]
    return found


def test_each_package_imports_only_the_layers_below_it():
    """generators imports neither surrogate, evaluation nor graphdem; surrogate neither evaluation nor graphdem;
    evaluation not graphdem; the workflow's helpers only generators. Every import counts, in a function too."""
    allowed = {package: set(LAYERS[:i + 1]) for i, package in enumerate(LAYERS)}
    allowed["workflow/graphdem_workflow"] = {"generators", "graphdem_workflow"}
    offenders = [f"{path.relative_to(ROOT)}:{line}: imports {name}"
                 for package in PACKAGES for path in _python_files(package)
                 for line, name in _imported_packages(path)
                 if name in {*LAYERS, "graphdem_workflow"} - allowed[package]]
    assert offenders == []


def test_the_layering_test_sees_a_forbidden_import(tmp_path):
    """The check above finds an import inside a function and one under TYPE_CHECKING."""
    path = tmp_path / "probe.py"
    path.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from evaluation import tables\n\n"
                    "def f():\n    import graphdem.cli\n")
    assert _imported_packages(path) == [(1, "typing"), (3, "evaluation"), (6, "graphdem")]


def test_the_registry_holds_every_scene_module_and_each_has_its_config_and_schema():
    names = scenes.names()
    assert names == sorted(names) and {"slide", "meteorite", "shear", "collapse"} <= set(names)
    folder = ROOT / "generators" / "scenes"
    for name in names:
        assert (folder / f"{name}.yaml").is_file() and (folder / f"{name}.schema.yaml").is_file()
        scene = scenes.get(name)
        assert set(scene.kinematic_species) <= set(scene.species) and scene.dim in (2, 3)
        assert set(scene.metrics.names + scene.metrics.pair_names) <= set(scene.metrics.units)
    cfg = config.load({"scale": "ci"})
    assert set(names) <= set(cfg)


def _names_in_python(path: Path, names: set[str]) -> list[str]:
    """Where the code of ``path`` names one of ``names``: as a string, an attribute, a variable or an import."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
            found.append(node.value)
        elif isinstance(node, ast.Attribute) and node.attr in names:
            found.append(node.attr)
        elif isinstance(node, ast.Name) and node.id in names:
            found.append(node.id)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = [a.name for a in node.names] + ([node.module] if isinstance(node, ast.ImportFrom) else [])
            found += [m for m in modules if m and m.split(".")[-1] in names]
    return found


def test_no_scene_is_named_outside_its_own_module_and_config():
    """Every stage reaches a scene through the registry: no code outside generators/scenes/<name>.py (and
    its YAML files) names it, whether as a string, an attribute, a variable or an import."""
    names = set(scenes.names())
    offenders = []
    for package in ("generators", "surrogate", "evaluation"):
        for path in _python_files(package):
            if path.parent == ROOT / "generators" / "scenes" and path.stem in names:
                continue
            offenders += [f"{path.relative_to(ROOT)}: {n}" for n in _names_in_python(path, names)]
    offenders += _workflow_code_naming(names)
    assert offenders == []


# A physical quantity, not a scene: the shear stress (its rules' subcommands and report subcategory name it, e.g.
# `graphdem shear-stress-check`; they serve every scene whose section has a shear_stress_readout).
QUANTITIES = re.compile(r"\bshear[- ]stress\b")


def _workflow_code_naming(names: set[str]) -> list[str]:
    """Where the workflow's code (comments and the QUANTITIES left out) names one of ``names`` as a word."""
    word = re.compile(r"\b(" + "|".join(sorted(names)) + r")\b")
    found = []
    for path in [ROOT / "workflow" / "Snakefile", *sorted((ROOT / "workflow" / "rules").glob("*.smk"))]:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            code = QUANTITIES.sub("", line.split("#", 1)[0])
            found += [f"{path.relative_to(ROOT)}:{number}: {m}" for m in word.findall(code)]
    return found


def _yaml_values(node) -> list:
    """Every key and scalar of a parsed YAML document."""
    if isinstance(node, dict):
        return [v for key, value in node.items() for v in (key, *_yaml_values(value))]
    if isinstance(node, list):
        return [v for value in node for v in _yaml_values(value)]
    return [node]


def test_no_engine_is_named_outside_its_package_and_the_registry():
    """Every choice of engine comes from generators/engines.py: no code outside it and the engines' own packages
    names an engine (as a string, attribute, variable or import), no rule names one, and no schema lists them:
    registering an engine is one line there (docs/architecture.md, "Adding an engine")."""
    names = set(engines.NAMES)
    assert names >= {"lammps", "yade"}
    offenders = []
    for package in ("generators", "surrogate", "evaluation"):
        for path in _python_files(package):
            own = path.relative_to(ROOT / package).parts[0] in names
            if not own and path != ROOT / "generators" / "engines.py":
                offenders += [f"{path.relative_to(ROOT)}: {n}" for n in _names_in_python(path, names)]
    offenders += _workflow_code_naming(names)
    schemas = [ROOT / "generators" / "defaults" / "schema.yaml", *sorted((ROOT / "generators" / "scenes").glob(
        "*.schema.yaml"))]
    for path in schemas:
        offenders += [f"{path.relative_to(ROOT)}: {v}" for v in _yaml_values(yaml.safe_load(path.read_text()))
                      if v in names]
    assert offenders == []


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_targets(node: ast.Import | ast.ImportFrom, known: set[str]) -> set[str]:
    """The project's modules an import statement runs: the module named and every package above it
    (``from a import b`` runs the module a.b where that is one, else a)."""
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        names = [f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in known else node.module
                 for a in node.names]
    parts = [name.split(".") for name in names if name]
    return {".".join(p[:i]) for p in parts for i in range(1, len(p) + 1)} & known


def _imports(path: Path, known: set[str]) -> tuple[set[str], set[str]]:
    """The project modules ``path`` imports when it is imported (module level, class bodies) and those it imports
    only inside functions; imports under ``if TYPE_CHECKING`` never run."""
    top: set[str] = set()
    local: set[str] = set()

    def visit(nodes, inside: bool) -> None:
        for node in nodes:
            if isinstance(node, ast.Import | ast.ImportFrom):
                (local if inside else top).update(_import_targets(node, known))
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                visit(ast.iter_child_nodes(node), True)
            elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                visit(node.orelse, inside)
            else:
                visit(ast.iter_child_nodes(node), inside)

    assert all(not getattr(n, "level", 0) for n in ast.walk(ast.parse(path.read_text()))), f"{path}: relative import"
    visit(ast.parse(path.read_text()).body, False)
    here = _module_name(path)
    return top - {here}, local - top - {here}


def _import_graph() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """The module import graph of the packages: (module-level edges, function-level edges)."""
    paths = {_module_name(p): p for package in LAYERS for p in _python_files(package)}
    graphs = {name: _imports(path, set(paths)) for name, path in paths.items()}
    return {n: g[0] for n, g in graphs.items()}, {n: g[1] for n, g in graphs.items()}


def _reach(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for nxt in graph[todo.pop()] - seen:
            seen.add(nxt)
            todo.append(nxt)
    return seen


def test_the_module_import_graph_has_no_circle():
    """Module-level imports form no circle, and no function-level import closes one that a module-level import
    opens (a circle hidden by importing inside a function, as the config loader, the scenes and the property
    test had through ConfigError: it lives in generators/errors.py; and as Scene.physics' default did to name the
    scenes that have a physics check: the physics command names them now)."""
    top, local = _import_graph()
    assert {"generators.config", "generators.errors", "generators.scene", "generators.engines",
            "surrogate.commands.train", "evaluation.commands.evaluate", "graphdem.cli"} <= set(top)
    list(graphlib.TopologicalSorter(top).static_order())          # raises CycleError on a circle
    full = {name: top[name] | local[name] for name in top}
    circles = {frozenset({a, b}) for a in full for b in local[a] if a in _reach(full, b)}
    assert circles == set()


@pytest.mark.engine
@pytest.mark.parametrize("scene", scenes.names())
def test_every_registered_scene_is_served_by_every_stage(tmp_path, scene):
    proc = subprocess.run([SNAKEMAKE, "-n", "-s", str(ROOT / "workflow" / "Snakefile"), "-d", str(tmp_path), "--config",
                           "scale=ci", "--", f"results/{scene}/metrics.csv"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    table = (proc.stdout + proc.stderr).split("Job stats:")[1].split("total")[0]
    jobs = {m[1]: int(m[2]) for m in re.finditer(r"^(\w+)\s+(\d+)\s*$", table, re.M)}
    assert set(STAGES) <= set(jobs), jobs
    from graphdem import cli
    for command in ("sweep", "prepare", "simulate", "dataset"):
        with pytest.raises(SystemExit) as exc:     # argparse accepts the scene, then stops at a missing argument
            cli.build_parser().parse_args([command, "--scene", scene])
        assert exc.value.code == 2



# Functions over the 80-line limit that are still to be split; the list may only shrink (a function that is no
# longer too long must leave it, a new one must not join it).
TOO_LONG: set[str] = set()
MAX_FUNCTION_LINES = 80


def test_no_function_is_longer_than_80_lines():
    long = set()
    for package in PACKAGES:
        for path in _python_files(package):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                        node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES:
                    long.add(f"{path.relative_to(ROOT)}:{node.name}")
    assert long - TOO_LONG == set(), "functions over 80 lines: split them"
    assert TOO_LONG - long == set(), "these are short now: take them off TOO_LONG"
