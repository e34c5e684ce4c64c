"""The benchmark's fixed choices: tuning grids, rule policies, seeds and the environments they run on."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from agents.conventions import TRAINING_SEED
from ea_gym.env import ENV_ID, env_id

__all__ = [
    "ENV_ID", "PERIODS", "THRESHOLDS", "BANDS", "QUIET_BAND", "ACTIONS", "DEFAULT_GRIDS", "EVALUATION_SEED_BASE", "EVALUATION_SEED_STRIDE",
    "RULES", "env_factory", "vector_env_factory", "evaluation_seeds", "tuning_seeds", "display_path",
]

#: Periodic's grid of periods (s), the RUL thresholds (s) of RulThreshold and Oracle, CorrectiveBand's bands:
#: the spring's and the mass's band (their estimates are good to 1-2 % of their safe ranges) x the light
#: damper's while it is well excited (6-12 %: it needs the wider margin); while it is quiet, QUIET_BAND.
#: Storage bands of 0.9 fail (0.05 failures per episode on the tuning seeds), 0.7 held the parts further
#: from their limits than needed; damper bands of 0.4 and 0.8 cost more than 0.5-0.7
PERIODS = (20, 40, 60, 80, 120, 160, 240)
THRESHOLDS = (2, 5, 10, 15, 20, 30, 45, 60)
BANDS = tuple({"k": storage, "m": storage, "b": damper} for storage in (0.75, 0.8, 0.85) for damper in (0.5, 0.6, 0.7))
#: CorrectiveBand's band for the damper while its EA over a step is below 0.003 J (its estimate then
#: scatters 18 % of its range, rms): 0.3, better than 0.4 and than none on the 300 tuning episodes
QUIET_BAND = {"b": 0.3}
DEFAULT_GRIDS: dict[str, tuple[Any, ...]] = {
    "oracle": THRESHOLDS, "rul_threshold": THRESHOLDS, "corrective_band": BANDS, "periodic": PERIODS,
}
#: the actions RulThreshold and Oracle are tuned over, each with the whole threshold grid
ACTIONS = ("replace", "corrective")
EVALUATION_SEED_BASE = 100_000
EVALUATION_SEED_STRIDE = 10_000  # evaluation seeds of benchmark seed s: BASE + s * STRIDE + i, i < episodes

#: (label, obs_mode, tuned parameter's name) of the rule-based policies, in evaluation order
RULES: dict[str, tuple[str, str, str | None]] = {
    "oracle": ("Oracle (true state)", "oracle", "threshold_s"),
    "rul_threshold": ("RulThreshold (PHM)", "phm", "threshold_s"),
    "corrective_band": ("CorrectiveBand (PHM)", "phm", "band"),
    "periodic": ("Periodic", "sensors", "period_s"),
    "run_to_failure": ("RunToFailure", "sensors", None),
}


def _benchmark_kwargs(obs_mode: str, env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    import ea_gym  # noqa: F401 - registers the environments

    return {"obs_mode": obs_mode, "continue_after_failure": True, **env_kwargs}


def env_factory(obs_mode: str, **env_kwargs: Any) -> Callable[[], Any]:
    """``() -> env``: ``ea_gym/SpringMassDamper-v0`` (BondGraphMaintenance-v0 when ``env_kwargs`` name a
    system) with ``continue_after_failure=True`` and ``env_kwargs``."""
    import gymnasium as gym

    kwargs = _benchmark_kwargs(obs_mode, env_kwargs)
    return lambda: gym.make(env_id(kwargs.get("system")), **kwargs)


def vector_env_factory(obs_mode: str, **env_kwargs: Any) -> Callable[[int], Any]:
    """``(n) -> vector env``: ``env_factory``'s environment, n of them batched (``ea_gym.env.vector``)."""
    import gymnasium as gym

    kwargs = _benchmark_kwargs(obs_mode, env_kwargs)
    return lambda n: gym.make_vec(env_id(kwargs.get("system")), num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def evaluation_seeds(seed: int, episodes: int) -> range:
    """The benchmark's evaluation seeds: ``100_000 + seed * 10_000 + i`` for i < episodes."""
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if not (isinstance(episodes, (int, np.integer)) and 1 <= episodes <= EVALUATION_SEED_STRIDE):
        raise ValueError(f"episodes must be an integer in [1, {EVALUATION_SEED_STRIDE}], got {episodes!r}")
    start = EVALUATION_SEED_BASE + int(seed) * EVALUATION_SEED_STRIDE
    return range(start, start + int(episodes))


def tuning_seeds(tune_episodes: int) -> range:
    """The tuning seeds ``0 .. tune_episodes - 1`` (below the training seeds, which start at 1000)."""
    if not (isinstance(tune_episodes, (int, np.integer)) and 1 <= tune_episodes <= TRAINING_SEED):
        raise ValueError(f"tune_episodes must be an integer in [1, {TRAINING_SEED}], got {tune_episodes!r}")
    return range(int(tune_episodes))


def display_path(path: Path) -> str:
    """``path`` relative to the working directory when it lies below it (for commands and notes), else as given."""
    path = Path(path)
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)
