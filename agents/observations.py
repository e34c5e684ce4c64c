"""How the environment's observations are presented to a learner.

``VecNormalize`` standardises every observation key by its running mean and std and clips the result
to +-10. That suits the unbounded signals (EA, residuals, time since maintenance) but destroys the
bounded ones whose informative values are rare: the RUL sits at ``rul_max`` (1000 s) nearly always,
so a RUL of 5 s and one of 150 s both standardise below -10 and clip to the same value, and a
diagnosis belief of 0.2 or 0.8 on a fault class (0 nearly always) both clip to +10. The decision the
learner must make, replacing the suspect shortly before its End of Life, then cannot be seen.

So the bounded keys pass unnormalised, and the RUL (s) goes on a log scale in [0, 1],
log(1 + rul) / log(1 + rul_max), which resolves the last seconds as well as the last minutes.

The parameter estimates are positions in each component's safe range, and the nominal value sits at
a different position for each (0.75 for the spring's (85, 105) N/m): a key ``wear`` adds each
component's way covered from nominal toward the limit on its estimate's side (0 at nominal, 1 at the
limit), the coordinate in which a corrective rule acts (``agents.policies.CorrectiveBand``).

The diagnosis says which component is the suspect, ``wear`` how far each one has gone: a rule acts on
the two together (the suspect's wear, ``agents.policies.CorrectiveBand``), which a small network must
otherwise learn as a product. With ``suspect_wear``, a key ``suspect_wear`` adds, per component, its
share of the diagnosis' belief in the fault classes (0 while the diagnosis believes in no fault) times
its wear.

Standardising the EA by its mean and std puts a damper's 0.001 J and 0.01 J over a step at the same
value, while how well a component's parameter can be estimated depends on exactly that (a weakly
excited damper's estimate scatters three times as widely): with ``activity``, a key ``activity`` adds
every element's EA on a log scale, log10(EA / 1 uJ) / 6 clipped to [0, 1] (1 uJ to 1 J).
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from agents.policies import ActionMap, wear_fraction
from ea_gym.numerics import TINY

#: keys standardised by VecNormalize; the others are bounded and passed as they are
NORMALISED_KEYS = ("ea", "residual", "time_since_maintenance")
#: the ``activity`` key's scale: EA (J) from ACTIVITY_FLOOR over ACTIVITY_DECADES decades maps to [0, 1]
ACTIVITY_FLOOR = 1e-6
ACTIVITY_DECADES = 6.0


def normalised_keys(observation_space: spaces.Dict) -> list[str]:
    """The keys of ``observation_space`` that VecNormalize should standardise."""
    return [key for key in NORMALISED_KEYS if key in observation_space.spaces]


class LearnerView(VecEnvWrapper):
    """Replaces ``observation["rul"]`` (s, in [0, rul_max]) by log(1 + rul) / log(1 + rul_max) and adds
    ``observation["wear"]``, each component's way from nominal to the limit its estimate heads for,
    clipped to [0, 2], with ``activity`` the key ``activity``: each element's EA on a log scale, and with
    ``suspect_wear`` the key ``suspect_wear``: each component's share of the fault classes' belief times
    its wear, in [0, 2].

    Observations without ``rul`` or ``parameter_estimate`` (obs_mode "sensors") keep those keys as they are.
    """

    def __init__(self, venv: VecEnv, activity: bool = False, suspect_wear: bool = False):
        space = cast(spaces.Dict, venv.observation_space)
        self.activity = bool(activity) and "ea" in space.spaces
        if self.activity:
            space = spaces.Dict({**space.spaces, "activity": spaces.Box(0.0, 1.0, space["ea"].shape, np.float32)})
        self.scale = math.log1p(float(np.max(cast(spaces.Box, space["rul"]).high))) if "rul" in space.spaces else None
        if self.scale is not None:
            space = spaces.Dict({**space.spaces, "rul": spaces.Box(0.0, 1.0, space["rul"].shape, np.float32)})
        self.nominal, self.suspect_class = None, None
        if "parameter_estimate" in space.spaces:
            actions = ActionMap.from_env(venv)
            self.nominal = np.array(actions.nominal_positions, dtype=np.float32)
            space = spaces.Dict({**space.spaces, "wear": spaces.Box(0.0, 2.0, self.nominal.shape, np.float32)})
            # each component's diagnosis class (column of observation["diagnosis"]), 0 ("none") for one without
            self.suspect_class = None
            if suspect_wear and "diagnosis" in space.spaces:
                self.suspect_class = np.array([actions.diagnosis_classes.index(c) if c in actions.diagnosis_classes else 0
                                               for c in actions.components])
                space = spaces.Dict({**space.spaces, "suspect_wear": spaces.Box(0.0, 2.0, self.nominal.shape, np.float32)})
        super().__init__(venv, observation_space=space)

    def forward(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The learner's view of an environment observation (single or batched)."""
        view = dict(observation)
        if self.scale is not None and "rul" in observation:
            view["rul"] = (np.log1p(np.maximum(observation["rul"], 0.0)) / self.scale).astype(np.float32)
        if self.nominal is not None and "parameter_estimate" in observation:
            view["wear"] = np.clip(wear_fraction(observation["parameter_estimate"], self.nominal), 0.0, 2.0).astype(np.float32)
            if self.suspect_class is not None and "diagnosis" in observation:
                beliefs = np.asarray(observation["diagnosis"], dtype=float)
                faults = beliefs[..., 1:].sum(axis=-1, keepdims=True)
                share = np.where(self.suspect_class > 0, beliefs[..., self.suspect_class], 0.0) / np.maximum(faults, TINY)
                view["suspect_wear"] = (share * view["wear"]).astype(np.float32)
        if self.activity and "ea" in observation:
            microjoules = np.maximum(np.asarray(observation["ea"], dtype=float), TINY) / ACTIVITY_FLOOR
            view["activity"] = np.clip(np.log10(microjoules) / ACTIVITY_DECADES, 0.0, 1.0).astype(np.float32)
        return view

    def inverse(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The environment observation back from the learner's view (RUL in s again, no ``wear``, ``activity`` or ``suspect_wear``)."""
        restored = {key: value for key, value in observation.items() if key not in ("wear", "activity", "suspect_wear")}
        if self.scale is not None and "rul" in observation:
            restored["rul"] = np.expm1(observation["rul"].astype(float) * self.scale).astype(np.float32)
        return restored

    def reset(self) -> Any:
        return self.forward(cast(dict[str, np.ndarray], self.venv.reset()))

    def step_wait(self) -> Any:
        observation, rewards, dones, infos = self.venv.step_wait()
        for info in infos:  # SB3 keeps the last observation of a finished episode here
            if "terminal_observation" in info:
                info["terminal_observation"] = self.forward(info["terminal_observation"])
        return self.forward(cast(dict[str, np.ndarray], observation)), rewards, dones, infos
