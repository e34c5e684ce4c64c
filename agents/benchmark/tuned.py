"""The rules' tuned settings as data: written by a tuning run, read by the benchmark by default.

``ea-gym benchmark --tune --write-tuned PATH`` grid-searches the rules and writes PATH; without
``--tune`` the benchmark reads ``TUNED_RULES_FILE`` (``agents/data/benchmark/tuned_rules.json``, or
``--tuned PATH``). The file holds each rule's winner (value and action), the whole search (the
grid, every value's mean cost on the tuning seeds), the tuning seeds, the command that tuned them,
and the environment they were tuned on: ``environment_settings`` (the environment's id, its complete
resolved configuration with the PHM chain's settings, the machine's parameters and safe limits, the
actions, a digest of the isolation network) and its SHA-256 ``fingerprint``. Reading compares the
fingerprint with the current environment's and refuses a stale file (``StaleTuning``, naming the
settings that differ) unless told to use it anyway; the report then says it was stale.

A change of the PHM chain's code that leaves every setting as it was is not visible in the
fingerprint: re-tune after such a change (the command is in the file).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ea_gym.files import json_ready, write_json

__all__ = ["TUNED_RULES_FILE", "FORMAT", "StaleTuning", "TunedRules", "environment_settings", "fingerprint", "read_tuned", "write_tuned"]

#: the committed tuned settings, beside the trained agents
TUNED_RULES_FILE = Path(__file__).resolve().parents[1] / "data" / "benchmark" / "tuned_rules.json"
FORMAT = "ea-gym tuned rules, version 1"


class StaleTuning(ValueError):
    """The tuned settings were tuned on another environment than the one the benchmark runs."""


@dataclass(frozen=True)
class TunedRules:
    """Each tuned rule's winner and where it came from.

    Attributes:
        rules: name -> (tuned value, its action or None).
        tables: name -> the grid search (obs_mode, parameter_name, grid, best, action, one row per
            action and value with its mean cost on the tuning seeds).
        tuning_seeds: the seeds the rules were tuned on.
        command: the command that tuned them.
        settings: ``environment_settings`` of the environment they were tuned on.
        fingerprint: ``fingerprint(settings)``.
        timings_s: the wall time of each rule's search (s).
        machine: where they were tuned.
    """

    rules: dict[str, tuple[Any, str | None]]
    tables: dict[str, Any]
    tuning_seeds: range
    command: str
    settings: dict[str, Any]
    fingerprint: str
    timings_s: dict[str, float]
    machine: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        """The file's content."""
        return json_ready({
            "format": FORMAT,
            "command": self.command,
            "tuning_seeds": [self.tuning_seeds.start, self.tuning_seeds.stop - 1],
            "fingerprint": self.fingerprint,
            "rules": {name: {"value": value, "action": action} for name, (value, action) in self.rules.items()},
            "tables": self.tables,
            "environment": self.settings,
            "timings_s": self.timings_s,
            "machine": self.machine,
        })

    @classmethod
    def from_json(cls, data: Any, source: str) -> TunedRules:
        """Parse a file's content; a ValueError naming the first field that is missing or wrong."""
        if not isinstance(data, Mapping) or data.get("format") != FORMAT:
            raise ValueError(f"{source}: not a tuned-rules file (format must be {FORMAT!r})")
        for key, kind in (("command", str), ("fingerprint", str), ("rules", Mapping), ("tables", Mapping), ("environment", Mapping),
                          ("tuning_seeds", list)):
            if not isinstance(data.get(key), kind):
                raise ValueError(f"{source}: field {key!r} must be a {kind.__name__}")
        rules: dict[str, tuple[Any, str | None]] = {}
        for name, entry in data["rules"].items():
            if not (isinstance(entry, Mapping) and "value" in entry and isinstance(entry.get("action"), (str, type(None)))):
                raise ValueError(f"{source}: rules[{name!r}] must hold a value and an action (a string or null)")
            rules[name] = (entry["value"], entry["action"])
        first, last = (data["tuning_seeds"] + [None, None])[:2]
        if not (isinstance(first, int) and isinstance(last, int) and 0 <= first <= last):
            raise ValueError(f"{source}: field 'tuning_seeds' must be [first, last] with 0 <= first <= last")
        return cls(rules=rules, tables=dict(data["tables"]), tuning_seeds=range(first, last + 1), command=data["command"],
                   settings=dict(data["environment"]), fingerprint=data["fingerprint"],
                   timings_s=dict(data.get("timings_s", {})), machine=dict(data.get("machine", {})))


