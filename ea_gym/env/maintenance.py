"""Maintenance of a degrading machine with the Energy-Activity PHM chain online."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any, SupportsInt, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.env.actions import DEFAULT_ACTION_KINDS, HandlerFactory
from ea_gym.env.config import EnvConfig, check_reset_arguments, env_config
from ea_gym.env.core import MaintenanceCore
from ea_gym.env.infos import check_info_layout
from ea_gym.env.observations import Observation
from ea_gym.env.specs import HorizonSpec
from ea_gym.model_files import load_system
from ea_gym.models import MODELS, ParameterError, SystemModel


class BondGraphMaintenanceEnv(HorizonSpec, gym.Env[Observation, np.int64]):
    """
    ## Description

    A machine modelled as a bond graph (by default the paper's spring-mass-damper) runs under a random
    load while one of its components degrades: its parameter drifts toward a safe limit from a random
    time on, at a random rate (linear drift, gamma or Wiener process). In parallel, a fault-free
    reference model runs under the same load, and the Energy-Activity PHM chain of the paper watches
    the noisy sensors: it computes every element's Energy Activity (EA) and EAI, detects a fault from
    the EA residuals, isolates the component with a neural network on STFT and energy-balance features,
    estimates its parameter (by default a Kalman filter per hypothesis tracking the parameter and its
    drift; `phm=PHMConfig(estimator_kind="ea_inversion")` for the paper's EA inversion) and carries it
    to the safe limits for the remaining useful life (RUL). The agent decides the maintenance: carry on, a corrective action on a component,
    or its replacement. Failure (a parameter outside its safe limits) is expensive; so are downtime,
    replacements and corrective actions.

    In v1 (`ea_gym/SpringMassDamper-v1`, `ea_gym/BondGraphMaintenance-v1`: the settings `V1_SETTINGS` of
    `ea_gym.env`) every part ages at once, as on a real machine: each part starts from its own value
    within a tolerance of nominal, ages slowly in the background from the start, and has its own fault
    (its `WearConfig`'s process, with a direction, arrival and rate drawn per part), so that faults
    overlap. Each machine is commissioned at its reset (and after a replacement): it runs healthy for a while,
    its parts' own values are fitted from the record, and the reference model and the chain take them, so the
    chain compares the machine with itself, not with the catalogue. The chain runs the joint filter (every
    part's estimate, variance and drift at once) with the model-fit test, and the observation gives every
    part's degrading probability and RUL.

    ## Action Space

    `Discrete(1 + 2n)` for the n maintainable components (`env.unwrapped.action_meanings`; the typed
    actions, `ea_gym.env.events.Action`, in `env.unwrapped.actions`):

    - 0: carry on
    - 1..n: corrective action on component i for this step: its parameter moves toward nominal (and
      past it, if continued) at `corrective_rate` x its safe range per second; costs `costs.corrective`
    - n+1..2n: replace component i: back to nominal, `costs.replacement`, and `costs.replace_downtime`
      steps without production

    Orders given while the machine is down are ignored. Each kind of action is done by its handler
    (`ea_gym.env.actions`); `action_kinds` adds kinds after these, whose actions take the next indices.

    ## Observation Space

    A `Dict`, float32 arrays (E elements, in `env.unwrapped.elements`; C = R/C/I components; K = 1 + n classes):

    | key | shape | meaning |
    |---|---|---|
    | `ea` | (E,) | Energy Activity of every element over the step's window (J) |
    | `eai` | (C,) | Energy Activity Index of every component |
    | `residual` | (E,) | relative EA residual, (EA - EA_ref) / EA_ref |
    | `diagnosis` | (K,) | class probabilities, classes in `env.unwrapped.diagnosis_classes` |
    | `parameter_estimate` | (n,) | each component's estimated parameter, its position in the safe range (0 lower limit, 1 upper), in [-1, 2] |
    | `rul` | (3,) | estimated RUL (s): point, interval low, interval high, clipped to [0, `rul_max`] |
    | `time_since_maintenance` | (1,) | s |
    | `maintenance_in_progress` | (1,) | 1 while the machine is down |

    v1 replaces `diagnosis` (one class) with each part's degrading probability and gives a RUL per part:

    | key | shape | meaning |
    |---|---|---|
    | `ea`, `eai`, `residual`, `time_since_maintenance`, `maintenance_in_progress` | as v0 | as v0 |
    | `degrading` | (n,) | each part's probability of degrading (its drift beyond `JointFilterConfig.degrading_rate` of its safe span per s) |
    | `parameter_estimate` | (n,) | each part's joint estimate, its position in the safe range, in [-1, 2] |
    | `rul` | (n, 3) | each part's RUL (s) from its drift, named degrading or not: point, low, high, clipped to [0, `rul_max`] |

    `obs_mode` selects the information regime: `"phm"` (the full chain, above), `"sensors"` (measured
    signal features only: no `diagnosis`, `degrading`, `parameter_estimate` or `rul`) or `"oracle"` (the
    same keys as `"phm"`, holding the truth: the faulty component (v1: 1 for each part whose fault has
    arrived, 0 for the others), the true parameters and the true RUL (v1: each part's)).

    ## Rewards

    Minus the step's cost (>= 0), from `CostModel`: corrective action per step, replacement, failure,
    and lost production per step down. `info["cost"]` has the breakdown.

    ## Starting State

    All components at nominal, the machine at rest, a new random load (random-phase multisine around
    the nominal load), and a fault drawn: which component, when it arrives, its direction and rate.
    v1: every wearing part drawn within `tolerance` x its safe span of nominal (uniform; default 1/8),
    then its own fault (direction, arrival, rate), from the system's generator, part by part; then
    `commission_seconds` of healthy operation (the load's clock moves on, the wear's does not) from which the
    machine is commissioned. The first observation's `parameter_estimate` is the commissioned values.

    ## Episode End

    Termination when a parameter leaves its safe limits (unless `continue_after_failure=True`: then a
    forced replacement with `costs.failure_downtime` steps down, and the episode goes on). Truncation
    after `horizon` steps, the environment's own (no TimeLimit wrapper); `env.spec.max_episode_steps` is
    the horizon (`ea_gym.env.specs`).

    ## Arguments

    ```python
    gymnasium.make("ea_gym/BondGraphMaintenance-v0", system="spring_mass_damper", config=None,
                   classifier=None, render_mode=None, action_kinds=DEFAULT_ACTION_KINDS, **overrides)
    ```

    - `config`: an `EnvConfig` (default `EnvConfig()`); every field can also be given as a keyword
      override: `obs_mode="phm"`, `step_seconds=1.0`, `window_seconds=None`, `noise=0.01`,
      `horizon=500`, `costs=CostModel()`, `wear=None`, `corrective_rate=0.02`,
      `continue_after_failure=False`, `rul_max=1000.0`, `sample_rate=100.0`, `load_std=(0.2, 0.4)`,
      `phm=None` (the chain's own settings, a `PHMConfig`).
    - `system`: a built-in model name, a model file's path (.yaml, .yml, .json; see `ea_gym.model_files`) or a
      `SystemModel` (bond graph with nominal values and safe limits).
    - `step_seconds`: degradation time per step; `window_seconds`: measured operation per step (default
      equal: continuous operation; a larger step is slow wear watched through periodic snapshots).
    - `noise`: sensor noise std as a fraction of each signal's RMS.
    - `wear`: `{component: WearConfig(...)}`; default every component with safe limits, linear drift.
    - `classifier`: a `FaultClassifier` or a path to one; default the network shipped for the system.
    - `render_mode`: `"rgb_array"` (recent EA, parameter estimate and RUL) or `"ansi"`.
    - `action_kinds`: the handlers of the action kinds in use, carrying on first (see `ea_gym.env.actions`);
      their order is the action table's.
    - `info_layout`: `"nested"` (the default: the dicts and texts below) or `"flat"` (one level of numbers,
      no events), for libraries that make a tensor of every info (TorchRL's `GymEnv`; `ea_gym.env.infos`).
    - v1's settings, `EnvConfig` fields like the others (v0 has them off): `concurrent_wear=True` (a wear
      process per part), `background_wear=2e-4` (every part ages by this fraction of the distance from
      nominal to its limit per s: 5000 s, ten default horizons, to its limit by background ageing alone,
      and at most 2e-4 of its safe span per s, below the joint filter's degrading rate, 1.5e-3: ageing,
      not a fault), `tolerance=0.125` (the parts' starting spread, fraction of the safe span either side
      of nominal), `commission_seconds=20.0` (the healthy record each machine is commissioned from at a reset
      and after a replacement: its parts' values to a median 0.1-0.5 % of their spans on the spring-mass-damper;
      0: none, the reference at nominal).

    `info["true_rul"]` is the true RUL (s) of the fault's mean trend (inf before it arrives); in v1 an
    array (n,), each part's mean trend (its background ageing, plus its fault once arrived) to its limit.

    ## Version History

    - v0: first version.
    - v1: every part ages at once (background ageing, a fault per part, overlapping), parts start within
      their tolerances, replaced parts too, and each machine is commissioned; the chain runs the joint filter
      and the model-fit test; the
      observation's `degrading` (n,) replaces `diagnosis`, `rul` is (n, 3) per part, `info["true_rul"]` (n,).
    """

    metadata = {"render_modes": ["rgb_array", "ansi"], "render_fps": 4}

    def __init__(
        self,
        system: str | os.PathLike[str] | SystemModel = "spring_mass_damper",
        config: EnvConfig | None = None,
        classifier: FaultClassifier | str | None = None,
        render_mode: str | None = None,
        action_kinds: Sequence[HandlerFactory] = DEFAULT_ACTION_KINDS,
        info_layout: str = "nested",
        **overrides: Any,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.info_layout = check_info_layout(info_layout)
        self.core = build_core(1, system, config, classifier, action_kinds, **overrides)
        self.config = self.core.config
        self.model = self.core.model
        self.render_mode = render_mode
        self.maintainable_components = self.core.components
        self.elements = self.core.elements
        self.diagnosis_classes = self.core.classes
        self.actions = self.core.actions
        self.action_meanings = self.core.action_meanings
        self.nominal_parameters = self.core.nominal_parameters
        self.safe_limits = self.core.safe_limits
        self.action_space = spaces.Discrete(len(self.action_meanings))
        self.observation_space = cast(spaces.Space[Observation], self.core.observer.space())
        self._history: list[dict[str, Any]] = []
        self._episode_over = True  # no episode before the first reset

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Observation, dict[str, Any]]:
        check_reset_arguments(seed, options, known=())
        super().reset(seed=seed)
        observation = self.core.reset([self.np_random])
        self._history = []
        self._episode_over = False
        return _first(observation), self.core.reset_info().system(0, self.info_layout)

    def step(self, action: SupportsInt) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        if self._episode_over:
            raise RuntimeError("step() needs reset() first: before the first reset and after an episode ends (terminated or truncated)")
        # an int in range (the usual action) needs none of the space's checks, which cost more than the rest of this method
        usual = (type(action) is int or isinstance(action, np.integer)) and 0 <= action < len(self.actions)
        if not usual and (isinstance(action, (bool, np.bool_)) or not self.action_space.contains(action)):
            raise ValueError(f"action must be an int in [0, {len(self.actions) - 1}] ({self.action_meanings}), got {action!r}")
        result = self.core.step(np.array([int(action)]), [self.np_random])
        observation = _first(result.observation)
        nested = result.info.system(0)  # rendering reads the nested layout
        info = nested if self.info_layout == "nested" else result.info.system(0, self.info_layout)
        self._history.append({"observation": observation, "info": nested, "action": int(action)})
        del self._history[:-120]
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        self._episode_over = terminated or truncated
        return observation, float(result.reward[0]), terminated, truncated, info

    def render(self) -> str | np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'ansi' to make()")
            return None
        from ea_gym.env.rendering import render_ansi, render_rgb

        return (render_rgb if self.render_mode == "rgb_array" else render_ansi)(self, self._history)


class SpringMassDamperEnv(BondGraphMaintenanceEnv):
    __doc__ = BondGraphMaintenanceEnv.__doc__

    def __init__(self, **kwargs: Any):
        if "system" in kwargs:
            raise TypeError("SpringMassDamper is the spring-mass-damper; use BondGraphMaintenance (same version) for another system")
        super().__init__(system="spring_mass_damper", **kwargs)


def build_core(
    n_systems: int,
    system: str | os.PathLike[str] | SystemModel = "spring_mass_damper",
    config: EnvConfig | None = None,
    classifier: FaultClassifier | str | os.PathLike[str] | None = None,
    action_kinds: Sequence[HandlerFactory] = DEFAULT_ACTION_KINDS,
    **overrides: Any,
) -> MaintenanceCore:
    """The step core of N environments from the environments' arguments: the system (a built-in
    model's name, a model file's path or a model), ``config`` with keyword ``overrides`` of its fields, the classifier
    (or a path to one) and the handlers of the action kinds in use."""
    if isinstance(system, (str, os.PathLike)):
        try:
            system = load_system(system)
        except ParameterError as exc:
            raise ValueError(f"system must be one of {sorted(MODELS)}, a model file or a SystemModel: {exc}") from None
    elif not isinstance(system, SystemModel):
        raise TypeError(f"system must be a model name, a model file's path or a SystemModel, got {type(system).__name__}")
    system.check_degradable()
    settings = env_config(config, **overrides)
    system.check_resolved(settings.sample_rate, "sample_rate")
    for name, bounds in system.safe_limits.items():  # the parts wear up to their limits
        for bound in bounds:
            system.check_resolved(settings.sample_rate, f"sample_rate (with {name} at its limit {bound:g})", {name: bound})
    if isinstance(classifier, (str, os.PathLike)):
        classifier = FaultClassifier.load(classifier)
    elif classifier is not None and not isinstance(classifier, FaultClassifier):
        raise TypeError(f"classifier must be a FaultClassifier, a path to one or None, got {type(classifier).__name__}")
    return MaintenanceCore(system, settings, n_systems, classifier, action_kinds=action_kinds)


def _first(batch: Observation) -> Observation:
    return {key: value[0] for key, value in batch.items()}
