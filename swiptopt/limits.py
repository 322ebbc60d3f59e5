"""Size limits: how big a scenario, a training run or an experiment may be.

Every size that grows memory or run time without bound is checked against these limits
before anything is allocated or run, and refused with a :class:`~swiptopt.errors.ConfigError`
that says how big it would be, what the limit is and which environment variable raises it.
The defaults fit a laptop (8 GB of memory, hours rather than weeks of work); a workstation
or a cluster run can raise any of them::

    SWIPTOPT_MAX_CELLS=5000000 swiptopt run big.toml

The limits are read from the environment each time they are checked (not at import), so a
process can change them, and a malformed value is itself a one-line error naming the
variable.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

from swiptopt.errors import ConfigError

#: One training-log row: the columns of :data:`rl.training.LOG_COLUMNS`, float64.
LOG_BYTES_PER_EPISODE = 8 * 8


@dataclass(frozen=True)
class Limits:
    """The largest sizes swiptopt accepts; each field is overridable by the variable in
    :data:`ENVIRONMENT` (``SWIPTOPT_`` and the field's name in capitals)."""

    max_cells: int = 1_000_000
    """Grid cells of one scenario (cells along x * y * depth). The kernel keeps about 120
    bytes per cell (moves and their energies), a tabular agent 4 states x 7 actions x 8
    bytes: about 350 MB at the limit. The paper's grid has 500 cells; 2.5 m cells in the
    paper's volume give 32,000."""
    max_cell_node_pairs: int = 50_000_000
    """Grid cells x nodes of one scenario: the coverage of every node from every cell is
    computed when the scenario's tables are built. 2.5 m cells with 1000 nodes in the
    paper's volume are 32 M pairs."""
    max_training_episodes: int = 10_000_000
    """Training episodes of one agent: the training log keeps one row of 64 bytes per
    episode (640 MB at the limit), and at the paper's 50 steps an episode is 5e8 steps."""
    max_tasks: int = 100_000
    """Tasks of one experiment: sweep points x layouts x algorithms x seeds. Every sweep
    point's scenario is validated before the run, and each task trains or plans."""
    max_evaluation_episodes: int = 10_000_000
    """Evaluation episodes of one experiment (tasks x episodes): each is a record in the
    results store."""
    max_buffer_values: int = 250_000_000
    """Float values in one deep-RL agent's rollout or replay buffer (observations of 4 + 6
    n_nodes values; a replay buffer keeps the next observation too): 1 GB of float32 at
    the limit, allocated when the agent is built."""
    max_network_parameters: int = 50_000_000
    """Parameters of one deep-RL agent's networks (policy and value or Q networks; about):
    200 MB of float32 at the limit, with the optimiser's state twice that."""


#: The environment variable that overrides each limit.
ENVIRONMENT = {f.name: "SWIPTOPT_" + f.name.upper() for f in dataclasses.fields(Limits)}


def limits() -> Limits:
    """The limits in force: the defaults, overridden by the environment variables."""
    values = {}
    for name, variable in ENVIRONMENT.items():
        raw = os.environ.get(variable)
        if raw is None or not raw.strip():
            continue
        try:
            value = int(raw.strip().replace("_", ""))
        except ValueError:
            value = 0
        if value < 1:
            raise ConfigError(f"{variable} = {raw!r} must be a positive integer", variable)
        values[name] = value
    return Limits(**values)


def check_size(
    limit: str, size: int, what: str, field: str, error: type[ConfigError] = ConfigError, note: str = ""
) -> None:
    """Refuse ``size`` when it exceeds the limit named ``limit`` (a :class:`Limits` field).

    ``what`` says what was counted (e.g. "grid cells (10,000 x 10,000 x 5)"), ``field``
    the configuration key to blame, ``error`` the error class to raise, ``note`` anything
    the message should add (what the size would cost).
    """
    allowed = getattr(limits(), limit)
    if size > allowed:
        raise error(
            f"{what}: {size:,}, over the limit of {allowed:,} (set {ENVIRONMENT[limit]} to raise it){note}", field
        )


def training_log_note(episodes: int) -> str:
    """What a training log of ``episodes`` rows would take, for a message."""
    return f"; its training log alone would take {episodes * LOG_BYTES_PER_EPISODE / 2**30:,.1f} GiB"


__all__ = ["ENVIRONMENT", "LOG_BYTES_PER_EPISODE", "Limits", "check_size", "limits", "training_log_note"]
