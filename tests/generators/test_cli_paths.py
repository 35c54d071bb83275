"""generators/cli_paths.py: the paths a subcommand declares it reads and writes, and the check before it runs
(every output option against every input: tests/generators/test_cli.py; every path option declared:
tests/test_cli.py)."""

import os

import pytest

from generators import cli_paths
from graphdem import cli


@pytest.fixture
def here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def refusal(argv, capsys) -> str:
    """The one-line refusal of ``argv`` (the subcommand never runs)."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert isinstance(exc.value.code, str), exc.value.code
    return exc.value.code


def passes(argv) -> None:
    """The check lets ``argv`` through (called directly: the subcommand itself is not run)."""
    parser = cli.build_parser()
    args = parser.parse_args(argv)
    cli_paths.check(cli.subcommands(parser)[args.command], args)


def files(root):
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_file_output_that_is_an_existing_folder_is_refused_by_name_and_the_folder_kept(here, capsys):
    (here / "model").mkdir()
    (here / "model" / "best.pt").write_bytes(b"weights")
    for option in ("--out", "--per-step", "--table-html"):
        argv = ["evaluate", "--checkpoint", "ckpt.pt", "--data", "sims", "--history", "6", "--out", "m.csv",
                option, "model"]
        message = refusal(argv if option != "--out" else argv[:-4] + ["--out", "model"], capsys)
        assert message == (f"graphdem evaluate: {option} model is an existing folder; a file is written there and "
                           "the folder would be deleted: give a file path")
    assert files(here) == {"model/best.pt": b"weights"}


def test_a_folder_output_that_is_an_existing_file_is_refused(here, capsys):
    (here / "notes.txt").write_text("mine")
    message = refusal(["rollout", "--checkpoint", "a.pt", "--data", "s.h5", "--out-dir", "notes.txt"], capsys)
    assert message == ("graphdem rollout: --out-dir notes.txt is an existing file; a folder is written there: give a "
                       "folder path")


def test_two_outputs_at_one_path_are_refused(here, capsys):
    message = refusal(["evaluate", "--checkpoint", "a.pt", "--data", "s.h5", "--history", "6", "--out", "m.csv",
                       "--per-step", "sub/../m.csv"], capsys)
    assert message == ("graphdem evaluate: --per-step sub/../m.csv and --out m.csv are one path; each output needs "
                       "its own")


def test_a_folder_written_whole_must_be_a_previous_output_of_the_command(here, capsys):
    model = here / "results" / "slide" / "model"
    model.mkdir(parents=True)
    (model / "best.pt").write_bytes(b"weights")
    argv = ["simulate", "--scene", "slide", "--sim", "{}", "--packing", "packing", "--out", str(model)]
    assert "is an existing folder that is not a previous output of this command (it would hold run.json)" in \
        refusal(argv, capsys)
    assert "(it would hold splits.csv)" in refusal(["import-solidgn", "solidgn", str(model)], capsys)
    series = ["export", "sim.h5", "--out", "results/slide/model.pvd"]
    assert refusal(series, capsys) == (
        "graphdem export: --out results/slide/model.pvd: its frames folder results/slide/model, is an existing folder "
        "that is not a previous output of this command (it would hold .vtu frames only); it would be replaced whole: "
        "give a new path")
    assert files(here) == {"results/slide/model/best.pt": b"weights"}
    (model / "best.pt").unlink()
    passes(series)                                  # an empty folder
    (model / "frame_000000.vtu").write_text("<VTKFile/>")
    passes(series)                                  # a previous export's frames
    (model / "run.json").write_text("{}")
    passes(argv)                                    # a previous simulate's raw folder


def test_an_export_whose_frames_folder_holds_its_input_is_refused(here, capsys):
    (here / "dem").mkdir()
    (here / "dem" / "sim.h5").write_bytes(b"sim")
    assert refusal(["export", "dem/sim.h5", "--out", "dem.pvd"], capsys) == (
        "graphdem export: --out dem.pvd (its frames folder dem) would overwrite the input TRAJECTORY dem/sim.h5 "
        "(held in that output folder); write the output elsewhere")


def test_a_symlink_in_an_input_folder_counts_as_its_target(here, capsys):
    (here / "real").mkdir()
    (here / "real" / "a.h5").write_bytes(b"sim")
    (here / "sims").mkdir()
    (here / "sims" / "a.h5").symlink_to(here / "real" / "a.h5")
    assert refusal(["evaluate", "--checkpoint", "c.pt", "--data", "sims", "--history", "6", "--out", "real/a.h5"],
                   capsys) == ("graphdem evaluate: --out real/a.h5 would overwrite the input --data sims (sims/a.h5 "
                               "in that folder); write the output elsewhere")
    assert (here / "real" / "a.h5").read_bytes() == b"sim"


def test_a_sim_a_split_table_lists_is_an_input(here, capsys):
    (here / "sims").mkdir()
    (here / "sims" / "a.h5").write_bytes(b"sim")
    (here / "splits.csv").write_text("id,split,path\na,test,sims/a.h5\n")
    assert refusal(["contacts", "--splits", "splits.csv", "--radius", "0.1", "--out", "sims/a.h5"], capsys) == (
        "graphdem contacts: --out sims/a.h5 would overwrite the input --splits splits.csv (the sim sims/a.h5 it "
        "lists); write the output elsewhere")


@pytest.mark.parametrize("table", [b"\xff\xfe\x00garbage", b"id,split\na,test\n", b"", None])
def test_a_split_table_that_cannot_be_read_adds_no_inputs_and_no_traceback(here, table):
    if table is not None:
        (here / "splits.csv").write_bytes(table)
    passes(["contacts", "--splits", "splits.csv", "--radius", "0.1", "--out", "out.csv"])


def test_outputs_beside_their_inputs_pass(here):
    """The workflow's layout: sims, model, dataset and plots side by side, a folder output that does not exist."""
    for name in ("sims/a.h5", "model/best.pt", "dataset/splits.csv"):
        (here / name).parent.mkdir(exist_ok=True)
        (here / name).write_bytes(b"x")
    (here / "dataset" / "splits.csv").write_text("id,split,path\na,test,sims/a.h5\n")
    passes(["evaluate", "--checkpoint", "model/best.pt", "--splits", "dataset/splits.csv", "--history", "6",
            "--out", "metrics.csv", "--per-step", "steps.csv", "--table-html", "metrics.html", "--plots", "plots"])
    passes(["rollout", "--checkpoint", "model/best.pt", "--data", "sims", "--out-dir", "rollouts"])
    os.mkdir(here / "rollouts")
    passes(["rollout", "--checkpoint", "model/best.pt", "--data", "sims/a.h5", "--out-dir", "rollouts"])


def test_a_path_type_reads_as_a_path_and_names_its_role():
    assert cli_paths.output_file("a/b.csv") == cli_paths.Path("a/b.csv")
    assert repr(cli_paths.run_folder) == "output folder holding run.json"
    assert cli_paths.split_table.table and not cli_paths.split_table.writes


def test_an_input_folder_counts_its_files_and_its_subfolders_files_only(here, capsys):
    """As deep as any subcommand reads (property-sensitivity's --runs: <run>/sims/<id>.h5), no deeper: a walk of
    everything below a folder such as / is not made."""
    deep = here / "runs" / "low" / "sims" / "a.h5"
    deep.parent.mkdir(parents=True)
    deep.write_bytes(b"sim")
    argv = ["property-sensitivity", "--checkpoint", "c.pt", "--runs", "runs/low", "high", "--sims", "a",
            "--property", "young", "--history", "6", "--out", "runs/low/sims/a.h5"]
    assert "would overwrite the input --runs runs/low (runs/low/sims/a.h5 in that folder)" in refusal(argv, capsys)
    passes([*argv[:4], "runs", *argv[5:]])          # runs/low/sims/a.h5 is two folders below runs: not read
