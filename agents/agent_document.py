"""``agent.json`` checked as plain data, before torch or stable-baselines3 is imported (a refusal comes at once).

What an agent file may ask for is bounded here, before anything is built: the action space's size, the observation's
values, the network's parameters (from ``net_arch`` and the spaces) and the training buffers' bytes (``n_steps`` or
``buffer_size`` times the observation, per environment). ``net_arch: [30000, 30000]`` would otherwise allocate gigabytes
of weights, ``n: 1e9`` actions a billion-wide output layer, ``n_steps: 1e8`` a rollout buffer larger than the memory.
:func:`read_agent_document` does every check that needs no torch; ``agents.agent_files.read_agent`` builds on it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from agents.conventions import AGENT_FILE
from agents.hyperparameters import HYPERPARAMETERS, check_hyperparameters
from ea_gym.documents import DocumentError, read_document
from ea_gym.files import refuse_links

__all__ = [
    "FORMAT", "MAX_ACTIONS", "MAX_BUFFER_BYTES", "MAX_OBSERVATION_VALUES", "MAX_PARAMETERS", "VERSION", "check_net_arch", "check_sizes",
    "field_of", "read_agent_document",
]

FORMAT = "ea-gym-agent"
VERSION = 1
#: most discrete actions an agent may choose among (the environments have 7)
MAX_ACTIONS = 1024
#: most values of one observation, its Dict's Boxes together (the environments' have tens)
MAX_OBSERVATION_VALUES = 65_536
#: most weights of a policy network (float32: 40 MB, Adam's moments twice that again)
MAX_PARAMETERS = 10_000_000
#: most bytes of a training buffer per environment (the rollout buffer's observations, or a replay buffer's)
MAX_BUFFER_BYTES = 1 << 30


#: stable-baselines3's defaults of the buffers' lengths: PPO's and A2C's n_steps, DQN's buffer_size
_DEFAULT_STEPS = {"ppo": 2048, "a2c": 5, "dqn": 1_000_000}


def field_of(data: Any, key: str, kind: type | tuple[type, ...], where: str) -> Any:
    """``data[key]``, of type ``kind`` (booleans are not numbers); ValueError naming the field otherwise."""
    if not isinstance(data, dict) or key not in data:
        raise ValueError(f"{where}: field {key!r} is missing")
    value = data[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        raise ValueError(f"{where}: field {key!r} must be {' or '.join(k.__name__ for k in kinds)}, got {value!r}")
    return value


def check_net_arch(net_arch: Any, where: str) -> None:
    """stable-baselines3's ``net_arch``: the hidden layers' widths, shared (a list) or the actor's and the critic's
    (``{"pi": [...], "vf": [...]}``); every width an integer >= 1."""
    layers = net_arch.values() if isinstance(net_arch, dict) and set(net_arch) <= {"pi", "vf"} else [net_arch]
    for widths in layers:
        if not (isinstance(widths, list) and all(isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in widths)):
            raise ValueError(f"{where} must be a list of layer widths (integers >= 1) or {{\"pi\": [...], \"vf\": [...]}}, got {net_arch!r}")


def read_agent_document(directory: Path) -> dict[str, Any]:
    """``directory/agent.json``'s data, its format, algorithm, hyperparameters, steps, ``net_arch`` and sizes checked."""
    path = Path(directory) / AGENT_FILE
    refuse_links(directory, "as an agent")
    try:
        data = read_document(path)
    except DocumentError as error:
        raise ValueError(f"{path}: cannot read the agent's description ({error})") from None
    where = str(path)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{where}: not an ea-gym agent (expected \"format\": {FORMAT!r})")
    version = field_of(data, "version", int, where)
    if version > VERSION:
        raise ValueError(f"{where}: format version {version} is newer than this ea-gym reads ({VERSION})")
    algorithm = field_of(data, "algorithm", str, where)
    if algorithm not in HYPERPARAMETERS:
        raise ValueError(f"{where}: algorithm must be one of {sorted(HYPERPARAMETERS)}, got {algorithm!r}")
    hyperparameters = field_of(data, "hyperparameters", dict, where)
    check_hyperparameters(algorithm, hyperparameters, f"{where}: hyperparameters")
    num_timesteps = field_of(data, "num_timesteps", int, where)
    if num_timesteps < 0:
        raise ValueError(f"{where}: num_timesteps must be an integer >= 0 (environment steps trained), got {num_timesteps}")
    kwargs = field_of(field_of(data, "policy", dict, where), "kwargs", dict, f"{where}: policy")
    if "net_arch" in kwargs:
        check_net_arch(kwargs["net_arch"], f"{where}: policy.kwargs.net_arch")
    check_sizes(data, where)
    return data


def _observation_values(space: Any, where: str) -> int:
    """The values of an observation space's description (a Dict of Boxes, a Box; 1 for a Discrete)."""
    kind = field_of(space, "type", str, where)
    if kind == "Dict":
        entries = field_of(space, "spaces", list, where)
        return sum(_observation_values(entry[1], f"{where}.{entry[0]}") for entry in entries if isinstance(entry, list) and len(entry) == 2)
    if kind == "Box":
        shape = field_of(space, "shape", list, where)
        if not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape):
            raise ValueError(f"{where}.shape must be a list of integers >= 0, got {shape}")
        return math.prod(shape)
    return 1


def _network_parameters(inputs: int, widths: list[int], outputs: int) -> int:
    """Weights and biases of a fully connected network ``inputs`` -> ``widths`` -> ``outputs``."""
    sizes = [inputs, *widths, outputs]
    return sum((a + 1) * b for a, b in zip(sizes, sizes[1:]))


def check_sizes(data: dict[str, Any], where: str) -> None:
    """The action space, the observation, the network and the training buffer within MAX_ACTIONS,
    MAX_OBSERVATION_VALUES, MAX_PARAMETERS and MAX_BUFFER_BYTES."""
    actions = field_of(field_of(data, "action_space", dict, where), "n", int, f"{where}: action_space")
    if not 1 <= actions <= MAX_ACTIONS:
        raise ValueError(f"{where}: action_space.n must be an integer in [1, {MAX_ACTIONS}], got {actions}")
    values = _observation_values(field_of(data, "observation_space", dict, where), f"{where}: observation_space")
    if values > MAX_OBSERVATION_VALUES:
        raise ValueError(f"{where}: observation_space holds {values} values; at most {MAX_OBSERVATION_VALUES}")
    net_arch = data["policy"]["kwargs"].get("net_arch", [64, 64])
    heads = net_arch if isinstance(net_arch, dict) else {"pi": net_arch, "vf": net_arch}
    parameters = sum(_network_parameters(values, widths, actions if head == "pi" else 1) for head, widths in heads.items())
    if parameters > MAX_PARAMETERS:
        raise ValueError(f"{where}: policy.kwargs.net_arch {net_arch} makes a network of {parameters:.3g} parameters; at most "
                         f"{MAX_PARAMETERS:.3g}")
    hyperparameters = data["hyperparameters"]
    steps_name = "buffer_size" if data["algorithm"] == "dqn" else "n_steps"
    steps = hyperparameters.get(steps_name, _DEFAULT_STEPS[data["algorithm"]])
    buffer = steps * (2 * values + 8) * 4  # float32 observations (twice in a replay buffer) and the per-step scalars
    if buffer > MAX_BUFFER_BYTES:
        raise ValueError(f"{where}: hyperparameters.{steps_name} = {steps} makes a training buffer of {buffer / 2**30:.3g} GiB per "
                         f"environment; at most {MAX_BUFFER_BYTES / 2**30:g} GiB")
