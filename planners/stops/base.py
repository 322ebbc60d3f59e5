"""What both worlds' stop-choice environments share: the dwell choices, the flat action with
its masks, the per-candidate part of the observation, the macro step (a decision executed as
kernel steps) and the adapter that runs a trained model as a policy on the kernel env.

A world supplies a *stops layout* (one per node layout, built once and cached): the candidate
stops, what one step at each earns from each node it covers, how many kernel steps the way to
each takes from where the AUV is, and the executor of one decision (:class:`Move`). Everything
else is here, so the two worlds cannot drift apart, and the environment and the adapter run
the same :class:`StopEpisode` (the adapter's episode is then the environment's, step for step).
"""

from __future__ import annotations

import json
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from swiptopt import kernel as K
from swiptopt.env import INFO_KEY, LAYOUT_CACHE_SIZE
from swiptopt.errors import ConfigError
from swiptopt.validation import Spec, check_value

#: ``Dwell.until`` values: ``"data"`` ends the dwell once the stop's covered nodes hold no
#: data; ``"served"`` once they need nothing more (the kernel's ``is_served``).
UNTIL = ("data", "served")

#: What a masked action does: ``"raise"`` refuses it (``ValueError`` naming the action and why);
#: ``"hover"`` executes it as one hover step at the current position (``info["masked"]`` says so).
MASKED_ACTIONS = ("raise", "hover")

#: Features per candidate after the kernel's vector observation: steps to reach it over the
#: episode's steps, what one step there earns now, what the longest fixed dwell there earns
#: now (both squashed, see :func:`squash`), and whether some dwell there is allowed now.
CANDIDATE_FEATURES = 4


@dataclass(frozen=True)
class Dwell:
    """How long to serve at a stop: ``steps`` service steps, the arrival step counted as the
    first (at a stop where the AUV already is, every one is a hover); with ``until``, at most
    ``steps``, ending early once the stop's covered nodes hold no data (``"data"``) or need
    nothing more (``"served"``), after at least one service step."""

    steps: int
    until: str | None = None

    #: What each field may hold, checked at construction (an error names ``dwells``, the
    #: setting that holds the dwells).
    FIELDS: ClassVar[dict[str, Spec]] = {
        "steps": Spec(kind="int", lo=1, strict=True, unit="steps"),
        "until": Spec(kind="str", choices=UNTIL, optional=True),
    }

    def __post_init__(self) -> None:
        for name, spec in self.FIELDS.items():
            check_value(f"Dwell.{name}", getattr(self, name), spec, field="dwells")

    @property
    def min_steps(self) -> int:
        """The fewest service steps it takes (the mask's test of what fits the episode)."""
        return int(self.steps) if self.until is None else 1

    @property
    def label(self) -> str:
        return f"{self.steps}" if self.until is None else f"until {self.until}, at most {self.steps}"


#: The default dwell choices: 1, 2, 3, 5 and 8 service steps, until the data is in (at most
#: 8), until the nodes are served (at most 12).
DWELLS: tuple[Dwell, ...] = (
    Dwell(1), Dwell(2), Dwell(3), Dwell(5), Dwell(8), Dwell(8, "data"), Dwell(12, "served"),
)


def check_dwells(dwells: Any) -> tuple[Dwell, ...]:
    """``dwells`` as a tuple of :class:`Dwell` (ints mean fixed dwells); a
    :class:`~swiptopt.ConfigError` naming ``dwells`` otherwise."""
    if isinstance(dwells, (str, bytes)) or not isinstance(dwells, Sequence) or len(dwells) == 0:
        raise ConfigError(f"dwells = {dwells!r} must be a non-empty sequence of Dwell (or ints)", "dwells")
    out = tuple(d if isinstance(d, Dwell) else Dwell(d) for d in dwells)
    if len(set(out)) != len(out):
        raise ConfigError(f"dwells = {dwells!r} holds the same choice twice", "dwells")
    return out


def squash(x: np.ndarray) -> np.ndarray:
    """x / (1 + x): [0, inf) onto [0, 1), monotone, so no value is clipped away."""
    return x / (1.0 + x)


