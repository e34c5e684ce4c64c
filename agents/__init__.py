"""Maintenance policies for the ea_gym environments: rule-based baselines and their evaluation.

All policies have stable-baselines3's ``predict(observation, state=None, episode_start=None,
deterministic=True) -> (actions, state)``, so rules and learned agents are evaluated the same way.
"""

from agents.evaluation import COST_BREAKDOWN, EpisodeStats, evaluate, mean_ci95, tune
from agents.policies import ActionMap, CorrectiveBand, Oracle, Periodic, RulePolicy, RulThreshold, RunToFailure

__all__ = [
    "ActionMap", "RulePolicy", "RunToFailure", "Periodic", "RulThreshold", "Oracle", "CorrectiveBand",
    "EpisodeStats", "evaluate", "tune", "mean_ci95", "COST_BREAKDOWN",
]
