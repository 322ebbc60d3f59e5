# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # The acoustic channel, energy harvesting and coverage
#
# The physics of the shared model (the paper's Section II), straight from the library functions the
# simulator uses:
#
# 1. the link budget against distance and carrier frequency: transmission loss
#    (Thorp absorption and spreading), ambient noise (Stojanovic's four-part model),
#    SNR from the passive sonar equation, and the Shannon rate;
# 2. Stojanovic's AN-optimal carrier frequency against distance;
# 3. the power a node harvests against distance, for the linear and the logistic
#    (Boshkovska) harvester;
# 4. the paper's coverage analysis (eqs. 24-25): the probability of covering at
#    least k of n uniformly placed nodes, analytic (binomial) against simulated, as a
#    function of the AUV's start position.
#
# Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).

# %%
import os

QUICK = os.environ.get("SWIPTOPT_NOTEBOOK_QUICK", "0") == "1"
SEED = 0
N_DISTANCES = 60 if QUICK else 300  # points of each distance axis
N_FREQUENCIES = 40 if QUICK else 200  # points of each frequency axis
COVERAGE_POSITIONS = 7 if QUICK else 19  # AUV positions along the centre line
COVERAGE_MAP_CELLS = 5 if QUICK else 10  # surface positions per side of the coverage map
COVERAGE_TRIALS = 300 if QUICK else 3000  # node layouts per simulated probability
COVERAGE_SAMPLES = 20_000 if QUICK else 200_000  # Monte Carlo points of a clipped cone

# %matplotlib inline
import matplotlib.pyplot as plt
import numpy as np

from swiptopt import Scenario, acoustics, harvesting
from swiptopt.coverage import (
    analytic_coverage_probability,
    binomial_at_least,
    coverage_fraction,
    simulated_coverage_probability,
)
from swiptopt.link import link_budget, reward_references, service_range_m

