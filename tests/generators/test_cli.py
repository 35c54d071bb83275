"""Outputs never overwrite inputs: every subcommand compares resolved paths before it reads or writes, including
the files inside its input folders and the sims its split tables list (generators/cli_paths.py)."""

import json
import os
from dataclasses import dataclass
from pathlib import Path

import pytest

from generators import cli as gcli
from generators import cli_paths
from graphdem import cli


def refused(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code not in (0, None)
    return str(exc.value.code) + capsys.readouterr().err


def test_evaluate_refuses_to_write_its_metrics_over_the_checkpoint(tmp_path, capsys, monkeypatch):
    checkpoint = tmp_path / "best.pt"
    checkpoint.write_bytes(b"weights")
    monkeypatch.chdir(tmp_path)
    os.mkdir("sub")
    for out in ("best.pt", "sub/../best.pt", str(checkpoint)):
        message = refused(["evaluate", "--checkpoint", "best.pt", "--data", "sims", "--history", "6", "--out", out],
                          capsys)
        assert f"--out {out} would overwrite the input --checkpoint best.pt" in message
    (tmp_path / "link.pt").symlink_to(checkpoint)
    assert "would overwrite the input --checkpoint" in refused(
        ["evaluate", "--checkpoint", "link.pt", "--data", "sims", "--history", "6", "--out", "best.pt"], capsys)
    assert checkpoint.read_bytes() == b"weights"


def test_a_rollout_folder_holding_the_sim_it_reads_is_refused(tmp_path, capsys):
    sim = tmp_path / "sims" / "slide_0000.h5"
    sim.parent.mkdir()
    sim.write_bytes(b"data")
    message = refused(["rollout", "--checkpoint", str(tmp_path / "best.pt"), "--data", str(sim),
                       "--out-dir", str(tmp_path / "sims")], capsys)
    assert "would overwrite the input --data" in message and "(held in that output folder)" in message
    assert sim.read_bytes() == b"data"


@pytest.mark.parametrize("argv", [
    ["convert", "--raw", "raw", "--out", "raw"],
    ["combine", "--tables", "a.csv", "b.csv", "--out", "b.csv"],
    ["crosscheck", "--combine", "a.csv", "--out", "a.csv"],
    ["transfer", "--same", "a.csv", "--other", "b.csv", "--trained-on", "lammps", "--other-engine", "yade",
     "--out", "a.csv"],
    ["import-solidgn", "data", "data"],
    ["physics", "--scene", "collapse", "--data", "a.h5", "--out", "out.csv", "--plot", "a.h5"],
    ["card", "--benchmark", "slide_small", "--seeds", "0", "--metrics", "m.csv", "--steps", "s.csv", "--histories",
     "h.csv", "--stats", "stats.json", "--article-json", "{}", "--out", "card.csv", "--markdown", "m.csv"],
])
def test_every_subcommand_refuses_an_output_that_is_an_input(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    assert "would overwrite the input" in refused(argv, capsys)
    assert list(tmp_path.iterdir()) == []


def test_the_physics_check_of_a_scene_without_one_is_refused_naming_those_with_one(tmp_path, capsys):
    code = cli.main(["physics", "--scene", "slide", "--data", str(tmp_path / "a.h5"), "--out",
                     str(tmp_path / "out.csv"), "--plot", str(tmp_path / "out.png")])
    err = capsys.readouterr().err
    assert code == 1 and "the slide scene has no physics check; scenes with one: collapse" in err
    assert not (tmp_path / "out.csv").exists()


def test_the_crosscheck_tolerance_defaults_to_the_configs():
    from generators import config
    args = cli.build_parser().parse_args(["crosscheck", "--combine", "a.csv", "--out", "b.csv"])
    assert args.tolerance == config.defaults()["crosscheck"]["tolerance"]


# --- every output option against every input it has: an attack per (output, input, way of reaching the input) ---

CASES = ("file", "file in an input folder", "sim in a split table")


@dataclass(frozen=True)
class Attack:
    """One subcommand run whose output option ``output`` names what its option ``input`` reads (``case``)."""

    command: str
    output: str
    input: str
    case: str
    argv: list[str]


def _value(action, base: Path) -> list[str]:
    """A valid value for an option that is not attacked (paths: fresh names under ``base``)."""
    count = 2 if action.nargs == 2 else 1
    if isinstance(action.type, cli_paths.PathType):
        return [str(base / f"given-{action.dest}-{i}") for i in range(count)]
    if action.choices:
        return [str(next(iter(action.choices)))] * count
    if action.type in (gcli.json_arg, json.loads):
        return ["{}"] * count
    return ["1"] * count


def _argv(parser, base: Path, attacked: dict) -> list[str]:
    """The subcommand's required options (one of each required group) and the ``attacked`` ones, with values."""
    wanted = [a for a in parser._actions if a.required or a.dest in attacked]
    for group in parser._mutually_exclusive_groups:
        if group.required and not any(a in wanted for a in group._group_actions):
            wanted.append(group._group_actions[0])
    positional = [v for a in wanted if not a.option_strings for v in attacked.get(a.dest) or _value(a, base)]
    optional = [x for a in wanted if a.option_strings
                for x in (a.option_strings[-1], *(attacked.get(a.dest) or _value(a, base)))]
    return positional + optional


def _target(base: Path, case: str, kind: cli_paths.PathType) -> tuple[str, Path, Path]:
    """Make the input of ``case`` under ``base``: the value the input option is given, the file it reads that way,
    and the path the output option is given (the file itself, or for a folder output the folder holding it)."""
    suffix = ".pvd" if kind.series else ".h5"
    if case == "file":
        value = read = base / "file" / f"input{suffix}"
    elif case == "file in an input folder":
        value, read = base / "in", base / "in" / "sub" / f"input{suffix}"
    else:
        value, read = base / "splits.csv", base / "sims" / f"slide_0000{suffix}"
        value.write_text(f"id,split,path\nslide_0000,test,{read}\n")
    read.parent.mkdir(parents=True, exist_ok=True)
    read.write_bytes(b"an input")
    return str(value), read, read.parent if kind.folder else read


def attacks(root: Path) -> list[Attack]:
    """Every subcommand's every output option pointed at each of its inputs: the input given as a file, as a folder
    holding the file (below a subfolder), and, for a split table, as a sim the table lists; each under its own
    folder of ``root``."""
    found = []
    for command, parser in cli.subcommands(cli.build_parser()).items():
        declared = cli_paths.declared(parser)
        for out, out_kind in ((a, k) for a, k in declared if k.writes):
            for inp, in_kind in ((a, k) for a, k in declared if not k.writes):
                for case in CASES[:3 if in_kind.table else 2]:
                    base = root / str(len(found))
                    base.mkdir()
                    value, _, target = _target(base, case, out_kind)
                    extra = [str(base / "other")] if inp.nargs == 2 else []
                    argv = _argv(parser, base, {out.dest: [str(target)], inp.dest: [value, *extra]})
                    found.append(Attack(command, cli_paths.option_name(out), cli_paths.option_name(inp), case,
                                        [command, *argv]))
    return found


def _tree(root: Path) -> dict[str, bytes | None]:
    return {str(p): (p.read_bytes() if p.is_file() else None) for p in sorted(root.rglob("*"))}


def test_every_output_option_of_every_subcommand_refuses_each_of_its_inputs(tmp_path, capsys, monkeypatch):
    """An output option pointed at an input (a file, a file in an input folder, a sim a split table lists) is
    refused naming both options, and nothing is written; the options come from the parser, so a new one is in."""
    found = attacks(tmp_path)
    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    before = _tree(tmp_path)
    missed = []
    for attack in found:
        with pytest.raises(SystemExit) as exc:
            cli.main(attack.argv)
        message = str(exc.value.code)
        if not (message.startswith(f"graphdem {attack.command}: {attack.output} ")
                and f"the input {attack.input} " in message):
            missed.append(f"{attack.case}: {' '.join(attack.argv)}: {message}")
    assert missed == []
    assert _tree(tmp_path) == before
    assert len(found) > 150 and {a.case for a in found} == set(CASES)
    assert {"--table-html", "--frames-out", "--substeps-plot", "--history", "--plots"} <= {a.output for a in found}


def test_trains_default_paths_are_checked_like_given_ones(tmp_path, capsys, monkeypatch):
    """`graphdem train --scene slide` writes results/slide/model/ by default: a --stats inside it is refused by
    name before training starts, and the defaults themselves pass."""
    monkeypatch.chdir(tmp_path)
    message = refused(["train", "--scene", "slide", "--stats", "results/slide/model/stats.json"], capsys)
    assert "--out-dir" in message and "--stats" in message
    args = cli.build_parser().parse_args(["train", "--scene", "slide"])
    args.complete(args)
    assert (args.stats, args.splits, args.out_dir) == (Path("results/slide/dataset/stats.json"),
                                                       Path("results/slide/dataset/splits.csv"),
                                                       Path("results/slide/model"))
