"""The correction's timing table: both searches give the same corrected packings (no timing asserted)."""

from evaluation.timing import correction


def test_the_table_rows_find_deep_pairs_and_agree_to_rounding(capsys):
    correction.main(["--repeats", "1", "--iterations", "10", "--max-particles", "300"])
    rows = [line.split("|")[1:-1] for line in capsys.readouterr().out.splitlines() if line.startswith("| 2 ")]
    assert len(rows) == 1                                                 # the slide's size only
    dim, n, deep, every, listed, speedup, diff = (cell.strip() for cell in rows[0])
    assert (dim, n) == ("2", "265")
    assert int(deep) > 100                                                # the squeeze made many pairs too deep
    assert float(every) > 0 and float(listed) > 0 and float(speedup) > 0
    assert float(diff) < 1e-5                                             # unit diameters: the same pairs found
