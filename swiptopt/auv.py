"""AUV energy: drag, propulsion power, and the energy of moving and hovering.

Paper eqs. 16-18; docs/design.md, 'The AUV (Section II-D)'. Defaults describe a REMUS-100-class vehicle:
cruise speed 1.5 m/s and hull diameter 0.19 m (so frontal area pi 0.095^2 = 0.028 m^2) are
the manufacturer's published figures; the drag coefficient 0.3, the propulsive efficiency
0.5 and the 15 W hotel load are typical values for small torpedo-shaped AUVs in the
AUV-energy literature. They are named assumptions, not measurements of one vehicle:
override them in the scenario for another vehicle.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

DEFAULT_SPEED_MPS = 1.5
DEFAULT_DRAG_COEFFICIENT = 0.3
DEFAULT_FRONTAL_AREA_M2 = 0.028
DEFAULT_WATER_DENSITY_KG_M3 = 1025.0
DEFAULT_PROPULSION_EFFICIENCY = 0.5
DEFAULT_HOTEL_POWER_W = 15.0


def drag_force_n(
    water_speed_mps: ArrayLike,
    drag_coefficient: float = DEFAULT_DRAG_COEFFICIENT,
    frontal_area_m2: float = DEFAULT_FRONTAL_AREA_M2,
    water_density_kg_m3: float = DEFAULT_WATER_DENSITY_KG_M3,
    propulsion_efficiency: float = DEFAULT_PROPULSION_EFFICIENCY,
) -> np.ndarray:
    """Drag as the paper writes it, D = 1/2 C_D A rho_w v^2 / beta, N (paper eq. 17).

    ``v`` is relative to the water. The paper folds the motor's conversion factor beta into
    the drag so that the propulsion power is simply D v (eqs. 16, 18); the hydrodynamic force
    alone is this value times beta.
    """
    v = np.asarray(water_speed_mps, dtype=float)
    return 0.5 * drag_coefficient * frontal_area_m2 * water_density_kg_m3 * v**2 / propulsion_efficiency


def propulsion_power_w(
    water_speed_mps: ArrayLike,
    drag_coefficient: float = DEFAULT_DRAG_COEFFICIENT,
    frontal_area_m2: float = DEFAULT_FRONTAL_AREA_M2,
    water_density_kg_m3: float = DEFAULT_WATER_DENSITY_KG_M3,
    propulsion_efficiency: float = DEFAULT_PROPULSION_EFFICIENCY,
) -> np.ndarray:
    """Electrical propulsion power P_prop = D v = 1/2 C_D A rho_w v^3 / beta, W (paper eqs. 16, 18)."""
    v = np.abs(np.asarray(water_speed_mps, dtype=float))
    return drag_force_n(v, drag_coefficient, frontal_area_m2, water_density_kg_m3, propulsion_efficiency) * v


def water_relative_speed_mps(
    ground_velocity_mps: ArrayLike, current_mps: ArrayLike = (0.0, 0.0, 0.0)
) -> np.ndarray:
    """Speed through the water needed to hold a ground velocity in a current, m/s.

    ``ground_velocity_mps`` and ``current_mps``: (..., 3); the result has shape (...).
    """
    rel = np.asarray(ground_velocity_mps, dtype=float) - np.asarray(current_mps, dtype=float)
    return np.linalg.norm(rel, axis=-1)


def move_energy_j(
    distance_m: ArrayLike,
    speed_mps: ArrayLike,
    propulsion_power_w: ArrayLike,
    hotel_power_w: ArrayLike = DEFAULT_HOTEL_POWER_W,
) -> np.ndarray:
    """Energy of a move, (P_prop + H) d / v, J (paper eq. 16 with Section II-D's E = P d / v)."""
    return (np.asarray(propulsion_power_w, float) + np.asarray(hotel_power_w, float)) * (
        np.asarray(distance_m, float) / np.asarray(speed_mps, float)
    )


def hover_energy_j(
    duration_s: ArrayLike,
    hotel_power_w: ArrayLike = DEFAULT_HOTEL_POWER_W,
    station_keeping_power_w: ArrayLike = 0.0,
) -> np.ndarray:
    """Energy of holding station for ``duration_s``, (H + P_station) dt, J."""
    return (np.asarray(hotel_power_w, float) + np.asarray(station_keeping_power_w, float)) * np.asarray(
        duration_s, float
    )
