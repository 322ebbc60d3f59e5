import pytest

from swiptopt import auv


def test_defaults_give_the_hand_computed_powers():
    # 1/2 * 0.3 * 0.028 m^2 * 1025 kg/m^3 * (1.5 m/s)^3 / 0.5
    expected = 0.5 * 0.3 * 0.028 * 1025.0 * 1.5**3 / 0.5
    assert auv.propulsion_power_w(1.5) == pytest.approx(expected)
    assert expected == pytest.approx(29.05875)
    # the paper's eq. 17 divides the drag by beta (0.5 by default), so that P_prop = D v (eq. 18)
    assert auv.drag_force_n(1.5) == pytest.approx(0.5 * 0.3 * 0.028 * 1025.0 * 2.25 / 0.5)
    assert auv.drag_force_n(1.5) * 1.5 == pytest.approx(auv.propulsion_power_w(1.5))
    assert auv.drag_force_n(1.5, propulsion_efficiency=0.25) == pytest.approx(2 * auv.drag_force_n(1.5))


def test_move_and_hover_energy():
    p = auv.propulsion_power_w(1.5)
    # 10 m at 1.5 m/s: (29.05875 + 15) W * 6.667 s
    assert auv.move_energy_j(10.0, 1.5, p, 15.0) == pytest.approx(44.05875 * 10 / 1.5)
    assert auv.hover_energy_j(10 / 1.5, 15.0) == pytest.approx(100.0)
    assert auv.hover_energy_j(2.0, 15.0, station_keeping_power_w=5.0) == pytest.approx(40.0)


def test_power_grows_with_the_cube_of_speed():
    assert auv.propulsion_power_w(3.0) / auv.propulsion_power_w(1.5) == pytest.approx(8.0)


def test_current_changes_the_water_relative_speed():
    assert auv.water_relative_speed_mps((1.5, 0, 0), (0.5, 0, 0)) == pytest.approx(1.0)  # with the current
    assert auv.water_relative_speed_mps((1.5, 0, 0), (-0.5, 0, 0)) == pytest.approx(2.0)  # against it
    assert auv.water_relative_speed_mps((0, 0, 0), (0.3, 0.4, 0)) == pytest.approx(0.5)  # holding station
