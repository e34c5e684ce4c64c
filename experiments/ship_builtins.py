"""Write what the package ships so that a fresh install's environments start without computing anything:

* ``ea_gym/data/{system}_strong.safetensors``: the isolation network of every built-in system that has
  none yet (``--retrain``: all but the spring-mass-damper's, which ``experiments/train_isolation.py``
  writes with its report), trained as ``ea_gym.phm.classifier_for`` would (seed 0, default settings);
* ``ea_gym/data/thresholds.json``: the detection thresholds of every built-in system at the
  environments' default settings and calibration seed (``EnvConfig().phm_config``, seed 0), each under
  its cache key (``ea_gym.phm.thresholds.calibration_key``), exactly as ``calibrate_thresholds`` gives them.

How to run (from the repository root; a minute or two per network on 2 cores, seconds for the thresholds)
    python experiments/ship_builtins.py [--retrain]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

try:  # runnable from a checkout without installing
    import ea_gym  # noqa: F401
except ImportError:  # pragma: no cover - depends on how the script is started
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ea_gym.diagnosis.training import ISOLATION_SEED, shipped_classifier_path, train_isolation
from ea_gym.env.config import EnvConfig
from ea_gym.files import write_json
from ea_gym.models import MODELS, get_model
from ea_gym.phm import calibrate_thresholds
from ea_gym.phm.thresholds import CALIBRATION_FORMAT, SHIPPED_THRESHOLDS, calibration_key

#: the seed of the environments' calibration (their default ``calibration_seed``)
SEED = 0
#: the spring-mass-damper's networks come with experiments/train_isolation.py's report
REPORTED = "spring_mass_damper"


def ship_network(name: str) -> Path:
    """Train the "strong" network of built-in ``name`` from seed 0 and save it where the package looks for it."""
    classifier = train_isolation(get_model(name), np.random.default_rng(ISOLATION_SEED), variants=("strong",)).classifiers["strong"]
    return classifier.save(shipped_classifier_path(name))


def ship_thresholds() -> Path:
    """Calibrate every built-in at the environments' defaults and write the table under the keys the package computes."""
    config = EnvConfig().phm_config
    entries = {}
    for name in sorted(MODELS):
        model = get_model(name)
        rng = np.random.default_rng(SEED)
        key = calibration_key(model, config, rng)
        thresholds = calibrate_thresholds(model, config, rng)
        entries[key] = {"model": name, "settings": "EnvConfig().phm_config", "seed": SEED, "thresholds": thresholds.tolist(),
                        "rng_after": rng.bit_generator.state}
        print(f"{name}: thresholds {np.array2string(thresholds, precision=4)}")
    return write_json(SHIPPED_THRESHOLDS, {"format": CALIBRATION_FORMAT, "entries": entries})


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--retrain", action="store_true", help="retrain the networks already shipped (but the spring-mass-damper's)")
    args = parser.parse_args()
    for name in sorted(MODELS):
        if name != REPORTED and (args.retrain or not shipped_classifier_path(name).is_file()):
            print(f"wrote {ship_network(name)}", flush=True)
    print(f"wrote {ship_thresholds()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
