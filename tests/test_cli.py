"""The `graphdem` command (graphdem/cli.py): its subcommands, each registered by its stage, all answer --help;
the console script and ``python -m graphdem`` (how torchrun starts the train stage) are the same command."""

import argparse
import inspect
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from generators import cli_paths
from graphdem import cli

ROOT = Path(__file__).resolve().parents[1]

# `graphdem --help`'s subcommands, in its order, when each stage came to register its own: none may go missing
SUBCOMMANDS = ("config", "sweep", "prepare", "simulate", "convert", "stability-dem", "restitution", "physics",
               "crosscheck", "transfer", "import-solidgn", "import", "export", "inspect", "dataset", "contacts",
               "train", "rollout", "evaluate", "combine", "seeds", "card", "property-sensitivity",
               "shear-stress-readout", "shear-stress-check", "stability-surrogate", "performance-dem",
               "performance-surrogate", "performance-report", "performance-pays", "publish", "tables")


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def test_the_registrars_add_every_subcommand_in_the_order_of_the_help():
    assert tuple(_subcommands(cli.build_parser())) == SUBCOMMANDS


def test_each_registrar_adds_its_own_subcommands():
    parser = argparse.ArgumentParser(prog="graphdem")
    sub = parser.add_subparsers(dest="command")
    seen = 0
    for register in cli.REGISTRARS:
        register(sub)
        assert len(sub.choices) > seen, f"{register.__module__}.{register.__name__} registers nothing"
        seen = len(sub.choices)
    assert seen == len(SUBCOMMANDS)


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_every_subcommand_answers_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([command, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: graphdem {command} ")
    assert callable(_subcommands(cli.build_parser())[command].get_default("func"))


def test_the_help_lists_every_subcommand(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--help"])
    assert exc.value.code == 0
    listed = re.findall(r"^    ([a-z][a-z-]*)", capsys.readouterr().out, re.M)
    assert tuple(listed) == SUBCOMMANDS


def test_every_subcommand_the_docs_name_is_registered():
    named = {m for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
             for m in re.findall(r"`graphdem ([a-z][a-z-]*)", path.read_text())}
    assert named and named <= set(SUBCOMMANDS)


def test_the_console_script_and_python_m_graphdem_are_one_command():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"graphdem": "graphdem.cli:main"}
    env = {"COLUMNS": "100", "PATH": "/usr/bin:/bin"}
    helped = subprocess.run([sys.executable, "-m", "graphdem", "--help"], capture_output=True, text=True, env=env,
                            cwd=ROOT)
    assert helped.returncode == 0 and helped.stdout.startswith("usage: graphdem [-h] COMMAND ...")


def test_an_unknown_subcommand_is_refused_with_the_list(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["no-such-command"])
    assert exc.value.code == 2
    assert "invalid choice: 'no-such-command'" in capsys.readouterr().err


def test_scene_options_take_scenes_only_and_a_public_benchmark_is_a_benchmark_option():
    """--scene names a registered scene in every subcommand; a public benchmark is --benchmark."""
    from generators import config, scenes
    for name, parser in _subcommands(cli.build_parser()).items():
        for action in parser._actions:
            if "--scene" in action.option_strings and action.choices is not None:
                assert set(action.choices) <= set(scenes.names()), name
    rest = {"dataset": ["--table", "t.csv", "--out-dir", "d", "--connectivity-radius", "1"], "train": []}
    for command, others in rest.items():
        parser = _subcommands(cli.build_parser())[command]
        for bench in config.BENCHMARKS:
            assert parser.parse_args(["--benchmark", bench, *others]).name == bench
        assert parser.parse_args(["--scene", "slide", *others]).name == "slide"
        for argv in (["--scene", "slide_samer"], ["--scene", "slide", "--benchmark", "slide_samer"]):
            with pytest.raises(SystemExit):
                parser.parse_args([*argv, *others])


def test_every_subcommand_is_described_by_its_run_functions_docstring():
    """`graphdem X --help` shows the docstring of the function X runs: one text, no second copy in code."""
    sub = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        run = parser.get_default("func")
        assert callable(run), name
        if name in ("card", "tables"):      # a multi-paragraph text of their own (RawDescriptionHelpFormatter)
            continue
        assert parser.description == inspect.getdoc(run), name
    assert "stable limit" in sub.choices["stability-dem"].format_help()


# a dest that names a path: an option with one and no type of its own takes a path (a str)
PATH_LIKE = re.compile(r"(^|_)(out|dir|dirs|path|paths|file|files|folder|plot|plots|html|csv|markdown|table|tables|"
                       r"root|results|checkpoint|data|splits|stats|raw|packing|packings|truth|readout|rollouts|"
                       r"ensemble|src|dest|trajectory|runs|histories|metrics|steps)($|_)")


def undeclared_path_options(parser: argparse.ArgumentParser) -> list[str]:
    """Every subcommand's options whose value is a path (type Path, or no type and a path-like dest) but whose type
    is not one of generators/cli_paths.py's: neither a declared output nor an input the output check compares."""
    found = []
    for name, sub in _subcommands(parser).items():
        for action in sub._actions:
            if action.nargs == 0 or isinstance(action.type, cli_paths.PathType):
                continue
            untyped = action.type in (None, str) and action.choices is None and PATH_LIKE.search(action.dest)
            if action.type is Path or untyped:
                found.append(f"{name} {cli_paths.option_name(action)}")
    return found


def test_every_path_option_of_every_subcommand_is_a_declared_output_or_input():
    """A new option that writes cannot escape the output check: its path must be declared (output_file,
    output_folder, ..., or input_path, split_table) where it is added."""
    parser = cli.build_parser()
    assert undeclared_path_options(parser) == []
    declared = {name: cli_paths.declared(sub) for name, sub in _subcommands(parser).items()}
    outputs = {f"{name} {cli_paths.option_name(a)}" for name, d in declared.items() for a, k in d if k.writes}
    assert {"evaluate --table-html", "stability-surrogate --frames-out", "performance-report --substeps-plot",
            "shear-stress-readout --history", "export --out", "import-solidgn DEST"} <= outputs
    assert all(declared[name] for name in SUBCOMMANDS)


def test_the_declaration_test_sees_an_undeclared_path_option():
    parser = cli.build_parser()
    rogue = _subcommands(parser)["seeds"]
    rogue.add_argument("--cache", type=Path)
    rogue.add_argument("--report-out")
    rogue.add_argument("--log-file", type=str)
    rogue.add_argument("--label")
    assert undeclared_path_options(parser) == ["seeds --cache", "seeds --report-out", "seeds --log-file"]