def node_worth(params: K.Params, data_bits: float, capacity_j: float) -> float:
    """The most one node can be worth in reward (all its data and a full storage), the fixed
    scale of the observation's earnings: Gamma D / D_ref + (1 - Gamma) E_cap / E_ref."""
    gamma = params.reward_weight
    return float(gamma * data_bits / params.data_ref_bits + (1.0 - gamma) * capacity_j / params.energy_ref_j)


def layout_key(scenario: Any) -> str:
    """A scenario's identity for the caches of stops layouts (all its fields, the layout's
    included)."""
    return json.dumps(scenario.to_dict(), sort_keys=True, default=str)


def cached_layout(layouts: dict[str, Any], scenario: Any, build: Callable[[], Any]) -> Any:
    """The stops layout of ``scenario``'s node layout from ``layouts`` (a dict by
    :func:`layout_key`), made by ``build()`` when it is not there; the last
    :data:`~swiptopt.env.LAYOUT_CACHE_SIZE` used are kept, the least recently used dropped."""
    key = layout_key(scenario)
    layout = layouts.pop(key, None)
    if layout is None:
        layout = build()
    layouts[key] = layout
    if len(layouts) > LAYOUT_CACHE_SIZE:
        layouts.pop(next(iter(layouts)))
    return layout


# ----------------------------------------------------------------------------- one episode


