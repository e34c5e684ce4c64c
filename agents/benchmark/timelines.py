"""One evaluation episode of a policy, recorded step by step for the timelines figure."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from agents.benchmark.settings import env_factory
from agents.policies import Policy
from ea_gym.env.events import Failure, parse_event
from ea_gym.files import finite_or_none

__all__ = ["record_timeline"]


def record_timeline(policy: Policy, obs_mode: str, seed: int, env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Step one episode of ``policy`` on ``obs_mode`` and record what the timelines show.

    The PHM chain's estimates come from a second environment in obs_mode "phm" stepped in lockstep
    with the same seed and the same actions (the dynamics do not depend on the obs_mode; the true
    parameters of the two are checked equal at every step), so a policy that sees no PHM output
    (sensors, oracle) is shown beside what the chain would have estimated on its episode.

    Returns JSON-ready lists over the episode's states (t = 0 after the reset, then after each step):
    ``t`` (s), ``component`` (the degrading one), ``true_position`` and ``estimated_position`` (its
    parameter as a position in its safe range: 0 lower limit, 1 upper; the estimate clipped to
    [-1, 2] by the environment), ``true_rul`` (s, None before the fault arrives), ``rul`` (the chain's
    [point, low, high], s, clipped to [0, rul_max]), ``down`` (machine down); and the events:
    ``actions`` ([t, meaning] of each action carried out, t the time it was given), ``failures``
    ([t, component]), with the episode's ``cost``.
    """
    env_kwargs = dict(env_kwargs or {})
    env = env_factory(obs_mode, **env_kwargs)()
    shadow = env_factory("phm", **env_kwargs)() if obs_mode != "phm" else None
    try:
        base = env.unwrapped
        core = base.core
        components = list(base.maintainable_components)
        limits = {c: base.safe_limits[c] for c in components}
        meanings = list(base.action_meanings)
        dt = float(base.config.step_seconds)
        observation, info = env.reset(seed=int(seed))
        phm_observation, phm_info = (observation, info) if shadow is None else shadow.reset(seed=int(seed))
        record: dict[str, Any] = {
            "seed": int(seed), "obs_mode": obs_mode, "components": components, "rul_max": float(base.config.rul_max),
            "t": [], "component": [], "true_position": [], "estimated_position": [], "true_rul": [], "rul": [],
            "down": [], "actions": [], "failures": [], "cost": 0.0,
        }

        def note(t: float, observation: Mapping[str, Any], phm_observation: Mapping[str, Any], info: Mapping[str, Any]) -> None:
            component = core.faulty_component(0)
            low, high = limits[component]
            record["t"].append(t)
            record["component"].append(component)
            record["true_position"].append((info["true_parameters"][component] - low) / (high - low))
            record["estimated_position"].append(float(phm_observation["parameter_estimate"][components.index(component)]))
            record["true_rul"].append(finite_or_none(float(info["true_rul"])))
            record["rul"].append([float(v) for v in phm_observation["rul"]])
            record["down"].append(bool(observation["maintenance_in_progress"][0] > 0.5))

        note(0.0, observation, phm_observation, info)
        state, start, step = None, True, 0
        while True:
            predicted, state = policy.predict(observation, state=state, episode_start=np.array([start]), deterministic=True)
            start = False
            action = int(np.asarray(predicted).reshape(-1)[0])
            was_down = bool(observation["maintenance_in_progress"][0] > 0.5)
            observation, _, terminated, truncated, info = env.step(action)
            if shadow is not None:
                phm_observation, _, _, _, phm_info = shadow.step(action)
                if phm_info["true_parameters"] != info["true_parameters"]:
                    raise RuntimeError(f"the phm shadow of the {obs_mode} env diverged at step {step + 1} (seed {seed})")
            else:
                phm_observation = observation
            if action != 0 and not was_down:
                record["actions"].append([step * dt, meanings[action]])
            step += 1
            record["cost"] += float(info["cost"]["total"])
            for event in info["events"]:
                failure = parse_event(event)
                if isinstance(failure, Failure):
                    record["failures"].append([step * dt, failure.component])
            note(step * dt, observation, phm_observation, info)
            if terminated or truncated:
                break
        return record
    finally:
        env.close()
        if shadow is not None:
            shadow.close()