plt.rcParams.update({"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3})
scenario = Scenario.preset("paper")
print(f"quick settings: {QUICK}")

# %% [markdown]
# ## 1. The link budget
#
# The `paper` preset: a 1 kW projector (η = 0.5) at 24 kHz with a 4 kHz band,
# spreading factor k = 1.5, wind 10 m/s, no shipping. `link_budget` combines the
# equations for a scenario at any array of distances.

# %%
at_10m = link_budget(scenario, 10.0)
refs = reward_references(scenario)
print(f"source level SL      = {at_10m.source_level_db:7.1f} dB re 1 uPa @ 1 m")
print(f"noise level NL       = {at_10m.noise_level_db:7.1f} dB re 1 uPa over {scenario.bandwidth_hz / 1e3:.0f} kHz")
print(f"SNR at 10 m          = {float(at_10m.snr_db):7.1f} dB (threshold {scenario.snr_threshold_db:.0f} dB)")
print(f"rate at 10 m         = {float(at_10m.rate_bps) / 1e3:7.1f} kbit/s with split ratio {scenario.split_ratio}")
print(f"harvested at 10 m    = {float(at_10m.harvested_power_w) * 1e3:7.2f} mW")
print(f"service range        = {service_range_m(scenario):7.1f} m (cone range {scenario.cone_range_m:.0f} m)")
print(f"reward references    : D_ref = {refs.data_ref_bits:.0f} bit, E_ref = {refs.energy_ref_j * 1e3:.1f} mJ, "
      f"E_move_ref = {refs.move_energy_ref_j:.0f} J")

# %%
distances_m = np.geomspace(1.0, 5000.0, N_DISTANCES)
carriers_khz = (5.0, 12.0, 24.0, 50.0, 100.0)
half_band_khz = scenario.bandwidth_hz / 2000.0

fig, axes = plt.subplots(2, 2, figsize=(11, 8))
ax_tl, ax_noise, ax_snr, ax_rate = axes.ravel()
for f_khz in carriers_khz:
    # the same 4 kHz band, centred on each carrier
    at_f = scenario.replace(frequency_khz=f_khz, band_min_khz=f_khz - half_band_khz, band_max_khz=f_khz + half_band_khz)
    budget = link_budget(at_f, distances_m)
    label = f"{f_khz:g} kHz"
    ax_tl.plot(distances_m, budget.transmission_loss_db, label=label)
    ax_snr.plot(distances_m, budget.snr_db, label=label)
    ax_rate.plot(distances_m, budget.rate_bps / 1e3, label=label)
ax_snr.axhline(scenario.snr_threshold_db, color="k", ls=":", lw=1, label="SNR threshold")
for ax in (ax_tl, ax_snr, ax_rate):
    ax.set_xscale("log")
    ax.set_xlabel("distance AUV to node (m)")
    ax.legend(fontsize=8)
ax_tl.set_ylabel("transmission loss TL (dB)")
ax_tl.set_title("spreading + Thorp absorption")
ax_snr.set_ylabel("SNR (dB)")
ax_snr.set_title("passive sonar equation SL - TL - NL")
ax_rate.set_ylabel("information rate (kbit/s)")
ax_rate.set_title(f"Shannon rate, split ratio alpha = {scenario.split_ratio}")

freqs_khz = np.geomspace(0.1, 1000.0, N_FREQUENCIES)
parts = {
    "turbulence": acoustics.turbulence_noise_psd_db(freqs_khz),
    "shipping": acoustics.shipping_noise_psd_db(freqs_khz, scenario.shipping),
    "wind": acoustics.wind_noise_psd_db(freqs_khz, scenario.wind_mps),
    "thermal": acoustics.thermal_noise_psd_db(freqs_khz),
}
for name, psd in parts.items():
    ax_noise.plot(freqs_khz, psd, lw=1, ls="--", label=name)
ax_noise.plot(freqs_khz, acoustics.noise_psd_db(freqs_khz, scenario.shipping, scenario.wind_mps), "k", label="total")
ax_noise.axvline(scenario.frequency_khz, color="0.5", lw=1, label="carrier")
ax_noise.set_xscale("log")
ax_noise.set_ylim(-20, 120)
ax_noise.set_xlabel("frequency (kHz)")
ax_noise.set_ylabel("noise PSD (dB re 1 uPa^2/Hz)")
ax_noise.set_title(f"ambient noise, wind {scenario.wind_mps:g} m/s, shipping {scenario.shipping:g}")
ax_noise.legend(fontsize=8)
fig.tight_layout()

# %% [markdown]
# ## 2. The AN-optimal frequency
#
# For a narrow band at distance l the SNR is SL − A(l, f) N(f): the frequency that
# minimises the AN product maximises it (Stojanovic 2007). Absorption grows with both
# distance and frequency, so the optimum falls with distance. Left: the narrowband
# SNR per Hz over distance and frequency with the optimum overlaid; right: the optimum
# for a few wind speeds.
#
# Beyond some tens of kilometres in wind the global optimum jumps to the lower end of
# Thorp's range (0.1 kHz): below 0.4 kHz the model's wind-noise term falls again, so
# the AN product has a second minimum there. That is a property of the empirical noise
# model at frequencies it was not meant for, not a recommendation to signal at 100 Hz.

# %%
far_m = np.geomspace(10.0, 100_000.0, N_DISTANCES)
grid_khz = np.geomspace(0.1, 500.0, N_FREQUENCIES)
an_db = acoustics.an_product_db(
    far_m[:, None], grid_khz[None, :], scenario.spreading_k, scenario.shipping, scenario.wind_mps
)
narrowband_snr_db = at_10m.source_level_db - an_db  # SNR in a 1 Hz band
best_khz = acoustics.optimal_frequency_khz(far_m, scenario.spreading_k, scenario.shipping, scenario.wind_mps)

# the golden-section optimum agrees with the grid's best frequency
grid_best = grid_khz[np.argmin(an_db, axis=1)]
inside = (best_khz > grid_khz[1]) & (best_khz < grid_khz[-2])
ratio = grid_best[inside] / best_khz[inside]
print(f"grid optimum / golden-section optimum: {ratio.min():.3f} .. {ratio.max():.3f} "
      f"(grid step {grid_khz[1] / grid_khz[0]:.3f})")

fig, (ax_map, ax_opt) = plt.subplots(1, 2, figsize=(12, 4.5))
# far and high, absorption reaches thousands of dB: clip the colours to the useful range
mesh = ax_map.pcolormesh(far_m / 1e3, grid_khz, narrowband_snr_db.T, shading="auto", cmap="viridis",
                         vmin=0.0, vmax=float(narrowband_snr_db.max()))
ax_map.plot(far_m / 1e3, best_khz, "w-", lw=2, label="AN-optimal frequency")
ax_map.set_xscale("log")
ax_map.set_yscale("log")
ax_map.set_xlabel("distance (km)")
ax_map.set_ylabel("frequency (kHz)")
ax_map.legend(loc="lower left", fontsize=8)
fig.colorbar(mesh, ax=ax_map, extend="min", label="narrowband SNR, SL - AN (dB re 1 Hz)")

for wind in (0.0, 5.0, 10.0, 20.0):
    ax_opt.plot(far_m / 1e3, acoustics.optimal_frequency_khz(far_m, scenario.spreading_k, scenario.shipping, wind),
                label=f"wind {wind:g} m/s")
ax_opt.plot(far_m / 1e3, acoustics.optimal_frequency_khz(far_m, scenario.spreading_k, 1.0, 10.0), "k--",
            label="wind 10 m/s, heavy shipping")
ax_opt.set_xscale("log")
ax_opt.set_yscale("log")
ax_opt.set_xlabel("distance (km)")
ax_opt.set_ylabel("AN-optimal frequency (kHz)")
ax_opt.legend(fontsize=8)
fig.tight_layout()

# %% [markdown]
# ## 3. Harvested power
#
# The node's hydrophone turns the received level into a voltage, V = 10^((RL + ρ)/20),
# and a matched load gets P_av = V² / (4 R_p). A share 1 − α goes to the harvester:
# linear (P_h = η (1 − α) P_av) or the logistic curve of Boshkovska et al., which
# saturates at M = 24 mW and yields little below its turning point b = 14 mW. Left:
# the two curves against their input power; right: what each delivers against
# distance for three split ratios.

# %%
p_in_w = np.geomspace(1e-5, 1.0, N_DISTANCES)
near_m = np.geomspace(1.0, 200.0, N_DISTANCES)
fig, (ax_curve, ax_dist) = plt.subplots(1, 2, figsize=(12, 4.5))
for model, style in (("linear", "-"), ("logistic", "--")):
    out = harvesting.harvested_power_w(p_in_w, 0.0, scenario.harvest_efficiency, model)
    ax_curve.plot(p_in_w * 1e3, out * 1e3, style, label=model)
ax_curve.plot(p_in_w * 1e3, p_in_w * 1e3, ":", color="0.5", label="input power (upper limit)")
ax_curve.set_xscale("log")
ax_curve.set_yscale("log")
ax_curve.set_ylim(1e-4, 1e3)
ax_curve.set_xlabel("power into the harvester (mW)")
ax_curve.set_ylabel("harvested DC power (mW)")
ax_curve.set_title(f"harvester curves (linear efficiency {scenario.harvest_efficiency:g})")
ax_curve.legend(fontsize=8)

colours = dict(zip((0.2, 0.5, 0.8), ("tab:blue", "tab:orange", "tab:green")))
for model, style in (("linear", "-"), ("logistic", "--")):
    for alpha, colour in colours.items():
        budget = link_budget(scenario.replace(harvester=model), near_m, split_ratio=alpha)
        ax_dist.plot(near_m, budget.harvested_power_w * 1e3, style, color=colour, label=f"{model}, alpha = {alpha}")
ax_dist.plot(near_m, link_budget(scenario, near_m).available_power_w * 1e3, ":", color="0.4", label="available P_av")
ax_dist.axvline(scenario.cone_range_m, color="k", lw=1, ls="-.", label="cone range")
ax_dist.set_xscale("log")
ax_dist.set_yscale("log")
ax_dist.set_ylim(1e-5, 1e3)
ax_dist.set_xlabel("distance AUV to node (m)")
ax_dist.set_ylabel("harvested power (mW)")
ax_dist.set_title("harvested power against distance")
ax_dist.legend(fontsize=7, ncol=2)
fig.tight_layout()

linear = link_budget(scenario, near_m).harvested_power_w
logistic = link_budget(scenario.replace(harvester="logistic"), near_m).harvested_power_w
ahead = near_m[logistic > linear]
if ahead.size:
    print(f"alpha = {scenario.split_ratio}: the logistic harvester yields more than the linear one "
          f"from {ahead.min():.1f} m to {ahead.max():.1f} m")
else:
    print(f"alpha = {scenario.split_ratio}: the linear harvester yields more at every distance shown")

# %% [markdown]
# ## 4. Coverage probability against the start position
#
# A node is covered when it lies inside the downward cone (half-angle 30°, range
# limited by the cone and the SNR threshold). With n nodes uniform in the volume,
# each is covered independently with p = V(cone ∩ volume) / V(volume), so the number
# covered is binomial (paper eq. 25). `coverage_fraction` computes p in closed form
# when only the depth clips the cone and by seeded Monte Carlo integration when the
# side walls do; `simulated_coverage_probability` checks the whole chain by placing
# nodes and testing cone, range and SNR directly.
#
# The paper's number first: from the centre of the surface, P(cover ≥ 1 of 10) ≈ 0.6.

# %%
centre = (50.0, 50.0, 0.0)
analytic = analytic_coverage_probability(scenario, centre, n_nodes=10, k=1, rng=SEED)
simulated = simulated_coverage_probability(scenario, centre, n_nodes=10, k=1, trials=COVERAGE_TRIALS, rng=SEED)
print(f"P(at least 1 of 10 covered) from the surface centre: analytic {analytic:.3f}, "
      f"simulated {simulated:.3f} ({COVERAGE_TRIALS} layouts)")


# %%
def node_probability(position):
    return coverage_fraction(scenario, position, rng=SEED, n_samples=COVERAGE_SAMPLES).p

fig, (ax_x, ax_depth, ax_map) = plt.subplots(1, 3, figsize=(15, 4.3))

# along the centre line at the surface, n = 10, 25, 50 nodes, at least one covered
xs_m = np.linspace(5.0, 95.0, COVERAGE_POSITIONS)
p_x = [node_probability((x, 50.0, 0.0)) for x in xs_m]
gaps = []
for i, n in enumerate((10, 25, 50)):
    exact = np.array([binomial_at_least(n, 1, p) for p in p_x])
    sim = np.array([simulated_coverage_probability(scenario, (x, 50.0, 0.0), n, 1, trials=COVERAGE_TRIALS,
                                                   rng=SEED + 1 + i) for x in xs_m])
    gaps.append(np.abs(exact - sim).max())
    line = ax_x.plot(xs_m, exact, label=f"n = {n}, analytic")[0]
    ax_x.plot(xs_m, sim, "o", ms=4, color=line.get_color(), label=f"n = {n}, simulated")
ax_x.set_xlabel("AUV start position x at the surface, y = 50 m (m)")
ax_x.set_ylabel("P(at least 1 node covered) (-)")
ax_x.set_ylim(0, 1.02)
ax_x.legend(fontsize=7, ncol=2)

# deeper starts at the centre, n = 25, at least k covered
depths_m = (np.arange(scenario.grid_shape[2]) + 0.5) * scenario.cell_size_m
p_z = [node_probability((50.0, 50.0, z)) for z in depths_m]
for i, k in enumerate((1, 2, 3)):
    line = ax_depth.plot(depths_m, [binomial_at_least(25, k, p) for p in p_z], label=f"k = {k}, analytic")[0]
    sim = [simulated_coverage_probability(scenario, (50.0, 50.0, z), 25, k, trials=COVERAGE_TRIALS, rng=SEED + 10 + i)
           for z in depths_m]
    ax_depth.plot(depths_m, sim, "o", ms=4, color=line.get_color(), label=f"k = {k}, simulated")
ax_depth.set_xlabel("AUV depth at the centre (m)")
ax_depth.set_ylabel("P(at least k of 25 nodes covered) (-)")
ax_depth.set_ylim(0, 1.02)
ax_depth.legend(fontsize=7)

# a map over start positions at the surface, n = 25, analytic
cells = (np.arange(COVERAGE_MAP_CELLS) + 0.5) * scenario.length_m / COVERAGE_MAP_CELLS
grid = np.array([[binomial_at_least(25, 1, node_probability((x, y, 0.0))) for x in cells] for y in cells])
image = ax_map.imshow(grid, origin="lower", extent=(0, scenario.length_m, 0, scenario.width_m), vmin=0, vmax=1,
                      cmap="magma")
ax_map.set_xlabel("start position x (m)")
ax_map.set_ylabel("start position y (m)")
ax_map.grid(False)
fig.colorbar(image, ax=ax_map, label="P(at least 1 of 25 covered) (-)")
fig.tight_layout()

print(f"largest |analytic - simulated| along the centre line: {max(gaps):.3f} "
      f"(one standard error of a simulated probability is at most {0.5 / np.sqrt(COVERAGE_TRIALS):.3f})")

# %% [markdown]
# **Reading the figures.** With a 1 kW projector the SNR stays far above the 10 dB
# threshold within the cone's 100 m, so the cone geometry, not the SNR, decides which
# nodes are covered; the link rate changes little over the volume while the harvested
# power falls with distance to the power 1.5 (plus absorption). Coverage is best from
# positions whose cone is not clipped by the side walls, and from the surface, where the
# cone has the whole depth to widen.
