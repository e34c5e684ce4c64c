"""Detection thresholds computed once: shipped for the built-in systems, cached on disk for the rest.

:func:`calibrate_thresholds` simulates fault-free runs (seconds); its result depends only on the model,
the settings of :func:`calibration_settings` and the state of the generator it draws from, so
:func:`thresholds_for` looks that up first: in ``ea_gym/data/thresholds.json`` (the built-ins at the
environments' default settings, written by ``experiments/build/ship_builtins.py``), then in the cache
(:mod:`ea_gym.cache`), and calibrates (and caches) only when neither has it. The generator is left as the
calibration leaves it, so what is drawn from it afterwards is the same whether or not the thresholds
were calibrated.
"""

from __future__ import annotations

import functools
import importlib.resources
import json
import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ea_gym.cache import cache_key, entry_path, model_definition, read_json_entry, warn_rebuilt, write_json_entry
from ea_gym.models import SystemModel
from ea_gym.phm.detection import calibrate_thresholds

if TYPE_CHECKING:
    from ea_gym.phm.config import PHMConfig

__all__ = ["CALIBRATION_FORMAT", "SHIPPED_THRESHOLDS", "calibration_key", "calibration_settings", "shipped_thresholds", "thresholds_for"]

#: raise it when ``calibrate_thresholds`` computes differently: every cached and shipped value is then recomputed
CALIBRATION_FORMAT = 1
#: the cache's entry kind, and the shipped table's file name
_KIND = "thresholds"
SHIPPED_THRESHOLDS = Path(str(importlib.resources.files("ea_gym") / "data" / f"{_KIND}.json"))


def calibration_settings(config: PHMConfig) -> dict[str, Any]:
    """The chain settings the calibration reads: step, sample rate, noise, monitor and detector, and the load's noise
    where there is some (an exact load's key stays as it was, so the shipped and cached thresholds still hold)."""
    timing = config.timing
    settings = {"step": timing.step, "sample_rate": timing.sample_rate, "noise": timing.noise, "monitor": config.monitor, "detector": config.detector}
    if timing.load_noise > 0:
        settings["load_noise"] = timing.load_noise
    return settings


def calibration_key(model: SystemModel, config: PHMConfig, rng: np.random.Generator) -> str:
    """The key of the thresholds ``calibrate_thresholds(model, config, rng)`` would give (rng in its present state)."""
    return cache_key(_KIND, CALIBRATION_FORMAT, model=model_definition(model), settings=calibration_settings(config), rng=rng.bit_generator.state)


@functools.cache
def shipped_thresholds() -> dict[str, dict[str, Any]]:
    """The shipped table: key -> entry (``thresholds``, ``rng_after``, the model's name and the settings' name)."""
    if not SHIPPED_THRESHOLDS.is_file():
        return {}
    return dict(json.loads(SHIPPED_THRESHOLDS.read_text())["entries"])


def _restore(entry: dict[str, Any], rng: np.random.Generator) -> np.ndarray | None:
    """The entry's thresholds, rng moved to where the calibration left it; None if the entry is malformed."""
    values = entry.get("thresholds")
    if not (isinstance(values, list) and values and all(isinstance(v, float) and math.isfinite(v) and v > 0 for v in values)):
        return None
    try:
        rng.bit_generator.state = entry["rng_after"]
    except (KeyError, TypeError, ValueError):
        return None
    return np.array(values)


def thresholds_for(model: SystemModel, config: PHMConfig, rng: np.random.Generator) -> np.ndarray:
    """``calibrate_thresholds(model, config, rng)``, read from the shipped table or the cache when they hold it, else
    calibrated now and cached; either way ``rng`` ends in the state the calibration leaves it in."""
    key = calibration_key(model, config, rng)
    shipped = shipped_thresholds().get(key)
    entry = shipped if shipped is not None else read_json_entry(_KIND, key)
    if entry is not None:
        thresholds = _restore(entry, rng)
        if thresholds is not None:
            return thresholds
        if shipped is not None:
            raise ValueError(f"{SHIPPED_THRESHOLDS}: the entry {key} is malformed; regenerate it with experiments/build/ship_builtins.py")
        warn_rebuilt(entry_path(_KIND, key, ".json"), "malformed thresholds or generator state")
    thresholds = calibrate_thresholds(model, config, rng)
    try:
        write_json_entry(_KIND, key, {"model": model.name, "thresholds": thresholds.tolist(), "rng_after": rng.bit_generator.state})
    except OSError as error:  # a read-only home: the thresholds are right, only not kept
        warnings.warn(f"could not cache the detection thresholds: {error}", RuntimeWarning, stacklevel=2)
    return thresholds