class StopEpisode:
    """One episode of stop decisions on a kernel env: its masks and observation at each
    decision, and the kernel actions that carry a decision out (one per call).

    ``layout``: the world's stops layout; ``env``: the unwrapped kernel env (already reset).
    The environment and :class:`StopChoicePolicy` both drive one of these, so they decide from
    the same numbers and act alike.
    """

    def __init__(self, layout: Any, env: Any, dwells: tuple[Dwell, ...], masked_action: str):
        self.layout = layout
        self.env = env
        self.dwells = dwells
        self.masked_action = masked_action
        self.n_candidates = int(layout.n_candidates)
        self.n_actions = self.n_candidates * len(dwells) + 1
        self.fallback = self.n_actions - 1
        self._min_steps = np.array([d.min_steps for d in dwells], dtype=np.int64)
        fixed = [d.steps for d in dwells if d.until is None]
        self._longest = max(fixed) if fixed else max(d.steps for d in dwells)
        self.site: int | None = layout.start_site
        self.move: Any = None
        self.decisions = 0
        self.last_decision = (-1, -1)
        """(candidate, dwell index) of the last decision started; (-1, -1): the hover fallback."""
        self._memo: tuple[int, tuple[np.ndarray, np.ndarray]] | None = None

    # ------------------------------------------------------------------ the decision's view

    def steps_left(self) -> int:
        return int(self.env.scenario.episode_steps) - int(self.env.state.t)

    def _unserved(self) -> np.ndarray:
        s = self.env.state
        return ~K.served_mask(s.data_left, s.energy, self.layout.capacity, K.named(self.layout.params).reward_weight)

    def earnings(self, steps: int) -> np.ndarray:
        """(n_candidates,) what ``steps`` service steps at each candidate would earn now from the
        nodes it covers, each capped at what it still holds and can store (the per-step model's
        amounts; service only, no movement)."""
        lay, s = self.layout, self.env.state
        room = np.maximum(lay.capacity - s.energy, 0.0)
        nodes = lay.pair_node
        per_pair = lay.data_weight * np.minimum(s.data_left[nodes], steps * lay.pair_bits) + lay.energy_weight * (
            np.minimum(room[nodes], steps * lay.pair_joules)
        )
        return np.bincount(lay.pair_cand, weights=per_pair, minlength=self.n_candidates)

    def _table(self) -> tuple[np.ndarray, np.ndarray]:
        """(n_candidates, n_dwells) bool of the allowed (stop, dwell) pairs, and the steps to
        reach each candidate from here (-1: no way). Every decision takes a step, so the step
        count identifies the decision: computed once per decision."""
        t = int(self.env.state.t)
        if self._memo is not None and self._memo[0] == t:
            return self._memo[1]
        lay = self.layout
        reach = lay.reach_steps(self.env, self.site)
        serves = np.bincount(lay.pair_cand, weights=self._unserved()[lay.pair_node], minlength=self.n_candidates) > 0
        ok = lay.valid & (reach >= 0) & serves
        need = reach[:, None] + self._min_steps[None, :] - (reach[:, None] > 0)
        table = ok[:, None] & (need <= self.steps_left())
        self._memo = (t, (table, reach))
        return table, reach

    def action_masks(self) -> np.ndarray:
        """(n_actions,) bool: action ``c * n_dwells + d`` (stop c, dwell d) is allowed when stop c
        exists (a node some reachable position covers, not a copy of an earlier stop), a way
        leads there from here, one of the nodes it covers still needs something, and the way
        there plus the dwell's fewest steps fit the steps left. The last action (hover one
        step) is allowed exactly when nothing else is, so the mask is never all false."""
        table, _ = self._table()
        out = np.zeros(self.n_actions, dtype=bool)
        out[:-1] = table.ravel()
        out[-1] = not out[:-1].any()
        return out

    def observation(self) -> np.ndarray:
        """The kernel's vector observation here, then :data:`CANDIDATE_FEATURES` per candidate."""
        table, reach = self._table()
        steps = float(self.env.scenario.episode_steps)
        features = np.empty((self.n_candidates, CANDIDATE_FEATURES))
        features[:, 0] = np.where(reach >= 0, np.minimum(reach, steps) / steps, 1.0)
        features[:, 1] = squash(self.earnings(1) / self.layout.worth)
        features[:, 2] = squash(self.earnings(self._longest) / self.layout.worth)
        features[:, 3] = table.any(axis=1)
        return np.concatenate([self.layout.base_observation(self.env), features.ravel()]).astype(np.float32)

    # ------------------------------------------------------------------ acting

    def decode(self, action: int) -> tuple[int, int]:
        """(candidate, dwell index) of an action; (-1, -1) for the hover fallback."""
        if action == self.fallback:
            return -1, -1
        return divmod(action, len(self.dwells))

    def start(self, action: Any) -> bool:
        """Begin carrying out ``action``; returns whether it was masked (then, with
        ``masked_action="hover"``, it hovers one step; with ``"raise"`` it is refused)."""
        if isinstance(action, np.ndarray):
            if action.size != 1:
                raise ValueError(f"an action is one integer in [0, {self.n_actions - 1}], got {action!r}")
            action = action.reshape(()).item()
        if isinstance(action, (bool, np.bool_)) or not isinstance(action, numbers.Integral) or not (
            0 <= action < self.n_actions
        ):
            raise ValueError(f"an action is one integer in [0, {self.n_actions - 1}], got {action!r}")
        a = int(action)
        masks = self.action_masks()
        self.decisions += 1
        if not masks[a]:
            if self.masked_action == "raise":
                raise ValueError(f"action {a} is masked: {self._why_masked(a)} (see action_masks())")
            self.move = HoverOnce(self.layout.hover(), self.site)
            self.last_decision = (-1, -1)
            return True
        c, d = self.decode(a)
        self.last_decision = (c, d)
        if c < 0:
            self.move = HoverOnce(self.layout.hover(), self.site)
        else:
            self.move = self.layout.move(self.env, self.site, c, self.dwells[d])
        return False

    def _why_masked(self, action: int) -> str:
        if action == self.fallback:
            return "the hover fallback is allowed only when no stop is"
        c, d = self.decode(action)
        table, reach = self._table()
        name = f"(stop {c}, dwell {self.dwells[d].label})"
        if not self.layout.valid[c]:
            return f"{name}: stop {c} does not exist ({self.layout.why_invalid[c]})"
        if reach[c] < 0:
            return f"{name}: no way leads from here to stop {c}"
        if not table[c].any() and reach[c] + 1 - (reach[c] > 0) <= self.steps_left():
            return f"{name}: every node stop {c} covers is already served"
        return f"{name}: the way ({reach[c]} steps) and the dwell do not fit the {self.steps_left()} steps left"

    def next_action(self) -> Any:
        """The next kernel action of the current decision; None when it is carried out (and
        before the first decision)."""
        if self.move is None:
            return None
        action = self.move.next_action(self.env)
        if action is None:
            self.site = self.move.site_after
            self.move = None
        return action


