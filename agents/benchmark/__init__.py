"""Benchmark of maintenance policies on common evaluation seeds: rules, the oracle and trained PPO agents.

Modules: ``settings`` (grids, rules, seeds, environments), ``tuning`` (the rules' grid search),
``evaluation`` (every policy on the evaluation seeds, paired comparisons, value of information),
``timelines`` (one episode recorded step by step), ``figures``, ``report`` (benchmark.md) and ``run``
(``run_benchmark``: all of it in order, outputs written).

``run_benchmark`` tunes the rule-based policies on tuning seeds, evaluates every policy on the same
evaluation seeds (common random numbers: per-seed cost differences are paired), and writes, atomically:

- ``benchmark.json``: per policy the mean episode cost with its 95 % interval (normal approximation,
  mean +- 1.96 sd / sqrt(n)), failures, availability, maintenance actions per episode, the ratio of its
  mean cost to the oracle's, the paired cost difference to the oracle, its obs_mode and tuned parameter,
  and the per-episode records; the seeds, the tuning tables, the skipped policies, the commands;
- ``benchmark.md``: the table sorted by mean cost, the ranking, the value of information, the tuning
  tables and the command that reproduces it;
- ``cost_distribution.png``: each policy's episode costs (box plot, episodes as dots, means marked);
- ``timelines.png`` (and the numbers in ``timelines.json``): one evaluation episode per policy, the
  same seed for all: the degrading component's true and PHM-estimated parameter (position in its safe
  range), the true and estimated RUL, the downtime and the actions.

Policies (environment ``ea_gym/SpringMassDamper-v0``, ``continue_after_failure=True``):

===================  ========  ====================================================================
name                 obs_mode  policy
===================  ========  ====================================================================
``oracle``           oracle    ``Oracle``: replace the truly degrading component, or apply a corrective
                               action on it, when its true RUL falls below the threshold (action and
                               threshold tuned): the reference lower bound
``ppo``              its own   a PPO agent loaded with ``agents.training.load_policy``
``rul_threshold``    phm       ``RulThreshold`` on the PHM chain's diagnosis and RUL (action and
                               threshold tuned)
``corrective_band``  phm       ``CorrectiveBand``: corrective actions on the suspect while its estimate
                               is beyond its component's band toward its limit (bands tuned; the
                               damper's narrower while it is quiet, ``QUIET_BAND``)
``periodic``         sensors   ``Periodic`` block replacement of every component (period tuned)
``run_to_failure``   sensors   ``RunToFailure``: never maintain
===================  ========  ====================================================================

plus any extra trained agents (``ppo_policies``, e.g. ``ppo_sensors`` and ``ppo_oracle``, for the value
of information: the same learner given less or more information).

Seeds: tuning ``0 .. tune_episodes - 1``; evaluation ``100_000 + seed * 10_000 + i`` for episode i;
the training environments of ``agents.training`` start at ``TRAINING_SEED`` = 1000 (1000..4999) and its
validation at ``VALIDATION_SEED`` = 5000, so no evaluation episode was seen in training, validation or
tuning. The environment's dynamics (wear, loads, sensor noise) depend only on the seed and the
actions, not on the obs_mode, so every policy meets the same machines.
"""

from __future__ import annotations

from agents.benchmark.evaluation import paired
from agents.benchmark.figures import plot_cost_distribution, plot_timelines
from agents.benchmark.report import fmt_ci, fmt_diff, markdown
from agents.benchmark.run import run_benchmark
from agents.benchmark.settings import (
    ACTIONS,
    BANDS,
    DEFAULT_GRIDS,
    ENV_ID,
    EVALUATION_SEED_BASE,
    EVALUATION_SEED_STRIDE,
    PERIODS,
    QUIET_BAND,
    THRESHOLDS,
    env_factory,
    evaluation_seeds,
    tuning_seeds,
    vector_env_factory,
)
from agents.benchmark.timelines import record_timeline

__all__ = [
    "ENV_ID", "PERIODS", "THRESHOLDS", "BANDS", "QUIET_BAND", "ACTIONS", "DEFAULT_GRIDS", "EVALUATION_SEED_BASE", "EVALUATION_SEED_STRIDE",
    "env_factory", "vector_env_factory", "evaluation_seeds", "tuning_seeds", "paired", "fmt_ci", "fmt_diff", "record_timeline",
    "plot_cost_distribution", "plot_timelines", "markdown", "run_benchmark",
]
