import math

import pytest

from generators import contact


@pytest.mark.parametrize("e", [0.1, 0.3, 0.5, 0.8, 0.99])
def test_damping_ratio_inverts_restitution(e):
    assert contact.restitution_of(contact.damping_ratio(e)) == pytest.approx(e, rel=1e-12)


@pytest.mark.parametrize("e", [0.2, 0.5, 0.9])
def test_tsuji_input_gives_the_linear_contact_damping(e):
    # LAMMPS applies zeta = alpha(e_input) / 2 on a hooke contact
    alpha = contact.tsuji_alpha(contact.lammps_tsuji_input(e))
    assert alpha / 2 == pytest.approx(contact.damping_ratio(e), rel=1e-9)


def test_lammps_asking_for_half_gives_0p58_as_documented():
    zeta = contact.tsuji_alpha(0.5) / 2
    assert contact.restitution_of(zeta) == pytest.approx(0.581, abs=1e-3)


def test_stable_step_is_verlet_limit_of_lightest_pair():
    m, k = 2.0, 50.0
    assert contact.stable_time_step(m, k) == pytest.approx(2 / math.sqrt(2 * k / m))


def test_step_above_limit_is_refused_with_both_numbers():
    with pytest.raises(contact.UnstableTimeStep) as err:
        contact.choose_time_step(1e-3, 0.1, 2.5e-3, "sim slide_0007")
    msg = str(err.value)
    assert "slide_0007" in msg and "0.0025" in msg and "0.001" in msg
    assert contact.choose_time_step(1e-3, 0.1, None, "x") == pytest.approx(1e-4)
    assert contact.choose_time_step(1e-3, 0.1, 5e-4, "x") == 5e-4