class HoverOnce:
    """The fallback decision: one hover step where the AUV is."""

    def __init__(self, hover_action: Any, site: int | None):
        self._action = hover_action
        self.site_after = site
        self._done = False

    def next_action(self, env: Any) -> Any:
        if self._done:
            return None
        self._done = True
        return self._action


# ----------------------------------------------------------------------------- the env


class StopEnvBase(gym.Env):
    """The Gymnasium side of both worlds' stop-choice environments (see
    :class:`planners.stops.StopChoiceEnv` for the contract). A subclass builds ``self.env`` (the
    kernel env), ``self.settings`` and defines :meth:`build_layout`."""

    env: Any
    settings: Any

    def _init_spaces(self) -> None:
        self.metadata = {"render_modes": list(self.env.metadata["render_modes"]),
                         "render_fps": self.env.metadata.get("render_fps", 4)}
        self.render_mode = self.env.render_mode
        self.scenario = self.env.scenario
        n_candidates = self.n_candidates
        self.action_space = spaces.Discrete(n_candidates * len(self.settings.dwells) + 1)
        self.observation_space = spaces.Box(-1.0, 1.0, (self._observation_size(),), dtype=np.float32)
        self._layouts: dict[str, Any] = {}
        self._episode: StopEpisode | None = None
        self._done = True
        self.kernel_actions: list[Any] = []

    # subclass hooks
    @property
    def n_candidates(self) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _observation_size(self) -> int:
        """The length of the observation: the kernel's vector observation, then
        :data:`CANDIDATE_FEATURES` per candidate (a fleet's env adds its other AUVs)."""
        return int(self.env.observation_space.shape[0]) + CANDIDATE_FEATURES * self.n_candidates

    @classmethod
    def build_layout(cls, env: Any, settings: Any) -> Any:  # pragma: no cover - abstract
        """The stops layout of the kernel env's current layout."""
        raise NotImplementedError

    # ------------------------------------------------------------------ layouts

    def stops_layout(self) -> Any:
        """The stops layout of the current node layout (built once, the last
        :data:`~swiptopt.env.LAYOUT_CACHE_SIZE` kept)."""
        return cached_layout(self._layouts, self.env.scenario, lambda: self.build_layout(self.env, self.settings))

    # ------------------------------------------------------------------ gym API

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset the kernel env (the same seed and options) and return the first decision's
        observation; ``info`` holds the kernel reset's info."""
        super().reset(seed=seed)
        _, kernel_info = self.env.reset(seed=seed, options=options)
        self.scenario = self.env.scenario
        self._episode = StopEpisode(self.stops_layout(), self.env, self.settings.dwells, self.settings.masked_action)
        self._done = False
        self.kernel_actions = []
        return self._episode.observation(), dict(kernel_info)

    def step(self, action: Any):
        if self._done or self._episode is None:
            raise RuntimeError("call reset() before step() (the episode has ended)")
        episode = self._episode
        masked = episode.start(action)
        stop, dwell = episode.last_decision
        move = episode.move
        total = 0.0
        parts = dict.fromkeys(K.REWARD_PART_NAMES, 0.0)
        steps = 0
        terminated = truncated = False
        kernel_info: dict[str, Any] = {}
        while True:
            a = episode.next_action()
            if a is None:
                break
            _, reward, terminated, truncated, kernel_info = self.env.step(a)
            self.kernel_actions.append(a)
            total += reward
            for name, value in kernel_info["reward_parts"].items():
                parts[name] += value
            steps += 1
            if terminated or truncated:
                break
        if steps == 0:  # the masks allow only decisions that take a step
            raise AssertionError(f"action {action!r} took no kernel step")  # pragma: no cover
        info: dict[str, Any] = {
            "kernel_steps": steps,
            "reward_parts": parts,
            "stop": stop,
            "dwell": dwell,
            "masked": masked,
            "given_up": bool(getattr(move, "given_up", False)),
        }
        if terminated or truncated:
            self._done = True
            info[INFO_KEY] = kernel_info[INFO_KEY]
        return episode.observation(), total, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """The allowed actions now (:meth:`StopEpisode.action_masks`), what
        ``sb3_contrib.common.maskable.utils.get_action_masks`` reads."""
        if self._episode is None:
            raise RuntimeError("call reset() before action_masks()")
        return self._episode.action_masks()

    def episode_metrics(self) -> Any:
        """The kernel episode's metrics so far."""
        return self.env.episode_metrics()

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()


