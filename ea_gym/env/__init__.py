"""Gymnasium maintenance environments, registered on ``import ea_gym``."""

from gymnasium.envs.registration import register, registry

from ea_gym.env.costs import CostModel

ENV_IDS = ("ea_gym/SpringMassDamper-v0", "ea_gym/BondGraphMaintenance-v0")
ENV_ID = ENV_IDS[0]  # the paper's spring-mass-damper: the default of every command and experiment

if ENV_IDS[0] not in registry:
    register(
        id=ENV_IDS[0],
        entry_point="ea_gym.env.maintenance:SpringMassDamperEnv",
        vector_entry_point="ea_gym.env.vector:SpringMassDamperVectorEnv",
    )
    register(
        id=ENV_IDS[1],
        entry_point="ea_gym.env.maintenance:BondGraphMaintenanceEnv",
        vector_entry_point="ea_gym.env.vector:BondGraphMaintenanceVectorEnv",
    )



def env_id(system: object = None) -> str:
    """The id to make: the spring-mass-damper's without a ``system``, BondGraphMaintenance-v0's with one
    (a built-in name, a model file's path or a model)."""
    return ENV_ID if system is None else ENV_IDS[1]


__all__ = ["ENV_ID", "ENV_IDS", "CostModel", "env_id"]
