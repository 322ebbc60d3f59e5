"""Scenarios: one frozen, validated configuration of the network, the channel and the AUV.

A :class:`Scenario` holds every parameter of the model (docs/design.md, 'The model') as a flat
set of named fields (so presets, overrides, TOML files and ``gymnasium.make`` keyword
arguments all speak the same names). A wrong value fails at construction with a :class:`ScenarioError` that names the
field, the value and what is allowed; a grid too big to simulate (see :mod:`swiptopt.limits`)
fails before any cell is allocated. Node positions, initial charges and link failure
probabilities are drawn from ``layout_seed`` alone, so one scenario is one layout.

Coordinates: x along ``length_m``, y along ``width_m``, z is depth (0 at the surface,
growing downwards to ``depth_m``). The AUV sits at cell centres of a grid of
``cell_size_m`` cubes; cell (i, j, k) has its centre at ((i + 1/2) c, (j + 1/2) c, (k + 1/2) c).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from swiptopt.acoustics import THORP_VALID_KHZ
from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.limits import check_size
from swiptopt.tomlfile import read_toml
from swiptopt.validation import Spec, check_keys, check_value


class ScenarioError(ConfigError):
    """A scenario value is invalid; ``field`` names it (``None`` for file-level problems)."""


# --------------------------------------------------------------------------- obstacles


@dataclass(frozen=True)
class Box:
    """An axis-aligned box obstacle, corners in metres (x, y, depth)."""

    min_m: tuple[float, float, float]
    max_m: tuple[float, float, float]

    def contains(self, points_m: np.ndarray) -> np.ndarray:
        """Whether each point (..., 3) lies inside the closed box."""
        p = np.asarray(points_m, dtype=float)
        return np.all((p >= np.asarray(self.min_m)) & (p <= np.asarray(self.max_m)), axis=-1)


@dataclass(frozen=True)
class Sphere:
    """A spherical obstacle, centre (x, y, depth) and radius in metres."""

    center_m: tuple[float, float, float]
    radius_m: float

    def contains(self, points_m: np.ndarray) -> np.ndarray:
        """Whether each point (..., 3) lies inside the closed sphere."""
        d = np.asarray(points_m, dtype=float) - np.asarray(self.center_m)
        return np.einsum("...i,...i->...", d, d) <= self.radius_m**2


Obstacle = Box | Sphere

_OBSTACLE_KINDS: dict[str, type] = {"box": Box, "sphere": Sphere}


def _obstacle_from_mapping(index: int, raw: Any) -> Obstacle:
    where = f"obstacles[{index}]"
    if isinstance(raw, (Box, Sphere)):
        return raw
    if not isinstance(raw, Mapping):
        raise ScenarioError(f"{where} must be a table with a 'kind', got {raw!r}", "obstacles")
    data = dict(raw)
    kind = data.pop("kind", None)
    if kind not in _OBSTACLE_KINDS:
        raise ScenarioError(
            f"{where}.kind = {kind!r} is not allowed: must be one of {sorted(_OBSTACLE_KINDS)}",
            "obstacles",
        )
    cls = _OBSTACLE_KINDS[kind]
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ScenarioError(
            f"{where}: unknown key {unknown[0]!r} for a {kind}; allowed keys: {sorted(names)}",
            "obstacles",
        )
    missing = sorted(names - set(data))
    if missing:
        raise ScenarioError(f"{where}: a {kind} needs {missing[0]!r}", "obstacles")
    values = {}
    for name, value in data.items():
        if name.endswith("radius_m"):
            values[name] = _number(f"{where}.{name}", value, "obstacles")
        else:
            values[name] = _vector(f"{where}.{name}", value, 3, "obstacles")
    obstacle = cls(**values)
    if isinstance(obstacle, Box) and any(a >= b for a, b in zip(obstacle.min_m, obstacle.max_m)):
        raise ScenarioError(f"{where}: min_m must be below max_m on every axis", "obstacles")
    if isinstance(obstacle, Sphere) and not obstacle.radius_m > 0:
        raise ScenarioError(f"{where}.radius_m = {obstacle.radius_m} must be > 0", "obstacles")
    return obstacle


def _obstacle_to_mapping(obstacle: Obstacle) -> dict[str, Any]:
    kind = next(k for k, cls in _OBSTACLE_KINDS.items() if isinstance(obstacle, cls))
    out: dict[str, Any] = {"kind": kind}
    for f in dataclasses.fields(obstacle):
        value = getattr(obstacle, f.name)
        out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


# ----------------------------------------------------------------------- value checks


_ANY_NUMBER = Spec()


def _number(name: str, value: Any, field_name: str | None = None) -> float:
    return check_value(name, value, _ANY_NUMBER, field=field_name, error=ScenarioError)


def _vector(name: str, value: Any, length: int, field_name: str | None = None) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != length:
        raise ScenarioError(f"{name} = {value!r} must be a list of {length} numbers", field_name or name)
    return tuple(_number(name, v, field_name or name) for v in value)


def _field(default: Any, unit: str = "", doc: str = "", **spec: Any) -> Any:
    # kinds beyond validation's scalars: vector3 | cell | positions | heightmap | obstacles
    return field(default=default, metadata={"spec": Spec(unit=unit, doc=doc, **spec)})


#: The largest fleet a scenario may have.
MAX_AUVS = 16

CHANNELS = ("none", "shadowing", "rician")
#: The signalling technology of the AUV-node link (docs/links.md): the paper's acoustic link,
#: underwater optical (UWOC) or magnetic induction (MI).
TECHNOLOGIES = ("acoustic", "optical", "magnetic_induction")
#: Water types of the optical link, with their beam attenuation near 530 nm
#: (:data:`swiptopt.optical.WATER_ATTENUATION_PER_M`).
WATER_TYPES = ("pure_sea", "clear_ocean", "coastal", "turbid_harbour")
HARVESTERS = ("linear", "logistic")
#: Which signal carries the data: the AUV's, power-split at the node, or the
#: node's own transmission to the AUV (the paper's eq. 13, SNR with the node's power P_i).
LINKS = ("downlink_split", "uplink")

#: Node transmitter electrical power that gives Table I's "170 dB re 1 uPa @ 1 m"
#: at the default node efficiency 0.5: 10^((170 - 170.8) / 10) / 0.5 W (paper eq. 2).
TABLE1_NODE_POWER_W = 1.6635


# --------------------------------------------------------------------------- scenario


@dataclass(frozen=True)
class Scenario:
    """Every parameter of one network, channel and AUV; frozen and validated.

    Build with ``Scenario(...)``, :meth:`preset` or :meth:`from_toml`; change with
    :meth:`replace`. Field names carry their units.
    """

    name: str = _field("custom", doc="label shown in tables", kind="str")

    # volume and grid
    length_m: float = _field(100.0, "m", "extent along x", lo=0, lo_open=True, hi=100_000)
    width_m: float = _field(100.0, "m", "extent along y", lo=0, lo_open=True, hi=100_000)
    depth_m: float = _field(50.0, "m", "water depth (z grows downwards)", lo=0, lo_open=True, hi=11_000)
    cell_size_m: float = _field(10.0, "m", "grid cell edge; one AUV step", lo=0, lo_open=True, hi=10_000)

    # nodes
    n_nodes: int = _field(25, "", "number of sensor nodes", lo=1, hi=10_000, kind="int")
    layout_seed: int = _field(
        0, "", "seed of node positions, charges and failure rates", lo=0, hi=2**63 - 1, kind="int"
    )
    node_positions_m: tuple[tuple[float, float, float], ...] | None = _field(
        None, "m", "explicit node positions (x, y, depth); default uniform in the volume", kind="positions",
        optional=True,
    )
    data_bits: float = _field(1e5, "bit", "data each node holds to deliver", lo=0, lo_open=True, hi=1e12)
    storage_capacity_j: float = _field(1.0, "J", "node energy storage capacity", lo=0, lo_open=True, hi=1e9)
    initial_soc_min: float = _field(0.2, "", "lowest initial state of charge (fraction)", lo=0, hi=1)
    initial_soc_max: float = _field(0.8, "", "highest initial state of charge (fraction)", lo=0, hi=1)
    failure_prob_min: float = _field(0.05, "", "lowest per-step link failure probability", lo=0, hi=1)
    failure_prob_max: float = _field(0.25, "", "highest per-step link failure probability", lo=0, hi=1)
    idle_drain_w: float = _field(0.0, "W", "node idle power drain", lo=0, hi=1e3)
    energy_gate_j: float = _field(0.0, "J", "a node below this stored energy cannot transmit (0: off)", lo=0, hi=1e9)

    # acoustics (Section II-B)
    frequency_khz: float = _field(24.0, "kHz", "carrier frequency", lo=THORP_VALID_KHZ[0], hi=THORP_VALID_KHZ[1])
    band_min_khz: float = _field(22.0, "kHz", "lower band edge", lo=THORP_VALID_KHZ[0], hi=THORP_VALID_KHZ[1])
    band_max_khz: float = _field(26.0, "kHz", "upper band edge", lo=THORP_VALID_KHZ[0], hi=THORP_VALID_KHZ[1])
    spreading_k: float = _field(1.5, "", "spreading factor (1 cylindrical .. 2 spherical)", lo=1, hi=2)
    shipping: float = _field(0.0, "", "shipping activity factor", lo=0, hi=1)
    wind_mps: float = _field(10.0, "m/s", "wind speed", lo=0, hi=100)
    noise_integrated: bool = _field(False, "", "integrate the noise PSD over the band", kind="bool")
    electrical_power_w: float = _field(1000.0, "W", "projector electrical power", lo=0, lo_open=True, hi=1e6)
    electroacoustic_efficiency: float = _field(0.5, "", "projector efficiency eta_ea", lo=0, lo_open=True, hi=1)
    directivity_tx_db: float = _field(0.0, "dB", "projector directivity index", lo=0, hi=60)
    directivity_rx_db: float = _field(0.0, "dB", "node receiver directivity index", lo=0, hi=60)
    snr_threshold_db: float = _field(10.0, "dB", "minimum SNR for a link", lo=-50, hi=200)

    # which signal carries the data
    link: str = _field(
        "downlink_split", "", "data link: 'downlink_split' (the AUV's signal, split by alpha) or 'uplink' "
        "(each node transmits with its own power, paid from its storage)", kind="str", choices=LINKS,
    )
    node_transmit_power_w: float = _field(
        TABLE1_NODE_POWER_W, "W", "node transmitter electrical power P_i (uplink; default: 170 dB re 1 uPa @ 1 m)",
        lo=0, lo_open=True, hi=1e5,
    )
    node_electroacoustic_efficiency: float = _field(
        0.5, "", "node transmitter efficiency (uplink)", lo=0, lo_open=True, hi=1
    )
    node_circuit_power_w: float = _field(
        0.1, "W", "node circuit power while transmitting (uplink; Table I P_C)", lo=0, hi=1e4
    )
    packet_bits: float = _field(
        800.0, "bit", "uplink packet size: data moves in whole packets (Table I: 100 bytes)", lo=1, hi=1e9
    )

    # SWIPT at the node (Section II-C)
    sensitivity_db: float = _field(-170.0, "dB re 1 V/uPa", "hydrophone receive sensitivity", lo=-300, hi=0)
    load_ohm: float = _field(100.0, "ohm", "matched load resistance R_p", lo=0, lo_open=True, hi=1e9)
    n_elements: int = _field(1, "", "transducer elements per node", lo=1, hi=10_000, kind="int")
    harvester: str = _field("linear", "", "harvester model", kind="str", choices=HARVESTERS)
    harvest_efficiency: float = _field(0.5, "", "acousto-electric efficiency eta_ae (linear model)", lo=0, hi=1)
    logistic_max_w: float = _field(0.024, "W", "logistic harvester saturation M", lo=0, lo_open=True, hi=1e6)
    logistic_a_per_w: float = _field(150.0, "1/W", "logistic harvester steepness a", lo=0, lo_open=True, hi=1e9)
    logistic_b_w: float = _field(0.014, "W", "logistic harvester turning point b", lo=0, hi=1e6)

    # link technology (docs/links.md); the optical and MI fields matter only for theirs
    technology: str = _field(
        "acoustic", "", "link technology: 'acoustic' (the paper's), 'optical' (UWOC) or 'magnetic_induction'",
        kind="str", choices=TECHNOLOGIES,
    )
    water_type: str = _field(
        "clear_ocean", "", "optical: water type, for its beam attenuation near 530 nm (Petzold)", kind="str",
        choices=WATER_TYPES,
    )
    optical_power_w: float = _field(1.0, "W", "optical: light power the AUV's source emits", lo=0, lo_open=True, hi=1e4)
    optical_wallplug_efficiency: float = _field(
        0.3, "", "optical: electrical-to-optical efficiency of the source", lo=0, lo_open=True, hi=1
    )
    receiver_aperture_m2: float = _field(
        0.01, "m^2", "optical: the node's receiver aperture (photodiode and photovoltaic panel)", lo=0, lo_open=True,
        hi=10,
    )
    responsivity_a_per_w: float = _field(0.4, "A/W", "optical: photodiode responsivity", lo=0, lo_open=True, hi=10)
    dark_current_a: float = _field(1e-9, "A", "optical: photodiode dark current", lo=0, hi=1)
    background_irradiance_w_m2: float = _field(
        0.01, "W/m^2", "optical: ambient light on the receiver (depth and daylight)", lo=0, hi=2000
    )
    photodiode_load_ohm: float = _field(
        1000.0, "ohm", "optical: the receiver's load (its thermal noise)", lo=0, lo_open=True, hi=1e9
    )
    pv_efficiency: float = _field(
        0.15, "", "optical: photovoltaic conversion efficiency of the node's panel", lo=0, lo_open=True, hi=1
    )
    optical_bandwidth_hz: float = _field(1e6, "Hz", "optical: signal bandwidth", lo=1, hi=1e10)
    mi_frequency_khz: float = _field(10.0, "kHz", "MI: resonant frequency of the coils", lo=0.1, hi=10_000)
    coil_radius_m: float = _field(0.15, "m", "MI: radius of the AUV's and the nodes' coils", lo=0, lo_open=True, hi=10)
    coil_turns: int = _field(20, "", "MI: turns of each coil", lo=1, hi=100_000, kind="int")
    coil_wire_ohm_per_m: float = _field(
        0.017, "ohm/m", "MI: resistance of the coils' wire per metre", lo=0, lo_open=True, hi=100
    )
    seawater_conductivity_s_per_m: float = _field(
        4.0, "S/m", "MI: the water's conductivity (seawater about 4; fresh water about 0.01)", lo=0, lo_open=True,
        hi=100,
    )
    mi_transmit_power_w: float = _field(
        10.0, "W", "MI: power the AUV's driver delivers to its coil", lo=0, lo_open=True, hi=1e5
    )
    mi_noise_figure_db: float = _field(6.0, "dB", "MI: receiver noise figure", lo=0, hi=40)
    mi_bandwidth_hz: float = _field(2000.0, "Hz", "MI: signal bandwidth", lo=1, hi=1e7)

    # coverage cone
    cone_half_angle_deg: float = _field(
        30.0, "deg", "half-angle of the downward coverage cone", lo=0, lo_open=True, hi=90, hi_open=True
    )
    cone_range_m: float = _field(100.0, "m", "slant range limit of the cone", lo=0, lo_open=True, hi=1e6)

    # AUV (Section II-D)
    start_cell: tuple[int, int, int] | None = _field(
        None, "cell", "AUV start (i, j, k); default the surface cell at the centre", kind="cell", optional=True
    )
    speed_mps: float = _field(1.5, "m/s", "AUV cruise speed through the water", lo=0, lo_open=True, hi=20)
    drag_coefficient: float = _field(0.3, "", "drag coefficient C_D", lo=0, lo_open=True, hi=10)
    frontal_area_m2: float = _field(0.028, "m^2", "frontal area A", lo=0, lo_open=True, hi=100)
    water_density_kg_m3: float = _field(1025.0, "kg/m^3", "sea water density", lo=900, hi=1100)
    propulsion_efficiency: float = _field(0.5, "", "propulsive efficiency beta", lo=0, lo_open=True, hi=1)
    hotel_power_w: float = _field(15.0, "W", "hotel load H", lo=0, hi=1e5)
    station_keeping_power_w: float = _field(0.0, "W", "extra power to hold station", lo=0, hi=1e5)
    battery_j: float = _field(3.6e6, "J", "AUV battery energy (1 kWh)", lo=0, lo_open=True, hi=1e12)

    # fleet (docs/fleet.md): several AUVs on one network
    n_auvs: int = _field(1, "", "fleet: number of AUVs (1: the paper's single AUV)", lo=1, hi=MAX_AUVS, kind="int")
    auv_start_cells: tuple[tuple[int, int, int], ...] | None = _field(
        None, "cell", "fleet: each AUV's start (i, j, k); default spread along x across the surface", kind="cells",
        optional=True,
    )
    auv_batteries_j: tuple[float, ...] | None = _field(
        None, "J", "fleet: each AUV's battery energy; default battery_j for every AUV", kind="energies", optional=True
    )
    share_cells: bool = _field(False, "", "fleet: whether two AUVs may be in one cell", kind="bool")
    current_mps: tuple[float, float, float] = _field(
        (0.0, 0.0, 0.0), "m/s", "ocean current at the surface (x, y, z)", kind="vector3"
    )
    current_bottom_mps: tuple[float, float, float] | None = _field(
        None, "m/s", "current at the bottom; linear in depth between (default: uniform)", kind="vector3",
        optional=True,
    )

    # MDP (Section III)
    episode_steps: int = _field(50, "steps", "episode length", lo=1, hi=1_000_000, kind="int")
    reward_weight: float = _field(0.5, "", "Gamma: weight of data against energy in the reward", lo=0, hi=1)
    split_ratio: float = _field(0.5, "", "alpha: share of the signal sent to information decoding", lo=0, hi=1)
    movement_weight: float = _field(0.02, "", "lambda: weight of the AUV energy penalty", lo=0, hi=1e3)
    data_ref_bits: float | None = _field(
        None, "bit", "reward data reference (default data_bits)", lo=0, lo_open=True, hi=1e15, optional=True
    )
    energy_ref_j: float | None = _field(
        None, "J", "reward energy reference (default: one step at 10 m on axis)", lo=0, lo_open=True, hi=1e12,
        optional=True,
    )
    move_energy_ref_j: float | None = _field(
        None, "J", "reward move reference (default: one horizontal move)", lo=0, lo_open=True, hi=1e12, optional=True
    )
    target_fraction: float = _field(
        0.5, "", "fraction of collectable data/energy for the steps-to-target metrics", lo=0, lo_open=True, hi=1
    )
    channel: str = _field("shadowing", "", "stochastic channel", kind="str", choices=CHANNELS)
    shadowing_sigma_db: float = _field(3.0, "dB", "log-normal shadowing standard deviation", lo=0, hi=30)
    rician_k: float = _field(10.0, "", "Rician K factor (linear)", lo=0, hi=1e6)

    # obstacles
    obstacles: tuple[Obstacle, ...] = _field((), "", "boxes and spheres", kind="obstacles")
    seabed_height_m: tuple[tuple[float, ...], ...] | None = _field(
        None, "m", "seabed height above the bottom on a regular (x, y) grid, bilinear", kind="heightmap",
        optional=True,
    )

    # ------------------------------------------------------------------ validation

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            spec: Spec = f.metadata["spec"]
            object.__setattr__(self, f.name, _check_field(f.name, getattr(self, f.name), spec))
        self._check_relations()
        self._check_link()

    def _check_link(self) -> None:
        if self.technology != "acoustic" and self.link != "downlink_split":
            raise ScenarioError(
                f"link = {self.link!r} is modelled for the acoustic link only: with technology = "
                f"{self.technology!r} use link = 'downlink_split'", "link",
            )

    def _check_relations(self) -> None:
        for axis in ("length_m", "width_m", "depth_m"):
            ratio = getattr(self, axis) / self.cell_size_m
            if ratio < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
                raise ScenarioError(
                    f"{axis} = {getattr(self, axis):g} must be a whole multiple of cell_size_m = "
                    f"{self.cell_size_m:g}",
                    axis,
                )
        # sizes first: everything below may allocate per cell
        nx, ny, nz = self.grid_shape
        check_size(
            "max_cells", self.n_cells,
            f"grid cells at cell_size_m = {self.cell_size_m:g} ({nx:,} x {ny:,} x {nz:,})", "cell_size_m",
            ScenarioError,
        )
        check_size(
            "max_cell_node_pairs", self.n_cells * self.n_nodes,
            f"grid cells x nodes in the coverage tables ({self.n_cells:,} x n_nodes = {self.n_nodes:,})", "n_nodes",
            ScenarioError,
        )
        if not self.band_min_khz < self.frequency_khz < self.band_max_khz:
            raise ScenarioError(
                f"frequency_khz = {self.frequency_khz:g} must lie inside the band "
                f"(band_min_khz, band_max_khz) = ({self.band_min_khz:g}, {self.band_max_khz:g})",
                "frequency_khz",
            )
        for low, high in (("initial_soc_min", "initial_soc_max"), ("failure_prob_min", "failure_prob_max")):
            if getattr(self, low) > getattr(self, high):
                raise ScenarioError(
                    f"{low} = {getattr(self, low):g} must not exceed {high} = {getattr(self, high):g}", low
                )
        if self.node_positions_m is not None:
            if len(self.node_positions_m) != self.n_nodes:
                raise ScenarioError(
                    f"node_positions_m has {len(self.node_positions_m)} positions but n_nodes = {self.n_nodes}",
                    "node_positions_m",
                )
            p = np.asarray(self.node_positions_m)
            if np.any(p < 0) or np.any(p > self.extent_m):
                raise ScenarioError(
                    f"node_positions_m must lie inside the volume [0, {self.length_m:g}] x "
                    f"[0, {self.width_m:g}] x [0, {self.depth_m:g}] m",
                    "node_positions_m",
                )
        if self.start_cell is not None:
            if any(not 0 <= c < n for c, n in zip(self.start_cell, self.grid_shape)):
                raise ScenarioError(
                    f"start_cell = {self.start_cell} is outside the grid 0..{tuple(n - 1 for n in self.grid_shape)}",
                    "start_cell",
                )
        if self.seabed_height_m is not None:
            h = np.asarray(self.seabed_height_m)
            if h.shape[0] < 2 or h.shape[1] < 2:
                raise ScenarioError("seabed_height_m needs at least 2 x 2 values", "seabed_height_m")
            if np.any(h < 0) or np.any(h >= self.depth_m):
                raise ScenarioError(
                    f"seabed_height_m values must lie in [0, depth_m = {self.depth_m:g})", "seabed_height_m"
                )
        self._check_fleet()
        start = self.start_cell_index
        if self.blocked_cells[start]:
            raise ScenarioError(
                f"start_cell = {self.resolved_start_cell} lies inside an obstacle or below the seabed",
                "start_cell",
            )

    def _check_fleet(self) -> None:
        for name in ("auv_start_cells", "auv_batteries_j"):
            value = getattr(self, name)
            if value is not None and len(value) != self.n_auvs:
                raise ScenarioError(f"{name} has {len(value)} entries but n_auvs = {self.n_auvs}", name)
        if self.auv_start_cells is not None and self.start_cell is not None:
            raise ScenarioError("give start_cell (one AUV) or auv_start_cells (a fleet), not both", "auv_start_cells")
        if self.n_auvs > 1 and self.start_cell is not None:
            raise ScenarioError(
                f"start_cell is one AUV's start: with n_auvs = {self.n_auvs} give auv_start_cells instead",
                "start_cell",
            )
        cells = self.fleet_start_cells
        limit = tuple(n - 1 for n in self.grid_shape)
        for k, cell in enumerate(cells):
            if any(not 0 <= c < n for c, n in zip(cell, self.grid_shape)):
                raise ScenarioError(f"auv_start_cells[{k}] = {cell} is outside the grid 0..{limit}", "auv_start_cells")
            if self.n_auvs > 1 and self.blocked_cells[int(self.cell_index(cell))]:
                where = f"auv_start_cells[{k}] = {cell}" if self.auv_start_cells else f"AUV {k}'s default start {cell}"
                raise ScenarioError(f"{where} lies inside an obstacle or below the seabed", "auv_start_cells")
        if not self.share_cells and len(set(cells)) < len(cells):
            raise ScenarioError(
                f"auv_start_cells = {[list(c) for c in cells]} puts two AUVs in one cell: give each its own cell, "
                "or set share_cells = true", "auv_start_cells",
            )

    # ------------------------------------------------------------------ construction

    @classmethod
    def preset(cls, preset: str, /, **overrides: Any) -> Scenario:
        """A named preset (``paper``, ``paper-table1``, ``paper-optical``, ``paper-mi``,
        ``harbour``, ``tiny``) with field overrides.

        The scenario's ``name`` is the preset's unless ``name=`` gives a label of its own.
        """
        if not isinstance(preset, str) or preset not in PRESETS:
            raise ScenarioError(
                f"unknown preset {preset!r}{did_you_mean(preset, PRESETS)}: choose one of {sorted(PRESETS)}", "preset"
            )
        values = {"name": preset, **PRESETS[preset]}
        values.update(overrides)
        return cls.from_dict(values)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> Scenario:
        """Build from a mapping of field names; a ``preset`` key starts from that preset
        (and a ``name`` key labels the result, whether or not it starts from a preset)."""
        values = check_keys("a scenario", values, "scenario", ScenarioError)
        preset = values.pop("preset", None)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ScenarioError(f"unknown scenario key {unknown[0]!r}{did_you_mean(unknown[0], names)}", unknown[0])
        if preset is not None:
            if not isinstance(preset, str):
                raise ScenarioError(f"preset = {preset!r} must be a preset name", "preset")
            return cls.preset(preset, **values)
        return cls(**values)

    @classmethod
    def from_toml(cls, path: str | Path) -> Scenario:
        """Read a scenario file: top-level field names, optional ``preset``, ``[[obstacles]]``."""
        try:
            data = read_toml(path, "scenario")
        except ConfigError as exc:
            raise ScenarioError(str(exc)) from None
        try:
            return cls.from_dict(data)
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: {exc}", exc.field) from None

    def to_dict(self) -> dict[str, Any]:
        """Every field as plain TOML-compatible values (``None`` fields omitted, and the link
        technology's and the fleet's fields when they hold their defaults: a scenario that
        uses none of them reads, and hashes, as it did before they existed)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is None or (f.name in OPTIONAL_FIELDS and value == f.default):
                continue
            if f.name == "obstacles":
                value = [_obstacle_to_mapping(o) for o in value]
            elif isinstance(value, tuple):
                value = [list(v) if isinstance(v, tuple) else v for v in value]
            out[f.name] = value
        return out

    def to_toml(self, path: str | Path) -> None:
        """Write every field, so that :meth:`from_toml` gives back an equal scenario."""
        import tomli_w

        Path(path).write_text(tomli_w.dumps(self.to_dict()), encoding="utf-8")

    def replace(self, **changes: Any) -> Scenario:
        """A copy with some fields changed, validated like a new scenario."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise ScenarioError(f"unknown scenario key {unknown[0]!r}", unknown[0])
        return dataclasses.replace(self, **changes)

    @staticmethod
    def field_info() -> list[tuple[str, str, str]]:
        """(name, unit, description) of every field, in declaration order."""
        return [(f.name, f.metadata["spec"].unit, f.metadata["spec"].doc) for f in dataclasses.fields(Scenario)]

    # ------------------------------------------------------------------ geometry

    @property
    def extent_m(self) -> np.ndarray:
        """(length, width, depth) of the volume, m."""
        return np.array([self.length_m, self.width_m, self.depth_m])

    @property
    def grid_shape(self) -> tuple[int, int, int]:
        """Number of cells along x, y and depth."""
        return tuple(int(round(e / self.cell_size_m)) for e in self.extent_m)  # type: ignore[return-value]

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.grid_shape))

    @property
    def bandwidth_hz(self) -> float:
        """The signal bandwidth B of the scenario's link technology, Hz: the acoustic band
        (``band_max_khz - band_min_khz``), or the optical or MI bandwidth."""
        if self.technology == "optical":
            return float(self.optical_bandwidth_hz)
        if self.technology == "magnetic_induction":
            return float(self.mi_bandwidth_hz)
        return (self.band_max_khz - self.band_min_khz) * 1000.0

    @property
    def step_duration_s(self) -> float:
        """Duration of every step, cell size / AUV speed."""
        return self.cell_size_m / self.speed_mps

    @cached_property
    def cell_centers_m(self) -> np.ndarray:
        """Centres of all cells, (n_cells, 3), in the order of :meth:`cell_index`."""
        idx = np.indices(self.grid_shape).reshape(3, -1).T
        return (idx + 0.5) * self.cell_size_m

    def cell_index(self, cell: tuple[int, int, int] | np.ndarray) -> int | np.ndarray:
        """Flat index of cell (i, j, k) (C order over ``grid_shape``)."""
        return np.ravel_multi_index(tuple(np.asarray(cell).T), self.grid_shape)

    def cell_of_index(self, index: int | np.ndarray) -> np.ndarray:
        """(i, j, k) of flat cell indices."""
        return np.stack(np.unravel_index(index, self.grid_shape), axis=-1)

    @property
    def resolved_start_cell(self) -> tuple[int, int, int]:
        """The start cell; by default the surface cell at the centre of the area."""
        if self.start_cell is not None:
            return self.start_cell
        if self.auv_start_cells is not None:
            return self.auv_start_cells[0]
        nx, ny, _ = self.grid_shape
        return (nx // 2, ny // 2, 0)

    @property
    def start_cell_index(self) -> int:
        return int(self.cell_index(self.resolved_start_cell))

    @property
    def fleet_start_cells(self) -> tuple[tuple[int, int, int], ...]:
        """Each AUV's start cell: ``auv_start_cells``, else the single AUV's start
        (``n_auvs = 1``), else the surface cells at the centre line y = ny // 2 with x
        spread evenly, AUV k at x = (2k + 1) nx // (2 n_auvs)."""
        if self.auv_start_cells is not None:
            return self.auv_start_cells
        if self.n_auvs == 1:
            return (self.resolved_start_cell,)
        nx, ny, _ = self.grid_shape
        return tuple(((2 * k + 1) * nx // (2 * self.n_auvs), ny // 2, 0) for k in range(self.n_auvs))

    @property
    def fleet_batteries_j(self) -> tuple[float, ...]:
        """Each AUV's battery energy, J: ``auv_batteries_j``, else ``battery_j`` for each."""
        return self.auv_batteries_j if self.auv_batteries_j is not None else (self.battery_j,) * self.n_auvs

    def seabed_depth_m(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Depth of the seabed under (x, y), m (``depth_m`` where no height map is set)."""
        x_m, y_m = np.asarray(x_m, float), np.asarray(y_m, float)
        if self.seabed_height_m is None:
            return np.full(np.broadcast(x_m, y_m).shape, self.depth_m)
        h = np.asarray(self.seabed_height_m)
        gx = np.clip(x_m / self.length_m * (h.shape[0] - 1), 0, h.shape[0] - 1)
        gy = np.clip(y_m / self.width_m * (h.shape[1] - 1), 0, h.shape[1] - 1)
        i0 = np.minimum(np.floor(gx).astype(int), h.shape[0] - 2)
        j0 = np.minimum(np.floor(gy).astype(int), h.shape[1] - 2)
        tx, ty = gx - i0, gy - j0
        height = (
            h[i0, j0] * (1 - tx) * (1 - ty)
            + h[i0 + 1, j0] * tx * (1 - ty)
            + h[i0, j0 + 1] * (1 - tx) * ty
            + h[i0 + 1, j0 + 1] * tx * ty
        )
        return self.depth_m - height

    def is_blocked(self, points_m: np.ndarray) -> np.ndarray:
        """Whether points (..., 3) are inside an obstacle or below the seabed."""
        p = np.asarray(points_m, dtype=float)
        blocked = p[..., 2] > self.seabed_depth_m(p[..., 0], p[..., 1])
        for obstacle in self.obstacles:
            blocked |= obstacle.contains(p)
        return blocked

    @cached_property
    def blocked_cells(self) -> np.ndarray:
        """(n_cells,) bool: the cell centre is inside an obstacle or below the seabed."""
        return self.is_blocked(self.cell_centers_m)

    def current_at_mps(self, depth_m: np.ndarray) -> np.ndarray:
        """Current velocity (..., 3) at the given depths, linear between surface and bottom."""
        d = np.asarray(depth_m, dtype=float)[..., None]
        top = np.asarray(self.current_mps)
        bottom = top if self.current_bottom_mps is None else np.asarray(self.current_bottom_mps)
        return top + (bottom - top) * (d / self.depth_m)

    # ------------------------------------------------------------------ layout

    @cached_property
    def layout(self) -> NodeLayout:
        """The node layout drawn from ``layout_seed`` (or the explicit positions)."""
        pos_seq, soc_seq, fail_seq = np.random.SeedSequence(self.layout_seed).spawn(3)
        if self.node_positions_m is not None:
            positions = np.asarray(self.node_positions_m, dtype=float)
        else:
            positions = _uniform_free_points(self, self.n_nodes, np.random.default_rng(pos_seq))
        capacity = np.full(self.n_nodes, self.storage_capacity_j)
        soc = np.random.default_rng(soc_seq).uniform(self.initial_soc_min, self.initial_soc_max, self.n_nodes)
        fail = np.random.default_rng(fail_seq).uniform(self.failure_prob_min, self.failure_prob_max, self.n_nodes)
        return NodeLayout(
            positions_m=positions,
            data_bits=np.full(self.n_nodes, self.data_bits),
            capacity_j=capacity,
            initial_energy_j=soc * capacity,
            failure_prob=fail,
        )


@dataclass(frozen=True, eq=False)
class NodeLayout:
    """Per-node arrays of one scenario, all of shape (n_nodes,) or (n_nodes, 3)."""

    positions_m: np.ndarray
    data_bits: np.ndarray
    capacity_j: np.ndarray
    initial_energy_j: np.ndarray
    failure_prob: np.ndarray


def _uniform_free_points(scenario: Scenario, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform in the free water of the volume (rejection sampling)."""
    points = np.empty((0, 3))
    for _ in range(1000):
        batch = rng.uniform(0.0, 1.0, (max(2 * n, 16), 3)) * scenario.extent_m
        points = np.concatenate([points, batch[~scenario.is_blocked(batch)]])
        if len(points) >= n:
            return points[:n]
    raise ScenarioError("the obstacles leave no free water to place nodes in", "obstacles")


def _check_list(name: str, value: Any, spec: Spec) -> tuple[Any, ...]:
    """A field holding a list: of cells (one per AUV), of energies (one per AUV) or of positions."""
    if spec.kind == "positions":
        if not isinstance(value, (list, tuple, np.ndarray)):
            raise ScenarioError(f"{name} must be a list of (x, y, depth) triples", name)
        return tuple(_vector(name, p, 3) for p in value)
    what = "(i, j, k) cells" if spec.kind == "cells" else "energies in J"
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) == 0:
        raise ScenarioError(f"{name} must be a list of {what}, one per AUV", name)
    if spec.kind == "cells":
        return tuple(_check_field(name, cell, dataclasses.replace(spec, kind="cell")) for cell in value)
    each = dataclasses.replace(spec, kind="float", lo=0, lo_open=True, hi=1e12, optional=False)
    return tuple(
        float(check_value(f"{name}[{i}]", v, each, error=ScenarioError, field=name)) for i, v in enumerate(value)
    )


def _check_field(name: str, value: Any, spec: Spec) -> Any:
    kind = spec.kind
    if value is None:
        if spec.optional:
            return None
        raise ScenarioError(f"{name} must be set: {spec.doc}", name)
    if kind == "vector3":
        return _vector(name, value, 3)
    if kind == "cell":
        if (
            not isinstance(value, (list, tuple, np.ndarray))
            or len(value) != 3
            or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in value)
        ):
            raise ScenarioError(f"{name} = {value!r} must be three integers (i, j, k)", name)
        return tuple(int(v) for v in value)
    if kind in ("cells", "energies", "positions"):
        return _check_list(name, value, spec)
    if kind == "heightmap":
        # len(), not truth: a numpy array has no single truth value
        if not isinstance(value, (list, tuple, np.ndarray)) or len(value) == 0:
            raise ScenarioError(f"{name} must be a 2-D list of heights", name)
        rows = tuple(
            tuple(_number(name, v) for v in row) if isinstance(row, (list, tuple, np.ndarray)) else None
            for row in value
        )
        if any(r is None for r in rows) or len({len(r) for r in rows}) != 1:  # type: ignore[arg-type]
            raise ScenarioError(f"{name} must be a rectangular 2-D list of heights", name)
        return rows
    if kind == "obstacles":
        if not isinstance(value, (list, tuple)):
            raise ScenarioError(f"{name} must be a list of obstacle tables", name)
        return tuple(_obstacle_from_mapping(i, o) for i, o in enumerate(value))
    return check_value(name, value, spec, error=ScenarioError)


# ---------------------------------------------------------------------------- presets

#: The presets as overrides of the defaults above. ``paper`` is the paper's Table I where
#: that is consistent and the choices docs/paper-fidelity.md documents elsewhere;
#: ``harbour`` adds obstacles, a sloping seabed and a tidal current, where path planning
#: matters; ``tiny`` is a deterministic instance (no fading, no link failures, a wide beam)
#: small enough for an exact optimum.
#: The fields of the link technologies, which a scenario's dict holds only when they differ
#: from their defaults (:meth:`Scenario.to_dict`).
TECHNOLOGY_FIELDS = frozenset(
    f.name for f in dataclasses.fields(Scenario)
    if f.name == "technology" or f.metadata["spec"].doc.startswith(("optical:", "MI:"))
)

#: The fleet's fields, which a scenario's dict holds only when they differ from their defaults.
FLEET_FIELDS = frozenset(f.name for f in dataclasses.fields(Scenario) if f.metadata["spec"].doc.startswith("fleet:"))
OPTIONAL_FIELDS = TECHNOLOGY_FIELDS | FLEET_FIELDS

PRESETS: dict[str, dict[str, Any]] = {
    "paper": {},
    # Table I literally, where it gives a value; docs/paper-fidelity.md, 'Item by item' has
    # a row per entry. Its "transmit power 170 dB re 1 uPa @ 1 m" is the nodes' P_i of
    # eq. 13 (node_transmit_power_w's default gives it at efficiency 0.5) and the AUV
    # projector stays at the text's 1 kW (Section IV): at 170 dB the AUV would deliver 1/600
    # of the power and charge nothing within an episode. The noise comes from the noise
    # model (eqs. 5-8), not the table's unit-less "-50 dB". Packet 100 bytes, circuit 100
    # mW, 22-26 kHz around 24 kHz, k = 1.5, w = 10 m/s, s = 0, failures 0.05-0.25 are the
    # defaults already; the RL values of Table I are the tabular agents' defaults.
    "paper-table1": {
        "link": "uplink",
        "node_transmit_power_w": TABLE1_NODE_POWER_W,
        "node_electroacoustic_efficiency": 0.5,
        "node_circuit_power_w": 0.1,
        "packet_bits": 800.0,
        "frequency_khz": 24.0,
        "band_min_khz": 22.0,
        "band_max_khz": 26.0,
        "spreading_k": 1.5,
        "wind_mps": 10.0,
        "shipping": 0.0,
        "failure_prob_min": 0.05,
        "failure_prob_max": 0.25,
        "noise_integrated": True,
    },
    "harbour": {
        "length_m": 200.0,
        "width_m": 200.0,
        "depth_m": 40.0,
        "n_nodes": 20,
        "episode_steps": 120,
        "shipping": 0.8,
        "wind_mps": 5.0,
        "current_mps": (0.3, 0.1, 0.0),
        "current_bottom_mps": (0.1, 0.0, 0.0),
        "obstacles": (
            # a pier on pilings along one side, from the surface down to the bottom
            Box(min_m=(0.0, 90.0, 0.0), max_m=(60.0, 110.0, 40.0)),
            # a moored vessel's hull near the surface
            Box(min_m=(120.0, 40.0, 0.0), max_m=(160.0, 60.0, 8.0)),
            # a wreck on the bottom
            Sphere(center_m=(140.0, 150.0, 40.0), radius_m=15.0),
        ),
        # the seabed rises towards the quay at x = 0
        "seabed_height_m": ((12.0, 12.0, 12.0), (4.0, 4.0, 4.0), (0.0, 0.0, 0.0)),
    },
    # the paper preset's network served by the other link technologies (docs/links.md)
    "paper-optical": {"technology": "optical"},
    "paper-mi": {"technology": "magnetic_induction"},
    "tiny": {
        "length_m": 30.0,
        "width_m": 30.0,
        "depth_m": 20.0,
        "n_nodes": 3,
        "episode_steps": 8,
        # a wide-beam projector, so that most of the few nodes can be reached at all
        "cone_half_angle_deg": 60.0,
        "channel": "none",
        "failure_prob_min": 0.0,
        "failure_prob_max": 0.0,
    },
}
