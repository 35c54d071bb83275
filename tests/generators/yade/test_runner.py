"""YADE run headless: restitution of the contact law, and two jobs side by side without colliding."""

from concurrent.futures import ThreadPoolExecutor

import pytest

from generators.yade import shear as yade_shear

pytestmark = pytest.mark.engine


@pytest.mark.parametrize("restitution", [0.3, 0.5, 0.8])
def test_restitution_within_two_percent(tmp_path, restitution):
    measured, _ = yade_shear.collision(5.0e7, 0.004, restitution, 2650.0, 0.05, tmp_path)
    assert measured == pytest.approx(restitution, rel=0.02)


def test_two_jobs_side_by_side_close_their_servers_and_agree(tmp_path):
    """Both yade processes start their TCP prompt and XML-RPC server (on distinct ports); each closes
    them before it simulates anything, holds no listening socket during or after its run, and the
    concurrent runs give the same answer as each other."""
    dirs = [tmp_path / "a", tmp_path / "b"]
    for d in dirs:
        d.mkdir()
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda d: yade_shear.collision(5.0e7, 0.004, 0.5, 2650.0, 0.05, d), dirs))
    (e_a, run_a), (e_b, run_b) = results
    assert e_a == e_b
    for run in (run_a, run_b):
        assert run.report["servers_closed"] == 2
        assert run.report["listening_at_start"] == [] and run.report["listening_sockets"] == []
