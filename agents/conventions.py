"""What training, evaluation and the benchmark agree on: the seed ranges, a trained agent's files, and
the refusal of files that would run code when loaded.

Light on purpose (no torch): the commands check seeds and agent directories before loading anything.
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "TRAINING_SEED", "VALIDATION_SEED", "AGENT_FILE", "POLICY_FILE", "OPTIMIZER_FILE", "SUMMARY_FILE", "AGENT_FILES",
    "SB3_MODEL_FILE", "SB3_NORMALIZATION_FILE", "TRUST_PICKLE", "UntrustedFileError", "pickled", "refuse_pickle",
]

#: seeds of the training environments start here, those of the validation environments at VALIDATION_SEED;
#: the benchmark's tuning seeds stay below TRAINING_SEED and its evaluation seeds start at 100_000
TRAINING_SEED = 1_000
VALIDATION_SEED = 5_000
#: a trained agent's directory (``ea-gym train --out DIR``, format of ``agents.agent_files``): the
#: description in JSON (architecture, spaces, normalisation statistics), the policy's weights and the
#: optimizer's state as safetensors, and the run's summary
AGENT_FILE = "agent.json"
POLICY_FILE = "policy.safetensors"
OPTIMIZER_FILE = "optimizer.safetensors"
SUMMARY_FILE = "training.json"
AGENT_FILES = (AGENT_FILE, POLICY_FILE, SUMMARY_FILE)
#: stable-baselines3's own files (``model.save``, ``VecNormalize.save``): both are unpickled on loading
SB3_MODEL_FILE = "model.zip"
SB3_NORMALIZATION_FILE = "vecnormalize.pkl"
#: the command-line opt-in that lets stable-baselines3 unpickle such files
TRUST_PICKLE = "--trust-pickle"


class UntrustedFileError(ValueError):
    """A file that would run code from itself when loaded (a pickle), refused without the user's opt-in."""


def pickled(path: Path) -> str | None:
    """What makes ``path`` unsafe to load, or None: an SB3 zip (its ``data`` entry is deserialised with
    cloudpickle), a pickle, or a directory of stable-baselines3's files that is not an agent directory.

    Only names and a regular file's first bytes are read (nothing is parsed).
    """
    path = Path(path)
    if path.is_dir():
        if (path / AGENT_FILE).is_file():
            return None
        for name in (SB3_MODEL_FILE, SB3_NORMALIZATION_FILE):
            why = pickled(path / name) if (path / name).is_file() else None
            if why is not None:
                return why
        return None
    if not path.is_file():
        return None
    with path.open("rb") as file:
        head = file.read(4)
    if path.suffix == ".zip" or head == b"PK\x03\x04":
        return f"{path} is a stable-baselines3 zip, whose data is unpickled on loading"
    if path.suffix in (".pkl", ".pickle") or head[:1] == b"\x80":
        return f"{path} is a pickle"
    return None


def refuse_pickle(path: Path, trust_pickle: bool) -> bool:
    """Raise ``UntrustedFileError`` when ``path`` is pickled (see ``pickled``) and ``trust_pickle`` is False.

    Returns:
        Whether ``path`` is pickled (and trusted).
    """
    why = pickled(path)
    if why is not None and not trust_pickle:
        raise UntrustedFileError(
            f"{why}: loading it would run any code it holds; pass {TRUST_PICKLE} only if you trust "
            f"where it came from, or give an agent directory ({AGENT_FILE}, {POLICY_FILE})"
        )
    return why is not None
