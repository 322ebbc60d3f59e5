"""A scenario rendered for the terminal as rich tables (``swiptopt scenario show``): its
parameters with units, derived quantities, the link budget at a few distances, the uplink
(when the scenario uses it) and the AUV's power. It reads the model only; printing is the
CLI's."""

from __future__ import annotations

import dataclasses

import numpy as np
from rich.table import Table

from swiptopt.link import (
    LinkBudget,
    auv_power,
    harvest_split,
    link_budget,
    magnetic_constants,
    node_source_level_db,
    optical_constants,
    reward_references,
    service_range_m,
    transmit_power_w,
    uplink_packet,
)
from swiptopt.scenario import Scenario

#: Distances of the link-budget table, m (short ones for the optical and MI links' reach).
BUDGET_DISTANCES_M = (2.0, 5.0, 10.0, 30.0, 50.0)


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, tuple) and value and dataclasses.is_dataclass(value[0]):
        return "; ".join(_fmt_obstacle(o) for o in value)
    if isinstance(value, tuple) and len(value) > 6:
        return f"{len(value)} rows"
    return str(value)


def _fmt_obstacle(obstacle: object) -> str:
    parts = ", ".join(f"{f.name}={getattr(obstacle, f.name)}" for f in dataclasses.fields(obstacle))
    return f"{type(obstacle).__name__.lower()}({parts})"


def scenario_tables(scenario: Scenario) -> list[Table]:
    """Parameters with units; derived quantities; the link budget; the uplink; the AUV's power."""
    budget = link_budget(scenario, np.asarray(BUDGET_DISTANCES_M))
    tables = [_parameters(scenario), _derived(scenario, budget), _link(scenario, budget)]
    if scenario.link == "uplink":
        tables.append(_uplink(scenario, budget))
    return [*tables, _auv(scenario)]


def _table(title: str, columns: tuple[str, ...], right_from: int = 1) -> Table:
    table = Table(title=title, title_justify="left")
    for i, column in enumerate(columns):
        table.add_column(column, justify="right" if i >= right_from else "left")
    return table


def _parameters(scenario: Scenario) -> Table:
    params = _table(f"Scenario '{scenario.name}'", ("parameter", "value", "unit", "meaning"))
    params.columns[2].justify = params.columns[3].justify = "left"
    for name, unit, doc in Scenario.field_info():
        value = getattr(scenario, name)
        params.add_row(name, "default" if value is None else _fmt(value), unit, doc)
    return params


def _derived(scenario: Scenario, budget: LinkBudget) -> Table:
    refs = reward_references(scenario)
    derived = _table("Derived", ("quantity", "value", "unit"))
    derived.columns[2].justify = "left"
    for label, value, unit in (
        ("grid (x, y, z cells)", " x ".join(map(str, scenario.grid_shape)), ""),
        ("start cell", str(scenario.resolved_start_cell), "cell"),
        ("blocked cells", str(int(scenario.blocked_cells.sum())), ""),
        ("step duration", f"{scenario.step_duration_s:.4g}", "s"),
        ("link technology", scenario.technology, ""),
        ("bandwidth", f"{scenario.bandwidth_hz:.6g}", "Hz"),
        *_technology_rows(scenario, budget),
        ("data link", scenario.link, ""),
        ("transmitter draw while serving", f"{transmit_power_w(scenario):.4g}", "W"),
        ("service range (cone or SNR)", f"{service_range_m(scenario):.4g}", "m"),
        ("reward data reference D_ref", f"{refs.data_ref_bits:.6g}", "bit"),
        ("reward energy reference E_ref", f"{refs.energy_ref_j:.6g}", "J"),
        ("reward move reference E_move_ref", f"{refs.move_energy_ref_j:.6g}", "J"),
    ):
        derived.add_row(label, value, unit)
    return derived


