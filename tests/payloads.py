"""Files whose loading would run code (the payload creates a marker file): stable-baselines3's files of an agent."""

from __future__ import annotations

import base64
import json
import pickle
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any


class Payload:
    """Unpickling it creates the file ``marker`` (builtins.open): any code could run there."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self) -> tuple[Any, ...]:
        return open, (self.marker, "w")


def malicious_agent(directory: Path, marker: Path, run: Mapping[str, Any]) -> Path:
    """An agent directory of stable-baselines3's files whose pickles run the payload; ``run``: its training.json's run."""
    directory.mkdir(parents=True)
    (directory / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    serialized = base64.b64encode(pickle.dumps(Payload(marker))).decode()
    with zipfile.ZipFile(directory / "model.zip", "w") as archive:
        archive.writestr("data", json.dumps({"policy_class": {":type:": "<class 'abc.ABCMeta'>", ":serialized:": serialized}}))
    (directory / "blob").write_bytes(pickle.dumps(Payload(marker)))  # a pickle by its content, not its name
    (directory / "training.json").write_text(json.dumps({"run": dict(run)}))
    return directory
