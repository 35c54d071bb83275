"""The installable package: a wheel built from this tree carries every file its packages open, and installed into a
fresh virtual environment, away from the checkout, it resolves and validates the config and runs `graphdem`;
pyproject.toml's ranges and constraints.txt's pins agree, and `make install` installs the pins."""

import argparse
import os
import shutil
import site
import subprocess
import sys
import tomllib
import zipfile
from email.parser import Parser
from importlib import metadata
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

from evaluation import evaluate
from generators import config, h5md, scenes
from graphdem import cli

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("generators", "surrogate", "evaluation", "graphdem")
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
EXTRAS = PROJECT["optional-dependencies"]


def _source_files() -> list[str]:
    """Every file of the packages in the source tree (modules, YAML defaults and schemas, the YADE script),
    relative to the root; bytecode caches left out."""
    return sorted(p.relative_to(ROOT).as_posix() for package in PACKAGES for p in (ROOT / package).rglob("*")
                  if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc")


def _pins() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, version = line.partition("==")
            assert version, f"constraints.txt: {line!r} is not an exact pin"
            pins[canonicalize_name(name)] = version
    return pins


def _run(cmd: list[str], **kwargs) -> subprocess.CompletedProcess:
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=300, **kwargs)
    assert out.returncode == 0, f"{cmd}: exit {out.returncode}\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}"
    return out


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    """The wheel built from a copy of this tree (an in-tree build would leave build/ behind, whose stale files a
    later wheel would carry), installed with --no-deps into a new venv that lies inside an unrelated git
    repository. Its dependencies come from this interpreter's site-packages, appended by a .pth path list after
    the venv's own: .pth files inside those folders are not processed, so an editable install of the checkout
    there stays invisible."""
    tmp = tmp_path_factory.mktemp("packaging")
    src, wheels, venv, cwd = tmp / "src", tmp / "wheels", tmp / "venv", tmp / "elsewhere"
    src.mkdir()
    cwd.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, src / name)
    for package in PACKAGES:
        shutil.copytree(ROOT / package, src / package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(wheels),
          str(src)])
    wheel, = wheels.glob("graphdem-*.whl")
    _run(["git", "init", "-q", str(tmp)])
    _run(["git", "-C", str(tmp), "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false",
          "commit", "-q", "--allow-empty", "-m", "unrelated"])
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    python = venv / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps", "-q", str(wheel)])
    purelib = _run([str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"]).stdout.strip()
    (Path(purelib) / "graphdem-test-deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    env = {"PATH": f"{venv / 'bin'}:/usr/bin:/bin", "HOME": str(tmp), "PYTHONNOUSERSITE": "1", "LC_ALL": "C.UTF-8"}
    return {"wheel": wheel, "venv": venv, "python": python, "purelib": Path(purelib), "cwd": cwd, "env": env}


def test_the_wheel_carries_every_file_of_the_packages_and_nothing_else(installed):
    with zipfile.ZipFile(installed["wheel"]) as whl:
        names = whl.namelist()
        entry_points = next(whl.read(n).decode() for n in names if n.endswith(".dist-info/entry_points.txt"))
        meta = Parser().parsestr(next(whl.read(n).decode() for n in names if n.endswith(".dist-info/METADATA")))
    expected = _source_files()
    assert {"generators/defaults/default.yaml", "generators/defaults/schema.yaml",
            "generators/yade/scripts/graphdem_yade.py"} <= set(expected)
    assert {f"generators/scenes/{s}{ext}" for s in scenes.names() for ext in (".yaml", ".schema.yaml")} <= set(expected)
    carried = {n for n in names if ".dist-info/" not in n}
    assert sorted(set(expected) - carried) == [] and sorted(carried - set(expected)) == []
    assert "graphdem = graphdem.cli:main" in entry_points
    assert meta["Version"] == h5md.CREATOR_VERSION            # the H5MD creator version is the package's
    declared = PROJECT["dependencies"] + [f'{r}; extra == "{extra}"' for extra, reqs in EXTRAS.items() for r in reqs]
    assert {str(Requirement(r)) for r in meta.get_all("Requires-Dist")} == {str(Requirement(r)) for r in declared}


def test_the_installed_wheel_is_the_code_imported_and_claims_no_commit_of_the_repository_around_it(installed):
    """The venv lies inside an unrelated git repository: its commit is not the code's."""
    code = ("import evaluation, generators, graphdem, surrogate; from evaluation import evaluate; "
            "print(generators.__file__, surrogate.__file__, evaluation.__file__, graphdem.__file__, "
            "evaluate.__file__); "
            "print(evaluate.code_version())")
    *where, version = _run([str(installed["python"]), "-c", code], cwd=installed["cwd"], env=installed["env"]
                           ).stdout.split()
    assert len(where) == 5 and all(Path(f).is_relative_to(installed["purelib"]) for f in where), where
    assert version == h5md.CREATOR_VERSION
    if (ROOT / ".git").exists():                                 # the checkout itself names its commit
        assert evaluate.code_version().startswith(f"{h5md.CREATOR_VERSION}+")


def test_the_installed_wheel_loads_the_config_and_runs_graphdem_outside_the_checkout(installed):
    graphdem, env, cwd = str(installed["venv"] / "bin" / "graphdem"), installed["env"], installed["cwd"]
    loaded = yaml.safe_load(_run([graphdem, "config"], cwd=cwd, env=env).stdout)
    assert set(scenes.names()) <= set(loaded) and loaded == config.load({})

    helped = _run([graphdem, "--help"], cwd=cwd, env=env).stdout
    assert _run([str(installed["python"]), "-m", "graphdem", "--help"], cwd=cwd, env=env).stdout == helped
    parser = cli.build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    assert {"config", "sweep", "simulate", "import-solidgn", "train", "evaluate"} <= set(commands)
    assert all(c in helped for c in commands)
    assert f"Scenes: {', '.join(scenes.names())}." in " ".join(helped.split())    # the wheel's registry is whole


def test_the_constraints_pin_every_dependency_inside_its_range():
    pins = _pins()
    for text in PROJECT["dependencies"] + [r for reqs in EXTRAS.values() for r in reqs]:
        req = Requirement(text)
        name = canonicalize_name(req.name)
        if name == "graphdem":                                    # an extra of its own (dev includes cluster)
            assert req.extras <= set(EXTRAS) and not req.specifier, text
            continue
        assert name in pins, f"constraints.txt lacks {req.name}"
        assert req.specifier.contains(pins[name]), f"{req.name}=={pins[name]} is outside {req.specifier}"
        assert len(req.specifier) and all(s.operator != "==" for s in req.specifier), f"{text}: not a range"


def test_the_constraints_are_closed_under_the_dependencies_of_the_pinned_versions():
    """For every pinned package installed here at its pin, what it requires is pinned too."""
    pins, missing, checked = _pins(), [], 0
    for name, version in pins.items():
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            continue
        if dist.version.split("+")[0] != version:
            continue
        checked += 1
        for text in dist.requires or []:
            req = Requirement(text)
            if req.marker is None or req.marker.evaluate({"extra": ""}):
                if canonicalize_name(req.name) not in pins:
                    missing.append(f"{name} needs {req}")
    assert checked >= len(PROJECT["dependencies"]) and missing == []


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_make_install_uses_the_constraints_and_reruns_when_they_change(tmp_path):
    for name in ("Makefile", "pyproject.toml", "constraints.txt"):
        shutil.copy2(ROOT / name, tmp_path / name)
    venv = tmp_path / ".venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(sys.executable)
    for stamp in (".graphdem-apt", ".graphdem-installed"):      # an up-to-date install
        (venv / stamp).touch()
        os.utime(venv / stamp, (2**31, 2**31))
    env = {**os.environ, "MAKEFLAGS": ""}
    assert "pip" not in _run(["make", "-n", "install"], cwd=tmp_path, env=env).stdout
    planned = _run(["make", "-n", "-W", "constraints.txt", "install"], cwd=tmp_path, env=env).stdout
    installs = [line for line in planned.splitlines() if " -m pip install" in line and "--upgrade pip" not in line]
    assert installs and all("-c constraints.txt" in line for line in installs)
    assert "torch" in installs[0] and "-e '.[dev]'" in installs[-1]


def test_the_license_and_citation_agree_with_the_package_metadata():
    assert PROJECT["license"] == "MIT" and PROJECT["license-files"] == ["LICENSE"]
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert citation["cff-version"] == "1.2.0" and citation["license"] == PROJECT["license"]
    assert citation["version"] == PROJECT["version"] and citation["title"].startswith(PROJECT["name"])
    article = citation["references"][0]
    assert (article["doi"], article["journal"], article["year"]) == ("10.3390/app151910432", "Applied Sciences", 2025)
