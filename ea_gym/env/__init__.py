"""Gymnasium maintenance environments, registered on ``import ea_gym``.

Two versions of each: v0, one fault per episode (its episodes kept bit for bit), and v1, the world where
every part ages at once (``V1_SETTINGS``: its own wear process per part, slow background ageing, parts
starting within their tolerances, each machine commissioned at its reset), with the per-part observation.
"""

from typing import Any

from gymnasium.envs.registration import register, registry

from ea_gym.degradation import BACKGROUND_WEAR
from ea_gym.env.costs import CostModel

ENV_IDS = ("ea_gym/SpringMassDamper-v0", "ea_gym/BondGraphMaintenance-v0")
V1_ENV_IDS = ("ea_gym/SpringMassDamper-v1", "ea_gym/BondGraphMaintenance-v1")
ENV_ID = ENV_IDS[0]  # the paper's spring-mass-damper: the default of every command and experiment
#: seconds of healthy operation each v1 machine is commissioned from (at a reset and after a replacement): on the
#: spring-mass-damper at 1 % noise its parts' values to a median 0.1-0.5 % of their safe spans (at most 1.5 %, b's),
#: against the +-12.5 % they are drawn within; 60 s halve b's error at three times the reset's cost
COMMISSION_SECONDS = 20.0
#: the v1 environments' settings (``EnvConfig`` fields), registered as their keyword arguments: keywords given to
#: ``make`` override them
V1_SETTINGS: dict[str, Any] = {
    "concurrent_wear": True, "background_wear": BACKGROUND_WEAR, "tolerance": 0.125, "commission_seconds": COMMISSION_SECONDS,
}

if ENV_IDS[0] not in registry:
    for ids, settings in ((ENV_IDS, {}), (V1_ENV_IDS, V1_SETTINGS)):
        register(
            id=ids[0],
            entry_point="ea_gym.env.maintenance:SpringMassDamperEnv",
            vector_entry_point="ea_gym.env.vector:SpringMassDamperVectorEnv",
            kwargs=dict(settings),
        )
        register(
            id=ids[1],
            entry_point="ea_gym.env.maintenance:BondGraphMaintenanceEnv",
            vector_entry_point="ea_gym.env.vector:BondGraphMaintenanceVectorEnv",
            kwargs=dict(settings),
        )


def env_id(system: object = None, version: int = 0) -> str:
    """The id to make: the spring-mass-damper's without a ``system``, BondGraphMaintenance's with one
    (a built-in name, a model file's path or a model); ``version`` 0 (one fault per episode) or 1 (every
    part ages)."""
    if version not in (0, 1):
        raise ValueError(f"version must be 0 or 1, got {version!r}")
    ids = V1_ENV_IDS if version == 1 else ENV_IDS
    return ids[0] if system is None else ids[1]


__all__ = ["ENV_ID", "ENV_IDS", "V1_ENV_IDS", "V1_SETTINGS", "CostModel", "env_id"]
