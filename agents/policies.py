"""Rule-based maintenance policies for ``BondGraphMaintenanceEnv``, with stable-baselines3's interface.

Every policy has ``predict(observation, state=None, episode_start=None, deterministic=True) ->
(actions, state)``, like an SB3 model, so that the same evaluation loop (``agents.evaluation.evaluate``
or SB3's ``evaluate_policy``) runs rules and learned agents alike:

- a single observation (a dict of arrays as ``env.step`` returns it, ``time_since_maintenance`` of
  shape (1,)) gives an action array of shape ();
- a batched observation (a dict whose arrays have a leading axis of n_envs, as a VecEnv returns it,
  ``time_since_maintenance`` of shape (n_envs, 1)) gives an action array of shape (n_envs,).

``deterministic`` is accepted and ignored (the rules are deterministic). ``episode_start`` (bool per
env) clears a policy's per-episode memory (only ``Periodic`` has one). The returned ``state`` is None
except for ``Periodic`` (see there).

Every policy carries on (action 0) while the machine is down (``maintenance_in_progress``), since the
environment ignores orders then anyway; so every non-zero action a policy returns is carried out.

Policies are built from the environment (a gymnasium env, wrapped or not, an SB3 ``VecEnv`` or a
gymnasium vector env) or from an ``ActionMap``, which says which action index is the corrective action
or the replacement of which component. Given an observation without a key it needs, a policy raises
``ValueError`` naming the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ea_gym.env.events import Action, ActionKind

__all__ = ["Policy", "ActionMap", "RulePolicy", "RunToFailure", "Periodic", "RulThreshold", "Oracle", "CorrectiveBand", "wear_fraction"]


@dataclass(frozen=True)
class ActionMap:
    """The environment's action indices by meaning.

    Attributes:
        action_meanings: ``env.unwrapped.action_meanings``: "carry on", then "corrective action on
            <c>" and "replace <c>" for each maintainable component c.
        components: ``env.unwrapped.maintainable_components``.
        diagnosis_classes: ``env.unwrapped.diagnosis_classes``: "none", then components.
        obs_mode: the environment's observation mode ("phm", "sensors", "oracle"), None if unknown.
        nominal_positions: each component's nominal value as a position in its safe range (0 the lower
            limit, 1 the upper: the coordinate of ``parameter_estimate``), None if unknown.
        elements: ``env.unwrapped.elements``: the bond-graph elements whose EA ``observation["ea"]``
            holds, in its order; None if unknown.
    """

    action_meanings: tuple[str, ...]
    components: tuple[str, ...]
    diagnosis_classes: tuple[str, ...]
    obs_mode: str | None = None
    nominal_positions: tuple[float, ...] | None = None
    elements: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "action_meanings", tuple(self.action_meanings))
        object.__setattr__(self, "components", tuple(self.components))
        object.__setattr__(self, "diagnosis_classes", tuple(self.diagnosis_classes))
        if not self.action_meanings or self.action_meanings[0] != str(Action(ActionKind.CARRY_ON)):
            raise ValueError(f"action 0 must be 'carry on', got action meanings {self.action_meanings}")
        if not self.diagnosis_classes or self.diagnosis_classes[0] != "none":
            raise ValueError(f"diagnosis class 0 must be 'none', got {self.diagnosis_classes}")
        for c in self.components:
            self.replace(c)
            self.corrective(c)
        unknown = [c for c in self.diagnosis_classes[1:] if c not in self.components]
        if unknown:
            raise ValueError(f"diagnosis classes {unknown} are not maintainable components {self.components}")
        if self.nominal_positions is not None:
            positions = tuple(map(float, self.nominal_positions))
            if len(positions) != len(self.components) or not all(0.0 < p < 1.0 for p in positions):
                raise ValueError(
                    f"nominal_positions must hold one position strictly inside (0, 1) per component {self.components}, got {positions}"
                )
            object.__setattr__(self, "nominal_positions", positions)
        if self.elements is not None:
            object.__setattr__(self, "elements", tuple(self.elements))

    def _index(self, action: Action) -> int:
        try:
            return self.action_meanings.index(str(action))
        except ValueError:
            raise ValueError(f"no action {str(action)!r} among {self.action_meanings}") from None

    def replace(self, component: str) -> int:
        """Index of the action "replace <component>"."""
        return self._index(Action(ActionKind.REPLACE, component))

    def corrective(self, component: str) -> int:
        """Index of the action "corrective action on <component>"."""
        return self._index(Action(ActionKind.CORRECTIVE, component))

    @classmethod
    def from_env(cls, env: Any) -> ActionMap:
        """From a gymnasium env (wrapped or not), an SB3 VecEnv or a gymnasium vector env."""
        if isinstance(env, ActionMap):
            return env
        base = getattr(env, "unwrapped", env)
        names = ("action_meanings", "maintainable_components", "diagnosis_classes")
        optional = ("config", "nominal_parameters", "safe_limits", "elements")
        if all(hasattr(base, name) for name in names):
            values = [getattr(base, name) for name in names]
            config, nominal, limits, elements = (getattr(base, name, None) for name in optional)
        elif hasattr(env, "get_attr"):  # vectorised environments: ask the first one
            try:
                values = [_first_attr(env, name) for name in names]
            except Exception as error:  # re-raised with the reason
                raise TypeError(f"cannot read {names} from {type(env).__name__}: {error}") from error
            config, nominal, limits, elements = (_optional_attr(env, name) for name in optional)
        else:
            raise TypeError(
                f"need a BondGraphMaintenanceEnv (or a wrapper / vector env of one) or an ActionMap, got {type(env).__name__}"
            )
        positions = None
        if nominal is not None and limits is not None:
            positions = tuple((nominal[c] - limits[c][0]) / (limits[c][1] - limits[c][0]) for c in values[1])
        meanings, components, classes = values
        return cls(meanings, components, classes, obs_mode=getattr(config, "obs_mode", None), nominal_positions=positions, elements=elements)


def _first_attr(env: Any, name: str) -> Any:
    values = env.get_attr(name)
    return values[0]


def _optional_attr(env: Any, name: str) -> Any:
    try:
        return _first_attr(env, name)
    except Exception:  # optional: older or foreign environments lack it
        return None


def _need(observation: Any, keys: Sequence[str], who: str, hint: str = "") -> tuple[dict[str, np.ndarray], bool]:
    """The observation's ``keys`` as float arrays with a leading env axis, and whether it was batched.

    Batching is told by ``time_since_maintenance``: shape (1,) is one observation, (n_envs, 1) a batch.
    """
    if not isinstance(observation, Mapping):
        raise TypeError(f"{who} needs a Dict observation (a mapping of arrays), got {type(observation).__name__}")
    for key in ("time_since_maintenance", *keys):
        if key not in observation:
            raise ValueError(
                f"{who} needs observation key {key!r}{hint}; the observation has keys {sorted(observation)}"
            )
    clock = np.asarray(observation["time_since_maintenance"])
    if clock.ndim == 1 and clock.shape == (1,):
        batched, n = False, 1
    elif clock.ndim == 2 and clock.shape[1] == 1:
        batched, n = True, clock.shape[0]
    else:
        raise ValueError(
            "observation key 'time_since_maintenance' must have shape (1,) (one observation) or "
            f"(n_envs, 1) (a batch), got {clock.shape}"
        )
    out = {}
    for key in dict.fromkeys(("time_since_maintenance", *keys)):
        value = np.asarray(observation[key], dtype=float)
        if not batched:
            value = value[None]
        if value.ndim != 2 or value.shape[0] != n:
            expected = f"({n}, ...)" if batched else "(d,)"
            raise ValueError(f"observation key {key!r} must have shape {expected}, got {np.shape(observation[key])}")
        out[key] = value
    return out, batched


def _output(actions: np.ndarray, batched: bool) -> np.ndarray:
    actions = np.asarray(actions, dtype=np.int64)
    return actions if batched else actions.reshape(())


def _starts(episode_start: Any, n: int) -> np.ndarray:
    if episode_start is None:
        return np.zeros(n, dtype=bool)
    starts = np.asarray(episode_start, dtype=bool).reshape(-1)
    if starts.size == 1 and n > 1:
        starts = np.repeat(starts, n)
    if starts.shape != (n,):
        raise ValueError(f"episode_start must hold one bool per env ({n}), got shape {np.shape(episode_start)}")
    return starts


class Policy(Protocol):
    """A maintenance policy as the evaluation, the benchmark and the teachers call it: SB3's ``predict``
    (the rules here, ``agents.training.NormalizedPolicy``, an SB3 model)."""

    def predict(
        self, observation: Mapping[str, Any], state: Any = None, episode_start: Any = None, deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]: ...


class RulePolicy:
    """Base class: SB3-style ``predict`` over single or batched observations."""

    #: observation keys the rule reads (besides ``time_since_maintenance``, always needed for batching)
    needs: tuple[str, ...] = ()
    hint: str = ""

    def predict(
        self,
        observation: Mapping[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Actions for the observation: shape () for one observation, (n_envs,) for a batch."""
        obs, batched = _need(observation, self.needs, type(self).__name__, self.hint)
        n = obs["time_since_maintenance"].shape[0]
        actions, state = self._act(obs, n, state, _starts(episode_start, n))
        return _output(actions, batched), state

    def reset(self) -> None:
        """Forget any per-episode memory (same as passing ``episode_start=True``)."""

    def _act(self, obs: dict[str, np.ndarray], n: int, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        raise NotImplementedError


class RunToFailure(RulePolicy):
    """Always carry on (action 0): no maintenance until a component fails.

    With ``continue_after_failure=True`` the environment then forces the replacement of the failed
    component (``costs.failure`` plus ``costs.failure_downtime`` steps down) and the episode goes on;
    otherwise the failure ends the episode. ``env`` is accepted for a uniform signature and unused.
    """

    def __init__(self, env: Any = None):
        pass

    def _act(self, obs: dict[str, np.ndarray], n: int, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        return np.zeros(n, dtype=np.int64), None

    def __repr__(self) -> str:
        return "RunToFailure()"


class Periodic(RulePolicy):
    """Block replacement by age: when ``time_since_maintenance`` reaches ``period`` seconds, replace
    every component in ``components`` (default all maintainable ones), one after the other.

    It reads no PHM output (it works in every obs_mode, ``"sensors"`` included): only
    ``time_since_maintenance`` and ``maintenance_in_progress``. A replacement resets the environment's
    ``time_since_maintenance`` and stops the machine for ``costs.replace_downtime`` steps, during which
    orders are ignored; so a round is a sequence: replace the first component, wait while the machine is
    down, replace the next, and so on. A failure (which also resets ``time_since_maintenance``) in the
    middle of a round does not stop it. The next round starts ``period`` s after the last maintenance.

    Memory: the position in the current round, per env, as an int array of shape (n_envs,) (n_envs = 1
    for a single observation): -1 when no round is in progress, else the index in ``components`` of the
    next component to replace. It is returned as ``state``; a ``state`` passed back in (as SB3's
    ``evaluate_policy`` does) is used, and with ``state=None`` the policy uses its own copy of the last
    state it returned (so a plain loop that drops the state works too, for one env or one VecEnv at a
    time). ``episode_start`` True for an env (or ``reset()``) ends its round.

    Args:
        env: the environment (or an ActionMap).
        period: seconds of ``time_since_maintenance`` between rounds, > 0.
        components: the components replaced in each round, in order; default all maintainable ones.
    """

    needs = ("maintenance_in_progress",)

    def __init__(self, env: Any, period: float, components: Sequence[str] | None = None):
        if not (isinstance(period, (int, float)) and math.isfinite(period) and period > 0):
            raise ValueError(f"period must be a positive number of seconds, got {period!r}")
        self.actions = ActionMap.from_env(env)
        self.period = float(period)
        self.components = tuple(self.actions.components if components is None else components)
        if not self.components:
            raise ValueError("components must name at least one maintainable component")
        self._round = np.array([self.actions.replace(c) for c in self.components], dtype=np.int64)
        self._position: np.ndarray | None = None

    def reset(self) -> None:
        self._position = None

    def _act(self, obs: dict[str, np.ndarray], n: int, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        if state is not None:
            position = np.array(state, dtype=np.int64).reshape(-1)
            if position.shape != (n,):
                raise ValueError(f"Periodic: state must be an int array of shape ({n},), got shape {np.shape(state)}")
        elif self._position is not None and self._position.shape == (n,):
            position = self._position.copy()
        else:
            position = np.full(n, -1, dtype=np.int64)
        position[starts] = -1
        if np.any((position < -1) | (position >= len(self._round))):
            raise ValueError(f"Periodic: state values must be in [-1, {len(self._round) - 1}], got {position}")
        down = obs["maintenance_in_progress"][:, 0] > 0.5
        due = obs["time_since_maintenance"][:, 0] >= self.period
        position = np.where(~down & (position < 0) & due, 0, position)  # a new round
        act = ~down & (position >= 0)
        actions = np.where(act, self._round[np.clip(position, 0, None)], 0)
        position = np.where(act, position + 1, position)
        position = np.where(position >= len(self._round), -1, position)
        self._position = position.copy()
        return actions, position

    def __repr__(self) -> str:
        return f"Periodic(period={self.period:g}, components={self.components})"


class RulThreshold(RulePolicy):
    """Condition-based maintenance on the PHM outputs: when the RUL interval's lower bound
    (``observation["rul"][1]``, s) is below ``threshold`` and the diagnosis believes in some fault,
    replace the component it believes most among the fault classes (``action="replace"``) or apply a
    corrective action on it for this step (``action="corrective"``); otherwise carry on. A diagnosis
    that is all "none" never acts.

    ``threshold=math.inf`` acts as soon as the diagnosis believes in a fault (after the chain's alarm), whatever its RUL. Needs the keys
    ``diagnosis`` and ``rul``: obs_mode ``"phm"`` (estimated) or ``"oracle"`` (true; see ``Oracle``).

    Args:
        env: the environment (or an ActionMap). An env with obs_mode "sensors" is refused.
        threshold: seconds, > 0 (inf allowed).
        action: "replace" or "corrective".
    """

    needs = ("maintenance_in_progress", "diagnosis", "rul")
    hint = " (make the env with obs_mode='phm' or 'oracle'; 'sensors' has no diagnosis or RUL)"

    def __init__(self, env: Any, threshold: float, action: str = "replace"):
        if not (isinstance(threshold, (int, float)) and not math.isnan(threshold) and threshold > 0):
            raise ValueError(f"threshold must be a positive number of seconds (inf allowed), got {threshold!r}")
        if action not in ("replace", "corrective"):
            raise ValueError(f"action must be 'replace' or 'corrective', got {action!r}")
        self.actions = ActionMap.from_env(env)
        self._check_mode(self.actions.obs_mode)
        self.threshold = float(threshold)
        self.action = action
        order = self.actions.replace if action == "replace" else self.actions.corrective
        self._class_action = np.array([0] + [order(c) for c in self.actions.diagnosis_classes[1:]], dtype=np.int64)

    def _check_mode(self, mode: str | None) -> None:
        if mode == "sensors":
            raise ValueError(
                f"{type(self).__name__} reads the diagnosis and the RUL, which obs_mode 'sensors' does not give; "
                "make the env with obs_mode='phm' (or 'oracle')"
            )

    def _act(self, obs: dict[str, np.ndarray], n: int, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        diagnosis, rul = obs["diagnosis"], obs["rul"]
        classes = len(self.actions.diagnosis_classes)
        if diagnosis.shape[1] != classes:
            raise ValueError(
                f"observation key 'diagnosis' has {diagnosis.shape[1]} classes, expected {classes} "
                f"{self.actions.diagnosis_classes}"
            )
        if rul.shape[1] != 3:
            raise ValueError(f"observation key 'rul' must hold [point, low, high], got {rul.shape[1]} values")
        # the suspect is the fault class the chain believes most; "none" may still outweigh it (a
        # network unsure of a young fault), but a finite RUL already says the chain tracks a fault
        named = 1 + np.argmax(diagnosis[:, 1:], axis=1)
        down = obs["maintenance_in_progress"][:, 0] > 0.5
        act = ~down & (diagnosis[:, 1:].sum(axis=1) > 0) & (rul[:, 1] < self.threshold)
        return np.where(act, self._class_action[named], 0), None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(threshold={self.threshold:g}, action={self.action!r})"


class Oracle(RulThreshold):
    """``RulThreshold``'s rule on the true state: MUST be paired with ``obs_mode="oracle"``, whose
    ``diagnosis`` is the one-hot of the truly degrading component (once its fault has arrived) and whose
    ``rul`` is the true RUL (three times). The reference lower bound of a condition-based policy: what
    a perfect PHM chain would allow.

    Built from an env whose obs_mode is known, it refuses any mode but "oracle"; built from an
    ActionMap without obs_mode, the pairing is the caller's responsibility (the observation keys are the
    same as in "phm").
    """

    hint = " (make the env with obs_mode='oracle')"

    def _check_mode(self, mode: str | None) -> None:
        if mode is not None and mode != "oracle":
            raise ValueError(f"Oracle reads the true faulty component and RUL: make the env with obs_mode='oracle', not {mode!r}")


def wear_fraction(position: np.ndarray, nominal: np.ndarray) -> np.ndarray:
    """The way a parameter has gone from its nominal value toward the safe limit on its side: 0 at
    nominal, 1 at the limit. ``position`` and ``nominal`` are positions in the safe range (0 the lower
    limit, 1 the upper, as in ``parameter_estimate``), broadcasting against each other."""
    return np.where(position < nominal, (nominal - position) / nominal, (position - nominal) / (1.0 - nominal))


class CorrectiveBand(RulePolicy):
    """Condition-based corrective maintenance on the parameter estimate: while the suspect's estimated
    parameter has gone more than its ``band`` of the way from its nominal value to the safe limit on
    its side, apply a corrective action on it (one step, which moves it back toward nominal); otherwise
    carry on. It never replaces: the corrective actions hold a wearing component inside its band.

    The suspect is the fault class the diagnosis believes most among the fault classes, when its share
    of their belief is at least ``share`` (with three fault classes, 0.4 acts on a leaning the chain's
    own confidence gate, 0.75, would still withhold: a corrective step on the wrong component costs
    one unit, a failure four hundred). ``parameter_estimate`` is each component's position in its safe
    range; the band is measured from the nominal position (``ActionMap.nominal_positions``), so an
    estimate of 0.9 is 60 % of the way up for a nominal at 0.75.

    One band for every component, or one per component: a component whose estimate scatters widely
    needs a wider margin to its limit (on the spring-mass-damper at 1 % noise, the light damper's
    estimate is off by 12 % of its safe range (rms), the spring's and the mass's by 1.7 and 1.8 %).

    A component's estimate is only as good as the excitation it had: the damper's estimate error is 18 %
    of its safe range (rms) in the fifth of steps where its EA is lowest (below 0.003 J per 1-s step) and
    6 % in the fifth where it is highest. ``quiet_band`` holds a component in a narrower band while its
    EA over the last step is below ``quiet_activity``, so that the wide band suits the well excited
    steps alone.

    Needs the keys ``diagnosis``, ``parameter_estimate`` and ``maintenance_in_progress`` (and ``ea``
    with a ``quiet_band``): obs_mode ``"phm"`` (estimated) or ``"oracle"`` (true).

    Args:
        env: the environment (or an ActionMap with ``nominal_positions``, and ``elements`` for a
            ``quiet_band``). "sensors" is refused.
        band: fraction of the way from nominal to the limit, in (0, 1): one for every component, or a
            mapping from each of the diagnosis' fault classes (components) to its own.
        share: the suspect's least share of the fault classes' belief, in (0, 1].
        quiet_band: mapping from fault classes to the band (in (0, 1)) that replaces theirs while the
            component's EA over the last step is below ``quiet_activity``; None: always ``band``.
        quiet_activity: EA (J) over a step below which a component counts as quiet, > 0.
    """

    needs: tuple[str, ...] = ("maintenance_in_progress", "diagnosis", "parameter_estimate")  # "ea" too with a quiet_band
    hint = " (make the env with obs_mode='phm' or 'oracle')"

    def __init__(
        self,
        env: Any,
        band: float | Mapping[str, float],
        share: float = 0.4,
        quiet_band: Mapping[str, float] | None = None,
        quiet_activity: float = 0.003,
    ):
        if not (isinstance(share, (int, float)) and 0 < share <= 1):
            raise ValueError(f"share must be in (0, 1], got {share!r}")
        if not (isinstance(quiet_activity, (int, float)) and math.isfinite(quiet_activity) and quiet_activity > 0):
            raise ValueError(f"quiet_activity must be an EA in J, finite and > 0, got {quiet_activity!r}")
        self.actions = ActionMap.from_env(env)
        if self.actions.obs_mode == "sensors":
            raise ValueError("CorrectiveBand reads the diagnosis and the parameter estimates, which obs_mode 'sensors' does not give")
        if self.actions.nominal_positions is None:
            raise ValueError("CorrectiveBand needs the components' nominal positions: pass the env or an ActionMap with nominal_positions")
        classes = self.actions.diagnosis_classes[1:]
        self.band, self._bands = _bands(band, classes)
        self.share = float(share)
        index = [self.actions.components.index(c) for c in classes]
        self._corrective = np.array([self.actions.corrective(c) for c in classes], dtype=np.int64)
        self._estimate_column = np.array(index)
        self._nominal = np.array(self.actions.nominal_positions)[index]
        self.quiet_band, self.quiet_activity = dict(quiet_band or {}), float(quiet_activity)
        self._quiet_bands = None
        if self.quiet_band:
            unknown = sorted(set(self.quiet_band) - set(classes))
            if unknown:
                raise ValueError(f"quiet_band: {unknown} are not among the fault classes {list(classes)}")
            if self.actions.elements is None:
                raise ValueError("a quiet_band needs the elements of observation['ea']: pass the env or an ActionMap with elements")
            self._quiet_bands = np.array([
                _fraction(self.quiet_band[c], f"quiet_band[{c!r}]") if c in self.quiet_band else b for c, b in zip(classes, self._bands)
            ])
            self._element_column = np.array([self.actions.elements.index(c) for c in classes])
            self.needs = (*type(self).needs, "ea")

    def _act(self, obs: dict[str, np.ndarray], n: int, state: Any, starts: np.ndarray) -> tuple[np.ndarray, Any]:
        diagnosis, estimate = obs["diagnosis"], obs["parameter_estimate"]
        if diagnosis.shape[1] != len(self._corrective) + 1:
            raise ValueError(
                f"observation key 'diagnosis' has {diagnosis.shape[1]} classes, expected {self.actions.diagnosis_classes}"
            )
        faults = diagnosis[:, 1:]
        suspect = np.argmax(faults, axis=1)
        rows = np.arange(n)
        share = faults[rows, suspect] / np.maximum(faults.sum(axis=1), 1e-12)
        way = wear_fraction(estimate[rows, self._estimate_column[suspect]], self._nominal[suspect])
        down = obs["maintenance_in_progress"][:, 0] > 0.5
        bands = self._bands[suspect]
        if self._quiet_bands is not None:
            quiet = obs["ea"][rows, self._element_column[suspect]] < self.quiet_activity
            bands = np.where(quiet, self._quiet_bands[suspect], bands)
        act = ~down & (faults.sum(axis=1) > 0) & (share >= self.share) & (way > bands)
        return np.where(act, self._corrective[suspect], 0), None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(band={self.band!r}, share={self.share:g})"


def _fraction(value: Any, name: str) -> float:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0 < value < 1):
        raise ValueError(f"{name} must be a fraction of the way to the limit in (0, 1), got {value!r}")
    return float(value)


def _bands(band: float | Mapping[str, float], classes: Sequence[str]) -> tuple[float | dict[str, float], np.ndarray]:
    """``band`` as given (a float, or a dict in the classes' order) and as one band per fault class."""
    if not isinstance(band, Mapping):
        value = _fraction(band, "band")
        return value, np.full(len(classes), value)
    unknown, missing = sorted(set(band) - set(classes)), [c for c in classes if c not in band]
    if unknown or missing:
        raise ValueError(f"band: one band for each of the fault classes {list(classes)}; unknown {unknown}, missing {missing}")
    given = {c: _fraction(band[c], f"band[{c!r}]") for c in classes}
    return given, np.array(list(given.values()))
