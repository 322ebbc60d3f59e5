"""Write the analysis notebooks of this folder from the cell sources below.

The notebooks are generated, not edited by hand: change a cell here and run

    python notebooks/build_notebooks.py            # (re)write every notebook
    python notebooks/build_notebooks.py --check    # exit 1 if a notebook differs

The files are written without outputs or execution counts and with fixed cell ids, so a
rebuild of unchanged sources is byte-identical and the committed notebooks diff cleanly.
``tests/test_notebooks.py`` executes every notebook on small settings
(``SWIPTOPT_NOTEBOOK_QUICK=1``) and checks that the files match this script.

Every notebook reads results through the public API only (``swiptopt``, ``rl``,
``planners``), seeds everything it draws, and labels every axis with its unit. Figures are
left for the inline backend to show at the end of their cell (no ``plt.show()``): the
tests inspect every figure at that point and fail on an axis without a label.
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent

#: The environment variable every notebook's first code cell reads ("1": small settings).
QUICK_VARIABLE = "SWIPTOPT_NOTEBOOK_QUICK"

KERNELSPEC = {"name": "python3", "display_name": "Python 3 (ipykernel)", "language": "python"}


def md(text: str) -> tuple[str, str]:
    return ("markdown", textwrap.dedent(text).strip("\n"))


def code(text: str) -> tuple[str, str]:
    return ("code", textwrap.dedent(text).strip("\n"))


# ---------------------------------------------------------------------------------------
# 01: the channel and harvesting

CHANNEL_AND_HARVESTING = [
    md(
        """
        # The acoustic channel, energy harvesting and coverage

        The physics of the shared model (SPEC 3), straight from the library functions the
        simulator uses:

        1. the link budget against distance and carrier frequency: transmission loss
           (Thorp absorption and spreading), ambient noise (Stojanovic's four-part model),
           SNR from the passive sonar equation, and the Shannon rate;
        2. Stojanovic's AN-optimal carrier frequency against distance;
        3. the power a node harvests against distance, for the linear and the logistic
           (Boshkovska) harvester;
        4. the paper's coverage analysis (eqs. 19-21): the probability of covering at
           least k of n uniformly placed nodes, analytic (binomial) against simulated, as a
           function of the AUV's start position.

        Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).
        """
    ),
    code(
        f"""
        import os

        QUICK = os.environ.get("{QUICK_VARIABLE}", "0") == "1"
        SEED = 0
        N_DISTANCES = 60 if QUICK else 300  # points of each distance axis
        N_FREQUENCIES = 40 if QUICK else 200  # points of each frequency axis
        COVERAGE_POSITIONS = 7 if QUICK else 19  # AUV positions along the centre line
        COVERAGE_MAP_CELLS = 5 if QUICK else 10  # surface positions per side of the coverage map
        COVERAGE_TRIALS = 300 if QUICK else 3000  # node layouts per simulated probability
        COVERAGE_SAMPLES = 20_000 if QUICK else 200_000  # Monte Carlo points of a clipped cone

        %matplotlib inline
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

        plt.rcParams.update({{"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3}})
        scenario = Scenario.preset("paper")
        print(f"quick settings: {{QUICK}}")
        """
    ),
    md(
        """
        ## 1. The link budget

        The `paper` preset: a 1 kW projector (η = 0.5) at 24 kHz with a 4 kHz band,
        spreading factor k = 1.5, wind 10 m/s, no shipping. `link_budget` combines the
        equations for a scenario at any array of distances.
        """
    ),
    code(
        """
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
        """
    ),
    code(
        """
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
        """
    ),
    md(
        """
        ## 2. The AN-optimal frequency

        For a narrow band at distance l the SNR is SL − A(l, f) N(f): the frequency that
        minimises the AN product maximises it (Stojanovic 2007). Absorption grows with both
        distance and frequency, so the optimum falls with distance. Left: the narrowband
        SNR per Hz over distance and frequency with the optimum overlaid; right: the optimum
        for a few wind speeds.

        Beyond some tens of kilometres in wind the global optimum jumps to the lower end of
        Thorp's range (0.1 kHz): below 0.4 kHz the model's wind-noise term falls again, so
        the AN product has a second minimum there. That is a property of the empirical noise
        model at frequencies it was not meant for, not a recommendation to signal at 100 Hz.
        """
    ),
    code(
        """
        far_m = np.geomspace(10.0, 100_000.0, N_DISTANCES)
        grid_khz = np.geomspace(0.1, 500.0, N_FREQUENCIES)
        an_db = acoustics.an_product_db(far_m[:, None], grid_khz[None, :], scenario.spreading_k, scenario.shipping, scenario.wind_mps)
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
        """
    ),
    md(
        """
        ## 3. Harvested power

        The node's hydrophone turns the received level into a voltage, V = 10^((RL + ρ)/20),
        and a matched load gets P_av = V² / (4 R_p). A share 1 − α goes to the harvester:
        linear (P_h = η (1 − α) P_av) or the logistic curve of Boshkovska et al., which
        saturates at M = 24 mW and yields little below its turning point b = 14 mW. Left:
        the two curves against their input power; right: what each delivers against
        distance for three split ratios.
        """
    ),
    code(
        """
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
        """
    ),
    md(
        """
        ## 4. Coverage probability against the start position

        A node is covered when it lies inside the downward cone (half-angle 30°, range
        limited by the cone and the SNR threshold). With n nodes uniform in the volume,
        each is covered independently with p = V(cone ∩ volume) / V(volume), so the number
        covered is binomial (paper eq. 21). `coverage_fraction` computes p in closed form
        when only the depth clips the cone and by seeded Monte Carlo integration when the
        side walls do; `simulated_coverage_probability` checks the whole chain by placing
        nodes and testing cone, range and SNR directly.

        The paper's number first: from the centre of the surface, P(cover ≥ 1 of 10) ≈ 0.6.
        """
    ),
    code(
        """
        centre = (50.0, 50.0, 0.0)
        analytic = analytic_coverage_probability(scenario, centre, n_nodes=10, k=1, rng=SEED)
        simulated = simulated_coverage_probability(scenario, centre, n_nodes=10, k=1, trials=COVERAGE_TRIALS, rng=SEED)
        print(f"P(at least 1 of 10 covered) from the surface centre: analytic {analytic:.3f}, "
              f"simulated {simulated:.3f} ({COVERAGE_TRIALS} layouts)")
        """
    ),
    code(
        """
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
        """
    ),
    md(
        """
        **Reading the figures.** With a 1 kW projector the SNR stays far above the 10 dB
        threshold within the cone's 100 m, so the cone geometry, not the SNR, decides which
        nodes are covered; the link rate changes little over the volume while the harvested
        power falls with distance to the power 1.5 (plus absorption). Coverage is best from
        positions whose cone is not clipped by the side walls, and from the surface, where the
        cone has the whole depth to widen.
        """
    ),
]


# ---------------------------------------------------------------------------------------
# 02: learning

LEARNING = [
    md(
        """
        # Learning: the paper's agents on the shared simulator

        Tabular Q-learning and SARSA (the paper's Table I settings: learning rate 0.75,
        discount 0.99, ε from 1 decaying ×0.999 per episode) and the random trajectory,
        trained with `rl.train` on the compiled backend (numba, the same kernel as the
        Gymnasium environment). This notebook shows

        1. training curves: moving averages of the per-episode return and data collected;
        2. the effect of the reward weight Γ and of the power-splitting ratio α on the
           greedy policy (small sweeps with `rl.paper_protocol`, error bars over layouts);
        3. a learned trajectory in 3D, with the nodes coloured by whether they were served.

        Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).
        """
    ),
    code(
        f"""
        import os

        QUICK = os.environ.get("{QUICK_VARIABLE}", "0") == "1"
        SEED = 0
        N_NODES = 25
        TRAIN_EPISODES = 5_000 if QUICK else 20_000  # training curves and the trajectory
        WINDOW = 100 if QUICK else 500  # moving-average window, episodes
        EVAL_EPISODES = 3 if QUICK else 20  # greedy evaluation episodes
        SWEEP_EPISODES = 2_000 if QUICK else 20_000  # training episodes per sweep task
        SWEEP_LAYOUTS = 2 if QUICK else 10  # node layouts per sweep point (error bars)
        REWARD_WEIGHTS = [0.2, 0.5, 0.8] if QUICK else [0.1, 0.3, 0.5, 0.7, 0.9]
        SPLIT_RATIOS = [0.2, 0.5, 0.8] if QUICK else [0.1, 0.3, 0.5, 0.7, 0.9]

        %matplotlib inline
        import matplotlib.pyplot as plt
        import numpy as np

        from rl import QLearningAgent, RandomAgent, SarsaAgent, paper_protocol, train
        from swiptopt import Scenario, Summary, evaluate
        from swiptopt.env import AuvSwiptEnv
        from swiptopt.kernel import is_served

        plt.rcParams.update({{"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3}})
        scenario = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=SEED)
        print(f"quick settings: {{QUICK}}; {{scenario.n_nodes}} nodes, {{scenario.n_cells}} cells, "
              f"{{scenario.episode_steps}} steps per episode")
        """
    ),
    md(
        """
        ## 1. Training curves

        One layout, one seed per agent. The compiled trainer steps the same kernel as
        `AuvSwiptEnv.step` and draws the same random numbers in the same order, so these
        curves are exactly what the Python loop would produce, only faster.
        """
    ),
    code(
        """
        def moving_average(values, window):
            window = max(1, min(window, len(values)))
            return np.convolve(values, np.ones(window) / window, mode="valid")

        agents, logs, envs = {}, {}, {}
        for name, make in (("Q-learning", QLearningAgent), ("SARSA", SarsaAgent), ("random", RandomAgent)):
            env = AuvSwiptEnv(scenario)
            agent = make(env.observation_space.n, seed=SEED)
            logs[name] = train(agent, env, TRAIN_EPISODES, seed=SEED, backend="compiled")
            agents[name], envs[name] = agent, env

        fig, (ax_return, ax_data) = plt.subplots(1, 2, figsize=(12, 4.3))
        for name, log in logs.items():
            x = np.arange(min(WINDOW, len(log)), len(log) + 1)  # the episode that ends each window
            ax_return.plot(x, moving_average(log["return"], WINDOW), label=name)
            ax_data.plot(x, moving_average(log["data_bits"], WINDOW) / 1e3, label=name)
        ax_eps = ax_return.twinx()
        ax_eps.plot(np.arange(1, len(logs["Q-learning"]) + 1), logs["Q-learning"]["epsilon"], ":", color="0.4")
        ax_eps.set_ylabel("exploration rate epsilon (-), dotted")
        ax_eps.set_ylim(0, 1.05)
        ax_eps.grid(False)
        ax_return.set_xlabel("training episode (-)")
        ax_return.set_ylabel(f"return, moving average over {WINDOW} episodes (-)")
        ax_return.legend(fontsize=8, loc="upper left")
        ax_data.set_xlabel("training episode (-)")
        ax_data.set_ylabel(f"data collected, moving average over {WINDOW} episodes (kbit)")
        ax_data.legend(fontsize=8)
        fig.tight_layout()
        """
    ),
    code(
        """
        print(f"greedy policy after {TRAIN_EPISODES} training episodes, {EVAL_EPISODES} evaluation episodes (mean +- 95 % CI):")
        for name, agent in agents.items():
            s = evaluate(agent, envs[name], EVAL_EPISODES, seed=SEED + 10_000).summary
            print(f"  {name:10s} return {s['return'].mean:6.2f} +- {np.nan_to_num(s['return'].ci95):5.2f}   "
                  f"data {s['data_bits'].mean / 1e3:6.0f} kbit   energy {s['energy_delivered_j'].mean * 1e3:6.0f} mJ   "
                  f"served {s['nodes_served'].mean:4.1f} nodes")
        """
    ),
    md(
        """
        ## 2. Reward weight and split ratio

        The paper's protocol per layout: train on a fixed node layout under the stochastic
        channel, then evaluate the greedy policy on separate seeds. Each point averages the
        evaluation of `SWEEP_LAYOUTS` layouts; error bars are 95 % confidence intervals over
        layouts (none with a single layout).

        Γ weighs data against energy in the reward, so returns at different Γ measure
        different things: compare the data and the energy. The energy reference of the
        reward does not depend on α, so returns across the split-ratio sweep are comparable.
        """
    ),
    code(
        """
        METRICS = {
            "return": ("return (-)", 1.0),
            "data_bits": ("data collected (kbit)", 1e-3),
            "energy_delivered_j": ("energy delivered (mJ)", 1e3),
            "nodes_served": ("nodes served (-)", 1.0),
        }

        def sweep(field, values, algorithm):
            # Summary over layouts of each layout's mean greedy evaluation, per value
            out = {metric: [] for metric in METRICS}
            for value in values:
                per_layout = {metric: [] for metric in METRICS}
                for layout in range(SWEEP_LAYOUTS):
                    s = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=layout, **{field: value})
                    result = paper_protocol(s, algorithm, train_episodes=SWEEP_EPISODES, eval_episodes=EVAL_EPISODES,
                                            seed=SEED + layout)
                    for metric in METRICS:
                        per_layout[metric].append(result.evaluation.summary[metric].mean)
                for metric in METRICS:
                    out[metric].append(Summary.of(per_layout[metric]))
            return out

        def plot_sweep(field, values, xlabel):
            fig, axes = plt.subplots(1, len(METRICS), figsize=(16, 3.6))
            for algorithm, label in (("q_learning", "Q-learning"), ("sarsa", "SARSA")):
                result = sweep(field, values, algorithm)
                for ax, (metric, (ylabel, scale)) in zip(axes, METRICS.items()):
                    mean = np.array([s.mean for s in result[metric]]) * scale
                    ci = np.nan_to_num(np.array([s.ci95 for s in result[metric]])) * scale
                    ax.errorbar(values, mean, yerr=ci, marker="o", capsize=3, label=label)
                    ax.set_xlabel(xlabel)
                    ax.set_ylabel(ylabel)
            axes[0].legend(fontsize=8)
            fig.tight_layout()
            return fig

        fig = plot_sweep("reward_weight", REWARD_WEIGHTS, "reward weight Gamma (-)")
        """
    ),
    code(
        """
        fig = plot_sweep("split_ratio", SPLIT_RATIOS, "power-splitting ratio alpha (-)")
        """
    ),
    md(
        """
        ## 3. A learned trajectory in 3D

        The Q-learning agent trained above, rolled out greedily once in the environment.
        `env.path` holds the cell of every step; `scenario.cell_centers_m` turns cells into
        metres. A node counts as served when its data is delivered and its storage is full
        (the environment's own definition); "partly served" nodes got data or energy but not
        all of it.
        """
    ),
    code(
        """
        env = AuvSwiptEnv(scenario)
        agent = agents["Q-learning"]
        obs, info = env.reset(seed=SEED + 20_000)
        parts = []
        while True:
            obs, reward, terminated, truncated, info = env.step(agent.predict(obs, deterministic=True))
            parts.append(info["reward_parts"])
            if terminated or truncated:
                break
        episode = info["episode"]
        path_m = scenario.cell_centers_m[np.asarray(env.path)]
        state = env.state
        nodes_m = scenario.layout.positions_m
        served = np.array([is_served(state.data_left, state.energy, env.tables.capacity, scenario.reward_weight, i)
                           for i in range(scenario.n_nodes)])
        partly = ~served & ((state.collected > 0) | (state.delivered > 0))
        untouched = ~served & ~partly
        print(f"{episode['length']} steps: {episode['data_bits'] / 1e3:.0f} kbit collected, "
              f"{episode['energy_delivered_j'] * 1e3:.0f} mJ delivered, {episode['nodes_served']} nodes served, "
              f"return {episode['return']:.2f}")

        fig = plt.figure(figsize=(15, 5))
        ax3d = fig.add_subplot(1, 3, (1, 2), projection="3d")
        ax3d.plot(*path_m.T, "-", color="k", lw=1.5, alpha=0.7, label="AUV path")
        cells, dwell = np.unique(np.asarray(env.path), return_counts=True)
        ax3d.scatter(*scenario.cell_centers_m[cells].T, s=12 * dwell, color="k", alpha=0.4)  # area: steps spent there
        ax3d.scatter(*path_m[0], marker="^", s=120, color="tab:red", label="start")
        for mask, colour, label in ((served, "tab:green", "served"), (partly, "tab:orange", "partly served"),
                                    (untouched, "tab:blue", "not served")):
            ax3d.scatter(*nodes_m[mask].T, color=colour, s=25, depthshade=False, label=f"{label} ({mask.sum()})")
        ax3d.set_xlim(0, scenario.length_m)
        ax3d.set_ylim(0, scenario.width_m)
        ax3d.set_zlim(scenario.depth_m, 0)  # depth grows downwards
        ax3d.set_box_aspect(scenario.extent_m)  # metres equal on every axis
        ax3d.set_xlabel("x (m)")
        ax3d.set_ylabel("y (m)")
        ax3d.set_zlabel("depth (m)")
        ax3d.set_title("greedy Q-learning trajectory (grey discs: steps spent in a cell)")
        ax3d.legend(fontsize=7, loc="upper left")

        ax_parts = fig.add_subplot(1, 3, 3)
        steps = np.arange(1, len(parts) + 1)
        for key in ("throughput", "harvest", "movement"):
            ax_parts.plot(steps, np.cumsum([p[key] for p in parts]), label=key)
        ax_parts.plot(steps, np.cumsum([sum(p.values()) for p in parts]), "k", lw=2, label="return")
        ax_parts.set_xlabel("step of the episode (-)")
        ax_parts.set_ylabel("cumulative reward part (-)")
        ax_parts.set_title("the reward, part by part")
        ax_parts.legend(fontsize=8)
        fig.tight_layout()
        """
    ),
]


# ---------------------------------------------------------------------------------------
# 03: head to head

HEAD_TO_HEAD = [
    md(
        """
        # Head to head: RL agents against classical planners

        A small experiment through the benchmark's public API, into a temporary results
        store: every algorithm on the `paper` preset over a sweep of node counts and a few
        layouts. Then the store is read back for

        1. the comparison table (`swiptopt.tables`: Markdown, and a pandas DataFrame from
           the CSV form);
        2. a paper-style figure: metrics against the node count with 95 % CI error bars;
        3. optimality gaps: against the upper bound of every scenario, and against the exact
           optimum (dynamic programming) on the `tiny` preset;
        4. a discussion computed from the numbers: which algorithm ranks first per metric,
           and where RL or the planners win.

        Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do); the quick numbers
        come from very short training and are a smoke test, not a result.
        """
    ),
    code(
        f"""
        import os

        QUICK = os.environ.get("{QUICK_VARIABLE}", "0") == "1"
        SEED = 0
        NODE_COUNTS = [10, 20] if QUICK else [10, 20, 30, 40, 50]
        LAYOUTS = 2 if QUICK else 6  # node layouts per sweep point (the error bars)
        EPISODES = 2 if QUICK else 10  # greedy evaluation episodes per task
        TRAIN_EPISODES = 1_000 if QUICK else 20_000  # per RL task
        TSP_TIME_LIMIT_S = 0.2 if QUICK else 1.0
        WORKERS = 1 if QUICK else None  # local processes; None: every core
        TINY_EPISODES = 3 if QUICK else 10  # evaluation episodes on the tiny preset

        %matplotlib inline
        import io
        import tempfile
        from pathlib import Path

        import matplotlib.pyplot as plt
        import numpy as np
        import pandas as pd
        from IPython.display import Markdown, display

        from planners.bounds import exact_optimum, upper_bound
        from swiptopt import Scenario, evaluate, tables
        from swiptopt.algorithms import ALGORITHMS, build_policy
        from swiptopt.env import AuvSwiptEnv
        from swiptopt.experiment import Experiment
        from swiptopt.runner import execute
        from swiptopt.store import ResultStore

        plt.rcParams.update({{"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3}})
        print(f"quick settings: {{QUICK}}")
        """
    ),
    md(
        """
        ## 1. Run the experiment

        `Experiment.from_dict` takes the same keys as an experiment TOML file. Each
        (node count, layout, algorithm, seed) is one task; `execute` runs the tasks the
        store lacks and commits each as it finishes. Running it a second time finds every
        task stored and runs nothing.
        """
    ),
    code(
        """
        experiment = Experiment.from_dict({
            "name": "notebook-head-to-head",
            "scenario": {"preset": "paper"},
            "sweep": {"n_nodes": NODE_COUNTS},
            "layouts": LAYOUTS,
            "seeds": 1,
            "episodes": EPISODES,
            "baseline": "random",
            "algorithms": {
                "q_learning": {"train_episodes": TRAIN_EPISODES},
                "sarsa": {"train_episodes": TRAIN_EPISODES},
                "random": {},
                "kmeans_tsp": {"tsp_time_limit_s": TSP_TIME_LIMIT_S},
                "lawnmower": {},
                "greedy": {},
            },
        })
        workdir = tempfile.TemporaryDirectory(prefix="swiptopt-notebook-")
        store_path = Path(workdir.name) / "results.sqlite"
        with ResultStore(store_path) as store:
            first = execute(experiment, store, workers=WORKERS)
            again = execute(experiment, store, workers=WORKERS)
        print(f"{first.total} tasks: ran {first.ran} in {first.seconds:.1f} s; "
              f"second run: {again.cached} found in the store, {again.ran} ran")
        """
    ),
    md(
        """
        ## 2. The comparison table

        `tables.aggregate` averages each task's evaluation episodes, then summarises over
        layouts (mean ± 95 % CI); the rank is by mean return at each node count. The gap to
        the bound is (bound − return) / bound per task.
        """
    ),
    code(
        """
        with ResultStore(store_path, create=False) as store:
            rows, missing = tables.aggregate(experiment, store)
            provenance = store.runs()[-1]["provenance"]
        print(f"{missing} tasks missing; swiptopt {provenance['versions']['swiptopt']}, numpy {provenance['versions']['numpy']}")
        display(Markdown(tables.to_markdown(rows)))
        """
    ),
    md(
        """
        With `baseline = "random"`, `tables.paired` divides each algorithm's mean by the
        random trajectory's over the same layouts: the ratio, a seeded 95 % bootstrap
        interval, and on how many layouts the algorithm did better.
        """
    ),
    code(
        """
        with ResultStore(store_path, create=False) as store:
            pairs = tables.paired(experiment, store)
        display(Markdown(tables.render_paired(pairs, "markdown")))
        """
    ),
    code(
        """
        results = pd.read_csv(io.StringIO(tables.to_csv(rows)))
        results["label"] = results["algorithm"].map({name: a.label for name, a in ALGORITHMS.items()})
        results["family"] = results["algorithm"].map({name: a.family for name, a in ALGORITHMS.items()})
        print("columns:", ", ".join(results.columns))
        print("mean data collected (kbit) per algorithm and node count:")
        data_kbit = results[results.metric == "data_bits"].pivot(index="label", columns="n_nodes", values="mean") / 1e3
        data_kbit.round(0)
        """
    ),
    md(
        """
        ## 3. Metrics against the number of nodes

        The paper's node-count figures for every algorithm at once; error bars are 95 %
        confidence intervals over layouts.
        """
    ),
    code(
        """
        FIGURE_METRICS = {
            "return": ("return (-)", 1.0),
            "data_bits": ("data collected (kbit)", 1e-3),
            "energy_delivered_j": ("energy delivered to nodes (mJ)", 1e3),
            "mobility_efficiency_bit_per_j": ("energy efficiency, AUV motion (bit/J)", 1.0),
        }
        fig, axes = plt.subplots(1, len(FIGURE_METRICS), figsize=(17, 3.8))
        for ax, (metric, (ylabel, scale)) in zip(axes, FIGURE_METRICS.items()):
            for algorithm in experiment.algorithms:
                mine = results[(results.metric == metric) & (results.algorithm == algorithm)].sort_values("n_nodes")
                ax.errorbar(mine["n_nodes"], mine["mean"] * scale, yerr=mine["ci95"].fillna(0.0) * scale,
                            marker="o", ms=4, capsize=3, label=mine["label"].iloc[0])
            ax.set_xticks(NODE_COUNTS)
            ax.set_xlabel("number of nodes (-)")
            ax.set_ylabel(ylabel)
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        """
    ),
    md(
        """
        ## 4. Optimality gaps

        **Against the upper bound.** `planners.bounds.upper_bound` caps what any policy can
        earn: every coverable node's data and storage room, with no travel. It is loose
        (serving takes time and moving costs), so the gap is an upper estimate of how far
        from optimal an algorithm is.
        """
    ),
    code(
        """
        example = experiment.scenario_for({"n_nodes": NODE_COUNTS[0]}, 0)
        bound = upper_bound(example)
        print(f"{example.n_nodes} nodes, layout 0: upper bound on the return {bound.return_:.2f}, "
              f"data {bound.data_bits / 1e3:.0f} kbit, energy {bound.energy_delivered_j * 1e3:.0f} mJ")

        gaps = results[results.metric == tables.GAP_BOUND]
        labels = [ALGORITHMS[name].label for name in experiment.algorithms]
        width = 0.8 / len(NODE_COUNTS)
        fig, ax = plt.subplots(figsize=(10, 3.8))
        for i, n in enumerate(NODE_COUNTS):
            at_n = gaps[gaps.n_nodes == n].set_index("label").reindex(labels)
            ax.bar(np.arange(len(labels)) + (i - (len(NODE_COUNTS) - 1) / 2) * width, at_n["mean"] * 100, width,
                   yerr=at_n["ci95"].fillna(0.0) * 100, capsize=2, label=f"{n} nodes")
        ax.set_xticks(np.arange(len(labels)), labels)
        ax.set_xlabel("algorithm")
        ax.set_ylabel("gap to the upper bound on the return (%)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        """
    ),
    md(
        """
        **Against the exact optimum.** The `tiny` preset (3 nodes, a 3 × 3 × 2 grid,
        8 steps, no fading, no link failures) is small enough for `exact_optimum` to find the
        best return by dynamic programming over the deterministic MDP. Replaying its actions
        in the environment earns exactly that return. Each algorithm, built with the same
        settings as in the experiment, is scored with `swiptopt.evaluate`.
        """
    ),
    code(
        """
        tiny = Scenario.preset("tiny", layout_seed=SEED)
        optimum = exact_optimum(tiny)
        tiny_bound = upper_bound(tiny)
        env = AuvSwiptEnv(tiny)
        env.reset(seed=SEED)
        replayed = 0.0
        for action in optimum.actions:
            _, reward, terminated, truncated, _ = env.step(action)
            replayed += reward
        print(f"exact optimum {optimum.return_:.3f} ({optimum.states_explored} states explored); "
              f"replayed in the environment {replayed:.3f}; upper bound {tiny_bound.return_:.3f}")
        assert np.isclose(replayed, optimum.return_)

        tiny_rows = []
        for name, settings in experiment.algorithms.items():
            policy = build_policy(name, env, settings, SEED)
            summary = evaluate(policy, env, TINY_EPISODES, seed=SEED + 1_000).summary["return"]
            tiny_rows.append({"algorithm": name, "label": ALGORITHMS[name].label, "family": ALGORITHMS[name].family,
                              "return": summary.mean, "ci95": summary.ci95,
                              "gap_to_optimum_pct": 100 * (optimum.return_ - summary.mean) / optimum.return_})
        tiny_results = pd.DataFrame(tiny_rows)

        fig, ax = plt.subplots(figsize=(9, 3.8))
        ax.bar(tiny_results["label"], tiny_results["return"], yerr=tiny_results["ci95"].fillna(0.0), capsize=3,
               color=["tab:blue" if f == "rl" else "tab:orange" for f in tiny_results["family"]])
        ax.axhline(optimum.return_, color="k", lw=1.5, label="exact optimum")
        ax.axhline(tiny_bound.return_, color="k", ls="--", lw=1, label="upper bound")
        ax.set_xlabel("algorithm (blue: RL, orange: planner)")
        ax.set_ylabel("return on the tiny preset (-)")
        ax.legend(fontsize=8)
        fig.tight_layout()
        tiny_results.round(3)
        """
    ),
    md(
        """
        ## 5. Where RL wins and where the planners win

        Computed from the table above, not written in advance: for every metric and node
        count, the best RL agent against the best planner. A win is "clear" when the
        difference of the means exceeds the sum of their 95 % CI half-widths. Steps to 50 %
        of the data count only for algorithms that reached the target on every layout (the
        table's "n/r" marks the others); a family with none loses that comparison clearly.
        """
    ),
    code(
        """
        LOWER_IS_BETTER = {"steps_to_data_target", tables.GAP_BOUND}
        # a mean over only the layouts where a target happened to be reached flatters the
        # algorithm, so a steps-to-target value counts only when every layout reached it
        EVERY_LAYOUT = {"steps_to_data_target"}

        def best(frame, higher):
            frame = frame.dropna(subset=["mean"])
            if frame.empty:
                return None
            return frame.loc[frame["mean"].idxmax() if higher else frame["mean"].idxmin()]

        def shown(row, scale, digits):
            return "not reached on every layout" if row is None else f"{row['label']} ({row['mean'] * scale:.{digits}f})"

        lines = ["| metric | nodes | first overall | best RL | best planner | winner |", "|---|---|---|---|---|---|"]
        wins = {"rl": [], "planner": []}
        compared = 0
        for metric, heading, scale, digits in tables.DISPLAY:  # the columns of the table above
            higher = metric not in LOWER_IS_BETTER
            for n in NODE_COUNTS:
                at = results[(results.metric == metric) & (results.n_nodes == n)]
                if metric in EVERY_LAYOUT:
                    at = at[at["missing"] == 0]
                top, rl, planner = best(at, higher), best(at[at.family == "rl"], higher), best(at[at.family == "planner"], higher)
                if top is None:
                    continue  # no algorithm has a value (a target nobody reached)
                compared += 1
                if rl is None or planner is None:
                    family, clear = ("planner" if rl is None else "rl"), True  # only one family has a value
                elif rl["mean"] == planner["mean"]:
                    family, clear = None, False
                else:
                    family = "rl" if (rl["mean"] > planner["mean"]) == higher else "planner"
                    ci = rl["ci95"] + planner["ci95"]  # NaN with a single layout: never clear
                    clear = bool(abs(rl["mean"] - planner["mean"]) > ci)
                if family is None:
                    verdict = "tie"
                else:
                    wins[family].append((heading, n, clear))
                    verdict = ("RL" if family == "rl" else "planner") + (" (clear)" if clear else "")
                lines.append(f"| {heading} | {n} | {top['label']} | {shown(rl, scale, digits)} | "
                             f"{shown(planner, scale, digits)} | {verdict} |")

        def summary_of(family):
            found = wins[family]
            if not found:
                return f"none of {compared} comparisons"
            clear = sorted({heading for heading, _, c in found if c})
            return (f"{len(found)} of {compared} comparisons"
                    + (f"; clearly on {', '.join(clear)}" if clear else "; none of them clearly"))

        best_tiny = tiny_results.loc[tiny_results["return"].idxmax()]
        rl_tiny = tiny_results[tiny_results.family == "rl"]["gap_to_optimum_pct"].min()
        planner_tiny = tiny_results[tiny_results.family == "planner"]["gap_to_optimum_pct"].min()
        text = "\\n".join(lines) + "\\n\\n" + "\\n".join([
            f"- **RL wins** {summary_of('rl')}.",
            f"- **Planners win** {summary_of('planner')}.",
            f"- On the `tiny` preset the best return is {best_tiny['label']}'s; the best RL agent is "
            f"{rl_tiny:.0f} % below the exact optimum, the best planner {planner_tiny:.0f} %.",
            f"- Settings: {TRAIN_EPISODES} training episodes per RL task, {LAYOUTS} layouts, {EPISODES} evaluation "
            f"episodes{' (quick settings: too short for RL to converge)' if QUICK else ''}.",
        ])
        display(Markdown(text))
        """
    ),
    code(
        """
        workdir.cleanup()  # the store was temporary
        """
    ),
]


# ---------------------------------------------------------------------------------------
# 04: planners as a library

PLANNERS_AS_LIBRARY = [
    md(
        """
        # The planners as a library

        The classical baselines without the environment: plain numpy arrays and small result
        dataclasses in, result dataclasses out.

        1. `planners.clustering.kmeans_hover_points`: k-means of the node positions into hover
           points, each group covered from one cell;
        2. `planners.tsp.solve_tsp`: the shortest tour (OR-Tools) over the start and the
           hover points;
        3. `planners.paths3d.plan_path_3d`: OMPL paths around obstacles, a sphere in open
           water and the `harbour` preset (pier, hull, wreck, sloping seabed, current);
        4. `planners.power_split`: the closed-form optimal split ratio over the reward weight
           and the distance, and the convex dwell-time and split program on a small instance.

        Set `SWIPTOPT_NOTEBOOK_QUICK=1` for small settings (the tests do).
        """
    ),
    code(
        f"""
        import os

        QUICK = os.environ.get("{QUICK_VARIABLE}", "0") == "1"
        SEED = 0
        OMPL_SEED = SEED + 1  # OMPL's seed is process-wide, set once, and must be >= 1
        N_NODES = 30
        TSP_TIME_LIMIT_S = 0.5 if QUICK else 2.0
        OMPL_TIME_LIMIT_S = 0.3 if QUICK else 2.0
        GRID_POINTS = 40 if QUICK else 200  # points per axis of the split-ratio map
        BUDGET_POINTS = 5 if QUICK else 20  # mission-time budgets of the dwell sweep

        %matplotlib inline
        import matplotlib.pyplot as plt
        import numpy as np
        from matplotlib.colors import LogNorm

        from planners.clustering import kmeans_hover_points
        from planners.paths3d import plan_path_3d
        from planners.power_split import (
            DwellSplitProblem,
            from_scenario,
            optimal_split_ratio,
            optimise_dwell_and_split,
            split_value_rate,
        )
        from planners.tsp import solve_tsp, tour_length
        from swiptopt import Box, Scenario, Sphere
        from swiptopt.link import link_budget, reward_references

        plt.rcParams.update({{"figure.dpi": 90, "axes.grid": True, "grid.alpha": 0.3}})
        scenario = Scenario.preset("paper", n_nodes=N_NODES, layout_seed=SEED)
        print(f"quick settings: {{QUICK}}")
        """
    ),
    md(
        """
        ## 1. Hover points by k-means

        With `k=None` the smallest K is chosen for which every group fits one coverage
        footprint: one hover cell covers all of its nodes. Nodes that no cell can cover are
        left out (label −1).
        """
    ),
    code(
        """
        hover = kmeans_hover_points(scenario, rng=SEED)
        nodes_m = scenario.layout.positions_m
        hover_m = scenario.cell_centers_m[hover.cells]
        print(f"K = {hover.k} hover points cover {hover.covered.any(axis=0).sum()} of {scenario.n_nodes} nodes; "
              f"uncoverable: {(hover.labels < 0).sum()}")

        fig, (ax_top, ax_side) = plt.subplots(1, 2, figsize=(12, 5))
        colours = plt.cm.tab10(np.arange(hover.k) % 10)
        for g in range(hover.k):
            members = nodes_m[hover.covered[g]]
            for ax, (i, j) in ((ax_top, (0, 1)), (ax_side, (0, 2))):
                for node in members:
                    ax.plot([hover_m[g, i], node[i]], [hover_m[g, j], node[j]], color=colours[g], lw=0.6, alpha=0.6)
                ax.scatter(nodes_m[hover.labels == g, i], nodes_m[hover.labels == g, j], color=colours[g], s=25)
                ax.scatter(hover_m[g, i], hover_m[g, j], marker="*", s=250, color=colours[g], edgecolor="k")
        for ax in (ax_top, ax_side):
            ax.scatter(*nodes_m[hover.labels < 0][:, [0, 1 if ax is ax_top else 2]].T, color="0.6", s=25, label="uncoverable")
            ax.set_xlim(0, scenario.length_m)
            ax.set_xlabel("x (m)")
        ax_top.set_ylim(0, scenario.width_m)
        ax_top.set_ylabel("y (m)")
        ax_top.set_title("top view: groups (colours), hover cells (stars)")
        ax_side.set_ylim(scenario.depth_m, 0)
        ax_side.set_ylabel("depth (m)")
        ax_side.set_title("side view: hover cells sit above their nodes")
        fig.tight_layout()
        """
    ),
    md(
        """
        ## 2. A TSP tour over the hover points

        Distances between the start cell and the hover cells in 3D. `solve_tsp` uses CP-SAT
        (a proof of optimality) on small instances and OR-Tools routing with guided local
        search on large ones, always under a time limit; the result reports whether the
        order is proven optimal. A closed tour returns to the start; an open path ends at
        the last hover point.
        """
    ),
    code(
        """
        start_m = scenario.cell_centers_m[scenario.start_cell_index]
        stops_m = np.vstack([start_m, hover_m])
        distance_m = np.linalg.norm(stops_m[:, None, :] - stops_m[None, :, :], axis=-1)
        tour = solve_tsp(distance_m, start=0, closed=True, time_limit_s=TSP_TIME_LIMIT_S)
        path = solve_tsp(distance_m, start=0, closed=False, time_limit_s=TSP_TIME_LIMIT_S)
        for name, result in (("closed tour", tour), ("open path", path)):
            if not result.order:
                raise RuntimeError(f"{name}: no solution ({result.status})")
            print(f"{name:11s}: {result.length:6.1f} m, status {result.status}, proven optimal {result.proven_optimal}, "
                  f"method {result.method}, {result.solve_time_s:.2f} s")
        shuffled = [0, *np.random.default_rng(SEED).permutation(np.arange(1, len(stops_m)))]
        print(f"a random order of the same stops: {tour_length(distance_m, shuffled, closed=True):.1f} m (closed)")

        fig = plt.figure(figsize=(13, 5))
        ax2d = fig.add_subplot(1, 2, 1)
        ax3d = fig.add_subplot(1, 2, 2, projection="3d")
        closed_m = stops_m[list(tour.order) + [tour.order[0]]]
        open_m = stops_m[list(path.order)]
        ax2d.plot(closed_m[:, 0], closed_m[:, 1], "-", color="tab:blue", label=f"closed tour, {tour.length:.0f} m")
        ax2d.plot(open_m[:, 0], open_m[:, 1], "--", color="tab:red", label=f"open path, {path.length:.0f} m")
        ax2d.scatter(nodes_m[:, 0], nodes_m[:, 1], s=10, color="0.5", label="nodes")
        ax2d.scatter(hover_m[:, 0], hover_m[:, 1], marker="*", s=150, color="tab:orange", edgecolor="k", label="hover points")
        ax2d.scatter(*start_m[:2], marker="^", s=120, color="k", label="start")
        for rank, stop in enumerate(tour.order[1:], start=1):
            ax2d.annotate(str(rank), stops_m[stop, :2], textcoords="offset points", xytext=(6, 6), fontsize=8)
        ax2d.set_xlim(0, scenario.length_m)
        ax2d.set_ylim(0, scenario.width_m)
        ax2d.set_xlabel("x (m)")
        ax2d.set_ylabel("y (m)")
        ax2d.set_title("top view (numbers: visiting order of the tour)")
        ax2d.legend(fontsize=7, loc="lower left")

        ax3d.plot(*closed_m.T, "-", color="tab:blue")
        ax3d.scatter(*nodes_m.T, s=8, color="0.5")
        ax3d.scatter(*hover_m.T, marker="*", s=120, color="tab:orange", edgecolor="k")
        ax3d.scatter(*start_m, marker="^", s=100, color="k")
        ax3d.set_xlim(0, scenario.length_m)
        ax3d.set_ylim(0, scenario.width_m)
        ax3d.set_zlim(scenario.depth_m, 0)
        ax3d.set_box_aspect(scenario.extent_m)  # metres equal on every axis
        ax3d.set_xlabel("x (m)")
        ax3d.set_ylabel("y (m)")
        ax3d.set_zlabel("depth (m)")
        ax3d.set_title("the closed tour in 3D")
        fig.tight_layout()
        """
    ),
    md(
        """
        ## 3. OMPL paths around obstacles

        `plan_path_3d` runs OMPL in a 3D real-vector space over the scenario's volume with a
        validity checker for its boxes, spheres and seabed, always under a time limit, and
        reports whether the path is exact. The seed is OMPL's process-wide seed: set once, on
        the first call, and the same on every later call. The default planner (AORRTC) is
        anytime and stops at the wall-clock limit, so path lengths can differ slightly from
        run to run even with a seed.

        In the harbour each trip is planned twice: for the shortest path (AORRTC) and for the
        least AUV energy (`objective="energy"`, Informed RRT*), which accounts for the tidal
        current that weakens with depth. Both are anytime planners cut off at the time limit;
        with the short limits of the quick settings the energy planner may not yet beat the
        shortest path even on energy, as the printed numbers show.

        Each path is checked here against the scenario's own obstacle test
        (`Scenario.is_blocked`) at points every 0.1 m along its segments.
        """
    ),
    code(
        """
        def densify(waypoints_m, step_m=0.1):
            # points every step_m along a polyline (k, 3)
            pieces = [np.linspace(a, b, max(2, int(np.ceil(np.linalg.norm(b - a) / step_m)) + 1))
                      for a, b in zip(waypoints_m[:-1], waypoints_m[1:])]
            return np.vstack(pieces)

        def check(result, scenario_, start, goal):
            if not result.exact:
                print(f"  {result.planner}: no exact path within the limit ({result.status})")
                return
            clear = not scenario_.is_blocked(densify(result.waypoints)).any()
            print(f"  {result.planner}, objective {result.objective}: {result.status}, {result.length_m:.1f} m "
                  f"(straight line {np.linalg.norm(np.subtract(goal, start)):.1f} m), {len(result.waypoints)} waypoints, "
                  f"AUV energy {result.energy_j / 1e3:.2f} kJ, collision-free: {clear}")
            assert clear

        def sphere_mesh(sphere, n=16):
            u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n), np.linspace(0, np.pi, n))
            c, r = sphere.center_m, sphere.radius_m
            return c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v), c[2] + r * np.cos(v)

        def box_edges(box):
            lo, hi = np.asarray(box.min_m), np.asarray(box.max_m)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            return [(corners[i], corners[j]) for i in range(8) for j in range(i + 1, 8)
                    if np.count_nonzero(corners[i] != corners[j]) == 1]

        def draw_obstacles(ax, scenario_, depth_exaggeration=1.0):
            for obstacle in scenario_.obstacles:
                if isinstance(obstacle, Sphere):
                    ax.plot_wireframe(*sphere_mesh(obstacle), color="0.5", lw=0.5)
                elif isinstance(obstacle, Box):
                    for a, b in box_edges(obstacle):
                        ax.plot(*np.stack([a, b]).T, color="0.3", lw=1)
            if scenario_.seabed_height_m is not None:
                gx, gy = np.meshgrid(np.linspace(0, scenario_.length_m, 12), np.linspace(0, scenario_.width_m, 12))
                ax.plot_surface(gx, gy, scenario_.seabed_depth_m(gx, gy), color="tan", alpha=0.3)
            ax.set_xlim(0, scenario_.length_m)
            ax.set_ylim(0, scenario_.width_m)
            ax.set_zlim(scenario_.depth_m, 0)
            ax.set_box_aspect(scenario_.extent_m * (1.0, 1.0, depth_exaggeration))
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
            ax.set_zlabel("depth (m)")

        # a sphere in open water
        rock = Sphere(center_m=(50.0, 50.0, 25.0), radius_m=18.0)
        open_water = Scenario.preset("paper", obstacles=(rock,))
        a, b = (8.0, 50.0, 25.0), (92.0, 50.0, 25.0)
        around_rock = plan_path_3d(a, b, open_water, time_limit_s=OMPL_TIME_LIMIT_S, seed=OMPL_SEED)
        print("sphere:")
        check(around_rock, open_water, a, b)

        # the harbour: around the pier, and past the moored hull, by length and by AUV energy
        harbour = Scenario.preset("harbour")
        trips = {"around the pier": ((30.0, 60.0, 20.0), (30.0, 140.0, 20.0)),
                 "past the hull": ((100.0, 50.0, 4.0), (180.0, 50.0, 4.0))}
        harbour_paths = {}
        for trip, (start, goal) in trips.items():
            print(f"harbour, {trip}:")
            for objective in ("length", "energy"):
                result = plan_path_3d(start, goal, harbour, objective=objective, time_limit_s=OMPL_TIME_LIMIT_S, seed=OMPL_SEED)
                check(result, harbour, start, goal)
                harbour_paths[trip, objective] = result
        """
    ),
    code(
        """
        fig = plt.figure(figsize=(19, 5.5))
        ax_rock = fig.add_subplot(1, 3, 1, projection="3d")
        draw_obstacles(ax_rock, open_water)
        if around_rock.exact:
            ax_rock.plot(*around_rock.waypoints.T, "o-", color="tab:red", ms=3, label=f"OMPL path, {around_rock.length_m:.0f} m")
        ax_rock.plot(*np.stack([a, b]).T, "k:", label="straight line (blocked)")
        ax_rock.set_title("around a sphere")
        ax_rock.legend(fontsize=8)

        ax_harbour = fig.add_subplot(1, 3, 2, projection="3d")
        draw_obstacles(ax_harbour, harbour, depth_exaggeration=2.5)
        ax_top = fig.add_subplot(1, 3, 3)
        for obstacle in harbour.obstacles:
            if isinstance(obstacle, Box):
                (x0, y0, z0), (x1, y1, z1) = obstacle.min_m, obstacle.max_m
                ax_top.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, color="0.6", alpha=0.6))
                ax_top.annotate(f"depth {z0:g}-{z1:g} m", (x0, y1), textcoords="offset points", xytext=(2, 3), fontsize=7)
            elif isinstance(obstacle, Sphere):
                (cx, cy, cz), r = obstacle.center_m, obstacle.radius_m
                ax_top.add_patch(plt.Circle((cx, cy), r, color="0.6", alpha=0.6))
                ax_top.annotate(f"wreck, top at {cz - r:g} m", (cx - r, cy + r), textcoords="offset points", xytext=(0, 3),
                                fontsize=7)
        styles = {"length": "-", "energy": "--"}
        colours = dict(zip(trips, ("tab:red", "tab:blue")))
        for (trip, objective), result in harbour_paths.items():
            if result.exact:
                label = f"{trip}, min {objective}: {result.length_m:.0f} m, {result.energy_j / 1e3:.2f} kJ"
                ax_harbour.plot(*result.waypoints.T, styles[objective], color=colours[trip], lw=2, label=label)
                ax_top.plot(*result.waypoints[:, :2].T, styles[objective], color=colours[trip], lw=2, label=label)
        current = harbour.current_mps
        ax_top.annotate("", xy=(185 + 40 * current[0], 15 + 40 * current[1]), xytext=(185, 15),
                        arrowprops={"arrowstyle": "->", "color": "tab:cyan", "lw": 2})
        ax_top.annotate("surface current", (150, 5), fontsize=7, color="tab:cyan")
        ax_harbour.set_title("the harbour preset (depth exaggerated 2.5 x)")
        ax_top.set_xlim(0, harbour.length_m)
        ax_top.set_ylim(0, harbour.width_m)
        ax_top.set_aspect("equal")
        ax_top.set_xlabel("x (m)")
        ax_top.set_ylabel("y (m)")
        ax_top.set_title("the harbour from above (obstacles grey)")
        ax_top.legend(fontsize=7, loc="lower left")
        fig.tight_layout(w_pad=4)
        """
    ),
    md(
        """
        ## 4. The power-split trade-off

        Serving a node with split ratio α for one second earns
        Γ · B log2(1 + α γ) / D_ref + (1 − Γ) · η (1 − α) P_av / E_ref (the reward's weighting,
        linear harvester). It is concave in α, and its maximiser has a closed form:
        α* = clip(Γ B E_ref / (ln 2 (1 − Γ) η P_av D_ref) − 1/γ, 0, 1). With a 1 kW
        projector γ is huge, so α* depends on the ratio of the information weight to the
        harvestable power: far nodes, which harvest little, get more of the signal for data.
        """
    ),
    code(
        """
        refs = reward_references(scenario)
        distances_m = np.linspace(2.0, scenario.cone_range_m, GRID_POINTS)
        weights = np.linspace(0.0, 1.0, GRID_POINTS)
        budget = link_budget(scenario, distances_m)
        snr = 10.0 ** (budget.snr_db / 10.0)
        model = dict(bandwidth_hz=scenario.bandwidth_hz, efficiency=scenario.harvest_efficiency,
                     data_ref_bits=refs.data_ref_bits, energy_ref_j=refs.energy_ref_j)
        alpha_star = np.array([optimal_split_ratio(snr, budget.available_power_w, reward_weight=w, **model) for w in weights])

        fig, (ax_map, ax_lines, ax_rate) = plt.subplots(1, 3, figsize=(16, 4.3))
        mesh = ax_map.pcolormesh(distances_m, weights, alpha_star, shading="auto", cmap="viridis", vmin=0, vmax=1)
        contours = ax_map.contour(distances_m, weights, alpha_star, levels=[0.1, 0.25, 0.5, 0.75, 0.9], colors="w", linewidths=0.8)
        ax_map.clabel(contours, fontsize=7)
        ax_map.set_xlabel("distance AUV to node (m)")
        ax_map.set_ylabel("reward weight Gamma (-)")
        fig.colorbar(mesh, ax=ax_map, label="optimal split ratio alpha* (-)")

        for d in (5.0, 10.0, 20.0, 40.0):
            at_d = link_budget(scenario, d)
            line = [float(optimal_split_ratio(10.0 ** (at_d.snr_db / 10.0), at_d.available_power_w, reward_weight=w, **model))
                    for w in weights]
            ax_lines.plot(weights, line, label=f"{d:g} m")
        ax_lines.set_xlabel("reward weight Gamma (-)")
        ax_lines.set_ylabel("optimal split ratio alpha* (-)")
        ax_lines.legend(fontsize=8, title="distance")

        # the closed form against a brute-force grid, one node at 10 m
        alphas = np.linspace(0.0, 1.0, 2001)
        at_10 = link_budget(scenario, 10.0)
        snr_10 = 10.0 ** (at_10.snr_db / 10.0)
        for w in (0.3, 0.5, 0.7):
            rate = split_value_rate(alphas, snr_10, at_10.available_power_w, reward_weight=w, **model)
            best = float(optimal_split_ratio(snr_10, at_10.available_power_w, reward_weight=w, **model))
            line = ax_rate.plot(alphas, rate, label=f"Gamma = {w}")[0]
            ax_rate.plot(best, split_value_rate(best, snr_10, at_10.available_power_w, reward_weight=w, **model), "o",
                         color=line.get_color())
            print(f"Gamma = {w}: closed form alpha* = {best:.4f}, grid argmax = {alphas[np.argmax(rate)]:.4f}")
        ax_rate.set_xlabel("split ratio alpha (-)")
        ax_rate.set_ylabel("value rate, node at 10 m (1/s)")
        ax_rate.legend(fontsize=8)
        fig.tight_layout()
        """
    ),
    md(
        """
        ## 5. Dwell times and split ratios at several hover points

        The joint program: a dwell time t_k at each hover point and a split α_ik for every
        covered node, maximising the same weighted value under a mission-time budget, with
        each node's data and storage room as caps. The bits are written in perspective form
        so the problem is convex (exponential cone, solved by cvxpy). `from_scenario` builds
        the inputs for a scenario and its hover cells; the result carries the solver status,
        and arrays only when the solve succeeded.

        With link SNRs of 80-100 dB a split of 10⁻⁴ of the signal already carries tens of
        kbit/s, so the program sends almost everything to the harvester: the split ratios are
        drawn on a log scale.
        """
    ),
    code(
        """
        small = Scenario.preset("paper", n_nodes=8, layout_seed=SEED + 1, episode_steps=20)
        small_hover = kmeans_hover_points(small, rng=SEED)
        inputs = from_scenario(small, small_hover.cells)
        result = optimise_dwell_and_split(**inputs.as_kwargs())
        print(f"{small_hover.k} hover points, {small.n_nodes} nodes, budget {inputs.mission_time_s:.0f} s: "
              f"status {result.status}, solver {result.solver}, {result.solve_time_s:.2f} s")
        if not result.ok:
            raise RuntimeError(f"the dwell/split program did not solve: {result.status}")
        print(f"objective {result.objective:.3f}; total dwell {result.dwell_s.sum():.1f} s")

        fig, (ax_dwell, ax_split, ax_nodes) = plt.subplots(1, 3, figsize=(16, 4.3),
                                                           gridspec_kw={"width_ratios": [1, 1.4, 1.6]})
        ax_dwell.bar(np.arange(small_hover.k), result.dwell_s)
        ax_dwell.set_xticks(np.arange(small_hover.k))
        ax_dwell.set_xlabel("hover point (-)")
        ax_dwell.set_ylabel("dwell time (s)")

        served_split = result.split_ratio[np.isfinite(result.split_ratio)]
        print(f"split ratios of the served pairs: {served_split.min():.2g} .. {served_split.max():.2g}")
        # with link SNRs of 80-100 dB a tiny share of the signal carries the data: log colours
        image = ax_split.imshow(np.ma.masked_invalid(np.maximum(result.split_ratio, 1e-9)), aspect="auto", cmap="viridis",
                                norm=LogNorm(vmin=max(1e-9, served_split.min()), vmax=1.0))
        ax_split.set_xlabel("node (-)")
        ax_split.set_ylabel("hover point (-)")
        ax_split.set_yticks(np.arange(small_hover.k))
        ax_split.grid(False)
        fig.colorbar(image, ax=ax_split, label="split ratio alpha (-, log scale), blank: not served")

        idx = np.arange(small.n_nodes)
        ax_nodes.bar(idx - 0.2, result.bits.sum(axis=0) / 1e3, 0.4, label="data collected (kbit)")
        ax_nodes.bar(idx + 0.2, result.energy_j.sum(axis=0) * 1e3, 0.4, label="energy delivered (mJ)")
        ax_nodes.plot(idx - 0.2, inputs.data_bits / 1e3, "k_", ms=14, label="data cap (kbit)")
        ax_nodes.plot(idx + 0.2, inputs.storage_room_j * 1e3, "r_", ms=14, label="storage room (mJ)")
        for i in np.flatnonzero(~inputs.coverage_mask.any(axis=0)):
            ax_nodes.annotate("not covered", (i, 0), textcoords="offset points", xytext=(0, 4), ha="center",
                              rotation=90, fontsize=7)
        ax_nodes.set_xticks(idx)
        ax_nodes.set_xlabel("node (-)")
        ax_nodes.set_ylabel("data (kbit) / energy (mJ)")
        ax_nodes.legend(fontsize=7)
        fig.tight_layout()
        """
    ),
    md(
        """
        The program is built once with cvxpy `Parameter`s (DPP), so a sweep over the
        mission-time budget re-solves without rebuilding. The value grows with the budget
        and flattens once every cap binds.
        """
    ),
    code(
        """
        problem = DwellSplitProblem(inputs.coverage_mask)
        budgets_s = np.linspace(0.05, 3.0, BUDGET_POINTS) * inputs.mission_time_s  # up to 3 episodes of dwell
        values, used = [], []
        for budget_s in budgets_s:
            r = problem.solve(**{**inputs.as_kwargs(), "mission_time_s": float(budget_s)})
            values.append(r.objective if r.ok else np.nan)
            used.append(r.dwell_s.sum() if r.ok else np.nan)
            if not r.ok:
                print(f"budget {budget_s:.0f} s: {r.status}")

        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(budgets_s, values, "o-", label="optimal value")
        ax.set_xlabel("mission-time budget (s)")
        ax.set_ylabel("weighted value (-)")
        ax_used = ax.twinx()
        ax_used.plot(budgets_s, used, "s--", color="tab:orange", label="dwell used")
        ax_used.set_ylabel("total dwell used (s), dashed")
        ax_used.grid(False)
        ax.legend(loc="upper left", fontsize=8)
        fig.tight_layout()
        """
    ),
]


NOTEBOOKS: dict[str, list[tuple[str, str]]] = {
    "01_channel_and_harvesting.ipynb": CHANNEL_AND_HARVESTING,
    "02_learning.ipynb": LEARNING,
    "03_head_to_head.ipynb": HEAD_TO_HEAD,
    "04_planners_as_library.ipynb": PLANNERS_AS_LIBRARY,
}


def build(name: str) -> nbformat.NotebookNode:
    """The notebook ``name`` (a key of :data:`NOTEBOOKS`), without outputs, fixed cell ids."""
    stem = name.split("_", 1)[0]
    cells = []
    for i, (kind, source) in enumerate(NOTEBOOKS[name]):
        cell_id = f"nb{stem}-{i:02d}"
        if kind == "markdown":
            cells.append(new_markdown_cell(source, id=cell_id))
        else:
            cells.append(new_code_cell(source, id=cell_id))
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = dict(KERNELSPEC)
    nb.metadata["language_info"] = {"name": "python"}
    return nb


def render(name: str) -> str:
    """The text of notebook ``name`` as written to disk."""
    nb = build(name)
    nbformat.validate(nb)
    return nbformat.writes(nb)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="report notebooks that differ from this script; write nothing")
    parser.add_argument("--outdir", type=Path, default=HERE, help="where to write (default: this folder)")
    args = parser.parse_args(argv)
    stale = []
    for name in NOTEBOOKS:
        path = args.outdir / name
        text = render(name)
        current = path.read_text(encoding="utf-8") if path.exists() else None
        if current == text:
            continue
        stale.append(name)
        if not args.check:
            path.write_text(text, encoding="utf-8")
    if args.check and stale:
        print("out of date (run python notebooks/build_notebooks.py): " + ", ".join(stale), file=sys.stderr)
        return 1
    for name in stale if not args.check else []:
        print(f"wrote {args.outdir / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