# ----------------------------------------------------------------------------- the adapter


class StopChoicePolicy:
    """A stop-choice model (a trained ``sb3_contrib.MaskablePPO``, or anything with
    ``predict(obs, deterministic=..., action_masks=...)``) as a policy on the plain kernel
    env, for :func:`swiptopt.evaluate` and the benchmark.

    ``begin_episode(env, obs, info)`` takes the unwrapped kernel env after its reset;
    ``predict(obs)`` then returns one kernel action per call: while a decision is being carried
    out, its next move or hover; when it is done, the model decides again from the stop
    observation and masks of the kernel env's state (the same :class:`StopEpisode` the
    environment runs). So ``evaluate(policy, kernel_env, ...)`` plays exactly the episodes the
    model plays in the stop environment on the same seeds. The kernel ``obs`` argument is not
    used (the stop observation is rebuilt from the env's state).

    ``env_class`` and ``settings``: the stop environment's class and settings the model was
    trained with; :meth:`from_env` copies them from a stop environment.
    """

    def __init__(self, model: Any, env_class: type, settings: Any, *, deterministic: bool = True):
        if not hasattr(model, "predict"):
            raise ConfigError(f"model {type(model).__name__} has no predict(obs, deterministic, action_masks)", "model")
        self.model = model
        self.env_class = env_class
        self.settings = settings
        self.deterministic = deterministic
        self._layouts: dict[str, Any] = {}
        self._episode: StopEpisode | None = None

    @classmethod
    def from_env(cls, model: Any, env: Any, *, deterministic: bool = True) -> StopChoicePolicy:
        """The adapter for a model trained on the stop environment ``env`` (its class and settings)."""
        base = getattr(env, "unwrapped", env)
        return cls(model, type(base), base.settings, deterministic=deterministic)

    def begin_episode(self, env: Any, obs: Any = None, info: Any = None) -> None:
        key = layout_key(env.scenario)
        layout = self._layouts.get(key)
        if layout is None:
            layout = self._layouts[key] = self.env_class.build_layout(env, self.settings)
            if len(self._layouts) > LAYOUT_CACHE_SIZE:
                self._layouts.pop(next(iter(self._layouts)))
        self._episode = StopEpisode(layout, env, self.settings.dwells, self.settings.masked_action)

    def predict(self, obs: Any, deterministic: bool = True) -> Any:
        """The next kernel action (see the class docstring). The model decides with this
        adapter's ``deterministic`` (set at construction), not the argument: the benchmark
        always asks for greedy actions of the kernel policy."""
        episode = self._episode
        if episode is None:
            raise RuntimeError("call begin_episode(env, obs, info) after each reset (swiptopt.evaluate does)")
        action = episode.next_action()
        while action is None:
            decision = self.model.predict(
                episode.observation(), deterministic=self.deterministic, action_masks=episode.action_masks()
            )
            decision = decision[0] if isinstance(decision, tuple) else decision
            episode.start(decision)
            action = episode.next_action()
            if action is None:  # the masks allow only decisions that take a step
                raise AssertionError(f"decision {decision!r} took no kernel step")  # pragma: no cover
        return action