def _technology_rows(scenario: Scenario, budget: LinkBudget) -> list[tuple[str, str, str]]:
    """The derived quantities of the scenario's link technology."""
    if scenario.technology == "optical":
        k = optical_constants(scenario)
        return [("water type", scenario.water_type, ""),
                ("beam attenuation c", f"{k.attenuation_per_m:.4g}", "1/m"),
                ("aperture over beam solid angle A/Omega", f"{k.aperture_per_sr_m2:.4g}", "m^2/sr")]
    if scenario.technology == "magnetic_induction":
        k = magnetic_constants(scenario)
        return [("skin depth delta", f"{k.skin_depth_m:.4g}", "m"),
                ("receiver noise k T B F", f"{k.noise_w:.4g}", "W")]
    return [("source level SL", f"{budget.source_level_db:.2f}", "dB re 1 uPa @ 1 m"),
            ("noise level NL", f"{budget.noise_level_db:.2f}", "dB re 1 uPa"),
            ("node source level (uplink)", f"{node_source_level_db(scenario):.2f}", "dB re 1 uPa @ 1 m")]


def _link(scenario: Scenario, budget: LinkBudget) -> Table:
    title = (f"Link budget ({scenario.technology}, {scenario.link}, split ratio {harvest_split(scenario):g}, "
             "mean channel)")
    acoustic = scenario.technology == "acoustic"
    levels = ("TL (dB)", "RL (dB re 1 uPa)") if acoustic else ()
    link = _table(title, ("distance (m)", *levels, "SNR (dB)", "rate (kbit/s)", "available (mW)", "harvested (mW)"),
                  right_from=0)
    for i, d in enumerate(BUDGET_DISTANCES_M):
        levels_i = (budget.transmission_loss_db[i], budget.received_level_db[i]) if acoustic else ()
        level_cells = tuple(f"{x:.2f}" for x in levels_i)
        link.add_row(
            f"{d:g}",
            *level_cells,
            f"{budget.snr_db[i]:.2f}",
            f"{budget.rate_bps[i] / 1e3:.2f}",
            f"{budget.available_power_w[i] * 1e3:.4g}",
            f"{budget.harvested_power_w[i] * 1e3:.4g}",
        )
    return link


def _uplink(scenario: Scenario, budget: LinkBudget) -> Table:
    up = _table("Uplink (each node to the AUV, mean channel)", ("distance (m)", "SNR (dB)", "rate (kbit/s)",
                "packet on air (ms)", "packet (mJ)", "all data (J)"), right_from=0)
    sending = budget.uplink_rate_bps > 0
    packet = uplink_packet(scenario, np.where(sending, budget.uplink_rate_bps, 1.0))
    packets = np.ceil(scenario.data_bits / scenario.packet_bits)
    for i, d in enumerate(BUDGET_DISTANCES_M):
        cells = [f"{packet.airtime_s[i] * 1e3:.4g}", f"{packet.energy_j[i] * 1e3:.4g}",
                 f"{packets * packet.energy_j[i]:.4g}"]
        up.add_row(f"{d:g}", f"{budget.uplink_snr_db[i]:.2f}", f"{budget.uplink_rate_bps[i] / 1e3:.2f}",
                   *(cells if sending[i] else ["-"] * 3))
    return up


def _auv(scenario: Scenario) -> Table:
    power = auv_power(scenario)
    auv = _table("AUV power (still water)", ("quantity", "value", "unit"))
    auv.columns[2].justify = "left"
    for label, value, unit in (
        ("propulsion power", power.propulsion_w, "W"),
        ("hotel load", power.hotel_w, "W"),
        ("move power (propulsion + hotel)", power.propulsion_w + power.hotel_w, "W"),
        ("hover power", power.hover_energy_j / scenario.step_duration_s, "W"),
        ("projector power (while serving)", power.projector_w, "W"),
        ("energy of one move", power.move_energy_j, "J"),
        ("energy of one hover step", power.hover_energy_j, "J"),
        ("projector energy per step", power.projector_energy_j, "J"),
    ):
        auv.add_row(label, f"{value:.4g}", unit)
    return auv