def environment_settings(env: Any, env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """What the tuned settings depend on, from an environment made with ``env_kwargs`` (JSON-ready).

    The environment's id and registered keyword arguments, ``env_kwargs``, the resolved ``EnvConfig``
    (every field but ``obs_mode``, the PHM chain's settings as the chain gets them), the machine
    (name, nominal parameters, safe limits), the actions and diagnosis classes, and the SHA-256 of the
    chain's data: the isolation network's weights and standardisation, and the detection thresholds
    (the values, not the files that hold them).
    """
    import gymnasium as gym

    from ea_gym.env import env_id

    made = env_id(env_kwargs.get("system"))
    base = env.unwrapped
    config = dataclasses.asdict(dataclasses.replace(base.config, phm=base.config.phm_config))
    config.pop("obs_mode")
    return json_ready({
        "id": made,
        "registered_kwargs": dict(gym.spec(made).kwargs),
        "env_kwargs": dict(env_kwargs),
        "config": config,
        "system": base.model.name,
        "nominal_parameters": dict(base.nominal_parameters),
        "safe_limits": dict(base.safe_limits),
        "action_meanings": list(base.action_meanings),
        "diagnosis_classes": list(base.diagnosis_classes),
        **_chain_data(base.model, base.config.phm_config),
    })


def _chain_data(model: Any, phm_config: Any) -> dict[str, str]:
    """SHA-256 of the isolation network the environment's chain loads (classes, weights, standardisation) and of its
    detection thresholds (calibration seed 0, the environment's)."""
    import numpy as np

    from ea_gym.phm import classifier_for, thresholds_for

    network = classifier_for(model)
    weights = hashlib.sha256(repr(tuple(network.classes)).encode())
    for name, tensor in sorted(network.network.state_dict().items()):
        weights.update(name.encode())
        weights.update(tensor.detach().cpu().numpy().tobytes())
    for array in (network.mean, network.scale):
        weights.update(np.ascontiguousarray(array, dtype=np.float64).tobytes())
    thresholds = thresholds_for(model, phm_config, np.random.default_rng(0))
    return {"isolation_network_sha256": weights.hexdigest(),
            "detection_thresholds_sha256": hashlib.sha256(np.ascontiguousarray(thresholds, dtype=np.float64).tobytes()).hexdigest()}


def fingerprint(settings: Mapping[str, Any]) -> str:
    """SHA-256 of the settings' canonical JSON (sorted keys, no spaces)."""
    return hashlib.sha256(json.dumps(json_ready(settings), sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _differences(old: Any, new: Any, where: str = "") -> list[str]:
    """The dotted names of the settings that differ between ``old`` and ``new``, with both values."""
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        return [d for key in sorted(set(old) | set(new), key=str)
                for d in _differences(old.get(key), new.get(key), f"{where}.{key}" if where else str(key))]
    return [] if old == new else [f"{where or 'settings'}: {old!r} in the file, {new!r} now"]


def read_tuned(path: Path, settings: Mapping[str, Any], allow_stale: bool = False) -> tuple[TunedRules, bool]:
    """The tuned settings in ``path`` and whether they are stale (tuned on other ``settings``).

    Raises:
        ValueError: the file is missing, not JSON or not a tuned-rules file (one line naming it).
        StaleTuning: the file's fingerprint is not the current environment's and ``allow_stale`` is
            False; the message names the differing settings and how to re-tune.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"--tuned: no tuned settings at {path} (tune them with --tune --write-tuned {path})") from None
    except json.JSONDecodeError as error:
        raise ValueError(f"--tuned: {path} is not JSON ({error.msg} at line {error.lineno})") from None
    tuned = TunedRules.from_json(data, str(path))
    current = fingerprint(settings)
    stale = tuned.fingerprint != current
    if stale and not allow_stale:
        changed = _differences(tuned.settings, dict(settings)) or ["the recorded settings do not hash to the recorded fingerprint"]
        raise StaleTuning(
            f"--tuned: {path} was tuned on environment {tuned.fingerprint[:12]}, this one is {current[:12]} "
            f"({'; '.join(changed[:3])}{'; ...' if len(changed) > 3 else ''}): re-tune with --tune (and --write-tuned {path}), "
            "or pass --allow-stale to use them anyway"
        )
    return tuned, stale


def write_tuned(path: Path, tuned: TunedRules) -> Path:
    """Write the tuned settings (atomically)."""
    return write_json(Path(path), tuned.to_json())
