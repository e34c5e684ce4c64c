"""What training, evaluation and the benchmark agree on: the seed ranges and a trained agent's files.

Light on purpose (no torch): the benchmark checks seeds and agent directories before loading anything.
"""

from __future__ import annotations

__all__ = ["TRAINING_SEED", "VALIDATION_SEED", "MODEL_FILE", "NORMALIZATION_FILE", "SUMMARY_FILE", "AGENT_FILES"]

#: seeds of the training environments start here, those of the validation environments at VALIDATION_SEED;
#: the benchmark's tuning seeds stay below TRAINING_SEED and its evaluation seeds start at 100_000
TRAINING_SEED = 1_000
VALIDATION_SEED = 5_000
#: a trained agent's directory (``ea-gym train --out DIR``): the model, its observation and reward
#: normalisation, and the run's summary
MODEL_FILE = "model.zip"
NORMALIZATION_FILE = "vecnormalize.pkl"
SUMMARY_FILE = "training.json"
AGENT_FILES = (MODEL_FILE, SUMMARY_FILE, NORMALIZATION_FILE)
