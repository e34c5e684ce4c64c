"""The maintenance environment's settings: one frozen, validated ``EnvConfig`` shaping an episode."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ea_gym.degradation import WearConfig
from ea_gym.env.costs import CostModel
from ea_gym.numerics import MAX_SAMPLES
from ea_gym.phm import ChainTiming, ModelFitConfig, PHMConfig
from ea_gym.phm.commissioning import COMMISSIONING_STEP

OBS_MODES = ("phm", "sensors", "oracle")
#: longest degradation time of one step (s, about 116 days): the wear laws integrate over it in one go
MAX_STEP_SECONDS = 1e7
#: most steps of an episode (long soaks run with 1e9)
MAX_HORIZON = 10**9
#: most systems of one vector environment (each holds its own states, windows and generator)
MAX_ENVS = 4096


def check_reset_arguments(seed: Any, options: Any, known: tuple[str, ...]) -> dict[str, Any]:
    """reset()'s ``options``, None or a dict of the ``known`` keys (a misspelt key would silently reset every system), as a
    dict; ``seed`` an int or None here (a bool is no seed). TypeError or ValueError naming the argument otherwise."""
    if seed is not None and (isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer))):
        raise TypeError(f"seed must be an int or None, got {seed!r}")
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
    unknown = [key for key in options if key not in known]
    if unknown:
        raise ValueError(f"options: unknown key {unknown[0]!r}; the known keys are {list(known)}")
    return options


@dataclass(frozen=True)
class EnvConfig:
    """Everything that shapes an episode; checked when built (a one-line error naming the field).

    Attributes:
        step_seconds: degradation time one step covers (s).
        window_seconds: measured operation per step (s); None: equal to ``step_seconds``.
        sample_rate: sensor sample rate (Hz).
        noise: sensor noise, fraction of each measured signal's RMS, in [0, 1).
        horizon: steps before truncation.
        obs_mode: "phm", "sensors" or "oracle".
        costs: the cost model.
        wear: wearing components and how they wear; None: every parameter with safe limits, linear
            drift in a random direction.
        corrective_rate: speed of a corrective action, fraction of the safe range per s (the paper's
            corrective action restores the spring at 0.27 N/m/s, 1.35 % of its range per s).
        continue_after_failure: a failure forces a replacement with downtime instead of ending the episode.
        rul_max: RUL observations are clipped to [0, rul_max] (s).
        load_std: range (low, high) of the random loads' std, fraction of
            ``SystemModel.random_load_scale`` (the nominal load unless the model gives a scale).
        phm: the PHM chain's own settings (isolation, detection, estimation, prognosis); its timing
            (window, clock, sample rate and noise) is the environment's (``phm_config``). With one fault per
            system it runs without the model-fit test (``PHMConfig.fit``) and without a joint filter beside its
            estimator (``JointFilterConfig.beside``): the v0 environments' episodes stay as they were. None: the
            defaults; where every part ages, with the joint filter (``estimator_kind="joint"``), which estimates
            every part at once.
        concurrent_wear: every wearing component has its own wear process (kind from its WearConfig;
            direction, arrival and rate drawn per part), so that faults overlap, instead of one fault per
            episode; the observation then gives every part's RUL and degrading probability (the v1
            environments' world, ``ea_gym.degradation.PartsWear``).
        background_wear: with ``concurrent_wear``, every wearing part also ages slowly from its
            installation on, in its fault's direction: this fraction of the distance from nominal to the
            limit per second (the v1 environments: 2e-4, so that a part needs 5000 s, ten default
            horizons, to reach its limit by background ageing alone).
        tolerance: with ``concurrent_wear``, each wearing part starts (at a reset and when replaced) from
            a value drawn uniformly within nominal +- this fraction of its safe span (the v1
            environments: 1/8, the middle half of the range for a nominal in its middle).
        commission_seconds: with ``concurrent_wear``, each machine runs this long healthy at its reset and after
            a replacement (before any wear: the degradation clock stands still), and its parts' own values are
            fitted from that record (``ea_gym.phm.commission``): its reference model is simulated with them and
            the chain compares the machine with itself, not with the catalogue (``PHMChain.commission``).
            0: none, the reference at nominal (the v1 environments: 20 s; at least ``COMMISSIONING_STEP``).
    """

    step_seconds: float = 1.0
    window_seconds: float | None = None
    sample_rate: float = 100.0
    noise: float = 0.01
    horizon: int = 500
    obs_mode: str = "phm"
    costs: CostModel = field(default_factory=CostModel)
    wear: dict[str, WearConfig] | None = None
    corrective_rate: float = 0.02
    continue_after_failure: bool = False
    rul_max: float = 1000.0
    load_std: tuple[float, float] = (0.2, 0.4)
    phm: PHMConfig | None = None
    concurrent_wear: bool = False
    background_wear: float = 0.0
    tolerance: float = 0.0
    commission_seconds: float = 0.0

    def __post_init__(self) -> None:
        for name in ("step_seconds", "sample_rate", "corrective_rate", "rul_max"):
            _check_positive(name, getattr(self, name))
        if self.window_seconds is not None:
            _check_positive("window_seconds", self.window_seconds)
        if self.step_seconds > MAX_STEP_SECONDS:
            raise ValueError(f"step_seconds must be at most {MAX_STEP_SECONDS:g} s, got {self.step_seconds!r}")
        if self.window * self.sample_rate > MAX_SAMPLES:
            field_name = "step_seconds" if self.window_seconds is None else "window_seconds"
            raise ValueError(
                f"{field_name} * sample_rate = {self.window * self.sample_rate:g} samples per step; at most {MAX_SAMPLES} "
                f"(a window of at most {MAX_SAMPLES / self.sample_rate:g} s at {self.sample_rate:g} Hz)"
            )
        if not (_is_number(self.noise) and 0 <= self.noise < 1):
            raise ValueError(f"noise must be in [0, 1), got {self.noise!r}")
        if not (isinstance(self.horizon, int) and not isinstance(self.horizon, bool) and 0 < self.horizon <= MAX_HORIZON):
            raise ValueError(f"horizon must be an int in [1, {MAX_HORIZON}], got {self.horizon!r}")
        if self.obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, got {self.obs_mode!r}")
        if not isinstance(self.costs, CostModel):
            raise TypeError(f"costs must be a CostModel or a dict of its fields, got {type(self.costs).__name__}")
        if self.wear is not None and not (
            isinstance(self.wear, dict) and all(isinstance(k, str) and isinstance(v, WearConfig) for k, v in self.wear.items())
        ):
            raise TypeError(f"wear must be None or a dict of component name -> WearConfig, got {self.wear!r}")
        if not isinstance(self.continue_after_failure, bool):
            raise TypeError(f"continue_after_failure must be a bool, got {self.continue_after_failure!r}")
        low_high = self.load_std
        if not (isinstance(low_high, tuple) and len(low_high) == 2 and all(_is_number(v) for v in low_high) and 0 <= low_high[0] <= low_high[1]):
            raise ValueError(f"load_std must be a tuple (low, high) of numbers with 0 <= low <= high, got {low_high!r}")
        if self.phm is not None and not isinstance(self.phm, PHMConfig):
            raise TypeError(f"phm must be None or a PHMConfig, got {type(self.phm).__name__}")
        self._check_world()

    def _check_world(self) -> None:
        """The settings of the world where every part ages: a bool and numbers >= 0, used only in that world."""
        if not isinstance(self.concurrent_wear, bool):
            raise TypeError(f"concurrent_wear must be a bool, got {self.concurrent_wear!r}")
        for name in ("background_wear", "tolerance", "commission_seconds"):
            value = getattr(self, name)
            if not (_is_number(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {value!r}")
            if value and not self.concurrent_wear:
                raise ValueError(f"{name} needs concurrent_wear=True (the world where every part ages), got {name}={value!r}")
        seconds = self.commission_seconds
        if seconds and not (COMMISSIONING_STEP <= seconds and seconds * self.sample_rate <= MAX_SAMPLES):
            raise ValueError(
                f"commission_seconds must be 0 (none) or within [{COMMISSIONING_STEP:g}, {MAX_SAMPLES / self.sample_rate:g}] s "
                f"(at {self.sample_rate:g} Hz), got {seconds!r}"
            )

    @property
    def window(self) -> float:
        """Measured operation per step (s)."""
        return self.step_seconds if self.window_seconds is None else self.window_seconds

    @property
    def phm_config(self) -> PHMConfig:
        """The chain's settings, its timing (window, clock, sample rate and noise) the environment's."""
        timing = ChainTiming(step=self.window, step_time=self.step_seconds, sample_rate=self.sample_rate, noise=self.noise)
        if self.concurrent_wear:  # the chain as on a real machine: every part estimated at once, the model's fit tested
            return dataclasses.replace(self.phm or PHMConfig(estimator_kind="joint"), timing=timing)
        phm = self.phm or PHMConfig()
        joint = dataclasses.replace(phm.joint, beside=False)  # no joint filter beside the estimator: v0's episodes stay as they were
        return dataclasses.replace(phm, timing=timing, fit=ModelFitConfig(enabled=False), joint=joint)


def env_config(config: EnvConfig | None = None, **overrides: Any) -> EnvConfig:
    """``config`` (default ``EnvConfig()``) with keyword overrides, each the name of a field.

    ``costs=None`` stands for the default cost model (the environments' keyword has always allowed it); a dict
    of CostModel's fields for that cost model.
    """
    if config is not None and not isinstance(config, EnvConfig):
        raise TypeError(f"config must be an EnvConfig or None, got {type(config).__name__}")
    names = [f.name for f in dataclasses.fields(EnvConfig)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise TypeError(f"unexpected keyword argument {unknown[0]!r}: not an environment setting ({', '.join(names)})")
    if "costs" in overrides and overrides["costs"] is None:
        overrides["costs"] = CostModel()
    elif isinstance(overrides.get("costs"), dict):
        overrides["costs"] = cost_model(overrides["costs"])
    base = config if config is not None else EnvConfig()
    return dataclasses.replace(base, **overrides) if overrides else base


def cost_model(fields: dict[Any, Any]) -> CostModel:
    """The CostModel of a dict of its fields; a one-line error names an unknown field or a wrong value."""
    names = [f.name for f in dataclasses.fields(CostModel)]
    for key, value in fields.items():
        if key not in names:
            raise TypeError(f"costs: unknown field {key!r}; CostModel's fields are {', '.join(names)}")
        if not _is_number(value):
            raise TypeError(f"costs: {key} must be a number, got {value!r}")
    return CostModel(**fields)


def _is_number(value: Any) -> bool:
    """A finite int or float, not a bool (an int beyond the float range is not finite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return abs(value) < 1e308 if isinstance(value, int) else math.isfinite(value)


def _check_positive(name: str, value: Any) -> None:
    if not (_is_number(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
