"""Outputs never overwrite inputs: every subcommand compares resolved paths before it reads or writes."""

import os

import pytest

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
    assert "would overwrite the input --data" in message and "(a file in that folder)" in message
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
