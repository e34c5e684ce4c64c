"""Connecting to Ray (a local one, or a cluster's head by address) for the optional Ray backends.

Ray comes with the optional extra ``ea-gym[rllib]``, installed in a virtual environment of its own
(RLlib pins its gymnasium); every import of ray stays inside these functions so that the rest of the
agents run without it.
"""

from __future__ import annotations

import importlib.util
from typing import Any

__all__ = ["MissingRay", "require_ray", "connect"]


class MissingRay(ValueError):
    """Ray (or RLlib) is not installed; ``ea-gym`` prints the message as a one-line error (exit code 2)."""


def require_ray(option: str) -> None:
    """Raise ``MissingRay`` naming ``option`` (e.g. ``"--ray"``) and the extra to install when ray is missing."""
    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("ray.rllib") is None:
        raise MissingRay(
            f"{option} needs Ray RLlib, which is not installed: pip install -c constraints.txt -e '.[rllib]' "
            "(in a virtual environment of its own: RLlib pins its gymnasium; README, RLlib and Ray)"
        )


def connect(address: str | None, num_cpus: int | None = None) -> Any:
    """Join the Ray cluster at ``address`` (``"auto"``, ``"HOST:PORT"`` of a ``ray start --head``), or, when
    None, start a local Ray with ``num_cpus`` CPUs (None: every core). A Ray this process already joined
    is kept. Returns the ray module.

    The workers of a cluster must have ea-gym installed (the env and the policies are imported by name there).
    """
    import ray

    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(address="local", num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)  # a Ray of its own, not one found running
    return ray
