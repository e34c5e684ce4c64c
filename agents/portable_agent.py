"""A trained agent that travels to other processes and machines as plain data.

A loaded agent (``agents.training.NormalizedPolicy``) keeps its learner view, a wrapper around an
environment, which does not pickle: a Ray task cannot take it along. ``PortableAgent`` acts as the
loaded agent does, and what it sends is the bytes of the two files acting needs (``agent.json``,
``policy.safetensors``). Where it first acts after the journey it writes them to a temporary
directory and loads them with ``agents.training.load_policy`` (JSON and safetensors: nothing is
unpickled), once per process: a Ray worker that runs several batches loads an agent once. The
agent's directory need not exist on the worker's machine.
"""

from __future__ import annotations

import hashlib
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.conventions import AGENT_FILE, POLICY_FILE

if TYPE_CHECKING:
    from agents.training import NormalizedPolicy

__all__ = ["ACTING_FILES", "PortableAgent"]

#: the files of an agent directory that acting needs (``optimizer.safetensors`` is for training on)
ACTING_FILES = (AGENT_FILE, POLICY_FILE)

#: the agents this process loaded from the bytes sent to it, by the digest of those bytes
_LOADED: dict[str, NormalizedPolicy] = {}


class PortableAgent:
    """A trained agent with SB3's ``predict``, loaded from its directory here and from its files' bytes elsewhere.

    Attributes:
        name: the agent directory's name.
        obs_mode: the environment's obs_mode the agent acts on.
        files: file name -> bytes, of ``ACTING_FILES``.
        digest: SHA-256 of the files' names and bytes.
    """

    def __init__(self, directory: Path):
        """Load the agent in ``directory`` (``load_policy``'s errors name its files) and keep the bytes that load it elsewhere."""
        from agents.training import load_policy  # loads torch: imported only when an agent is evaluated

        directory = Path(directory)
        self._policy: NormalizedPolicy | None = load_policy(directory)  # checks the files first
        self.files = {name: (directory / name).read_bytes() for name in ACTING_FILES}
        self.name = directory.name
        self.obs_mode = self._policy.obs_mode
        self.digest = _digest(self.files)

    def policy(self) -> NormalizedPolicy:
        """The loaded agent: the one loaded from the directory, or, after a journey, the one this process loaded from the bytes."""
        if self._policy is None:
            if self.digest not in _LOADED:
                _LOADED[self.digest] = _load(self.files)
            self._policy = _LOADED[self.digest]
        return self._policy

    def predict(
        self, observation: Mapping[str, Any], state: Any = None, episode_start: Any = None, deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """The loaded agent's ``predict`` (``NormalizedPolicy.predict``)."""
        return self.policy().predict(observation, state, episode_start, deterministic)

    def __getstate__(self) -> dict[str, Any]:
        """What travels: the bytes, the name, the obs_mode and the digest, not the loaded agent."""
        return {"files": self.files, "name": self.name, "obs_mode": self.obs_mode, "digest": self.digest}

    def __setstate__(self, state: Mapping[str, Any]) -> None:
        self.files, self.name, self.obs_mode, self.digest = dict(state["files"]), state["name"], state["obs_mode"], state["digest"]
        if _digest(self.files) != self.digest:
            raise ValueError(f"the files of agent {self.name!r} arrived changed (SHA-256 differs)")
        self._policy = None

    def __repr__(self) -> str:
        return f"PortableAgent({self.name!r}, obs_mode={self.obs_mode!r})"


def _digest(files: Mapping[str, bytes]) -> str:
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + len(files[name]).to_bytes(8, "little") + files[name])
    return digest.hexdigest()


def _load(files: Mapping[str, bytes]) -> NormalizedPolicy:
    """``load_policy`` on a temporary agent directory of ``files``."""
    from agents.training import load_policy

    with tempfile.TemporaryDirectory(prefix="ea-gym-agent-") as directory:
        for name, content in files.items():
            (Path(directory) / name).write_bytes(content)
        return load_policy(Path(directory))
