"""`graphdem card` (evaluation/commands/card.py): one file per seed and no seed twice, checked before any file is
read, and the hardware a history.csv that does not record it is taken to have trained on."""

import pytest

from evaluation import card as card_module
from evaluation.commands import card
from surrogate import devices

from ...command_line import parse, run


def _argv(tmp_path, seeds, metrics, steps, histories, *extra):
    def files(name, n):
        return [str(tmp_path / f"{name}{i}.csv") for i in range(n)]

    return ["card", "--benchmark", "slide_samer", "--seeds", *map(str, seeds), "--metrics", *files("m", metrics),
            "--steps", *files("s", steps), "--histories", *files("h", histories), "--stats",
            str(tmp_path / "stats.json"), "--article-json", '{"history": 6}', "--out", str(tmp_path / "card.csv"),
            "--markdown", str(tmp_path / "card.md"), *extra]


@pytest.mark.parametrize("seeds, counts, message", [
    ([0, 1], (2, 1, 2), r"give one file per seed \(2 seeds: \[0, 1\]\); got 2 --metrics, 1 --steps, 2 --histories"),
    ([3, 3], (2, 2, 2), r"--seeds \[3, 3\] repeat a seed"),
])
def test_one_file_per_seed_and_no_seed_twice(tmp_path, seeds, counts, message):
    with pytest.raises(SystemExit, match=message):
        run(card.register, _argv(tmp_path, seeds, *counts))
    assert not (tmp_path / "card.csv").exists() and not (tmp_path / "card.md").exists()


def test_a_history_without_hardware_is_taken_to_have_trained_where_it_is_told(tmp_path):
    args = parse(card.register, _argv(tmp_path, [0], 1, 1, 1, "--device", "cpu", "--train-threads", "4"))
    cpu = devices.resolve("cpu")
    assert card._fallback(args) == card_module.Hardware(str(cpu), devices.name(cpu), 4, 1)
    assert card._fallback(parse(card.register, _argv(tmp_path, [0], 1, 1, 1))) is None     # else refused
