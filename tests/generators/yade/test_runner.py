"""YADE run headless: two jobs side by side close their servers, hold no listening socket, and agree."""

from concurrent.futures import ThreadPoolExecutor

import pytest

from generators import collision, contact, dem
from generators.yade import driver

pytestmark = pytest.mark.engine


def test_two_jobs_side_by_side_close_their_servers_and_agree(tmp_path):
    """Both yade processes start their TCP prompt and XML-RPC server (on distinct ports); each closes
    them before it simulates anything, holds no listening socket during or after its run, and the
    concurrent runs give the same answer as each other."""
    c = dem.Contact(young=5.0e7, kn=2.0e5, kt_over_kn=0.3, restitution=0.5, friction=0.5)
    setup = collision.collision_setup(c, 0.004, 2650.0, 3, 0.05 * contact.stable_time_step(
        contact.sphere_mass(2650.0, 0.004), c.kn), 0.05)
    dirs = [tmp_path / "a", tmp_path / "b"]
    for d in dirs:
        d.mkdir()
    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(lambda d: driver.record(setup, d), dirs))
    (frames_a, run_a), (frames_b, run_b) = results
    assert (frames_a.position == frames_b.position).all()
    for run in (run_a, run_b):
        assert run.notes["servers_closed"] == 2
        assert run.notes["listening_sockets"] == []
