"""Write what the package ships so that a fresh install's environments start without computing anything:

* ``ea_gym/data/{system}_strong.safetensors``: the isolation network of every built-in system that has
  none yet (``--retrain``: all but the spring-mass-damper's, which ``experiments/build/train_isolation.py``
  writes with its report), trained as ``ea_gym.phm.classifier_for`` would (seed 0, default settings);
* ``ea_gym/data/thresholds.json``: the detection thresholds of every built-in system at the
  environments' default settings and calibration seed (``EnvConfig().phm_config``, seed 0), each under
  its cache key (``ea_gym.phm.thresholds.calibration_key``), exactly as ``calibrate_thresholds`` gives them.

How to run (from the repository root; a minute or two per network on 2 cores, seconds for the thresholds)
    python experiments/build/ship_builtins.py [--retrain] [--out DIR] [--smoke]

``--smoke`` writes the RLC circuit's network, trained on a small database for a few epochs, and its
thresholds into a temporary folder: the package's data stays as it is.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.diagnosis.classifier import TrainingConfig
from ea_gym.diagnosis.database import DatabaseConfig
from ea_gym.diagnosis.training import ISOLATION_SEED, shipped_classifier_path, train_isolation
from ea_gym.env.config import EnvConfig
from ea_gym.files import write_json
from ea_gym.models import MODELS, get_model
from ea_gym.phm import calibrate_thresholds
from ea_gym.phm.thresholds import CALIBRATION_FORMAT, SHIPPED_THRESHOLDS, calibration_key
from experiments.common import parse_with_smoke

#: the seed of the environments' calibration (their default ``calibration_seed``)
SEED = 0
#: the spring-mass-damper's networks come with experiments/build/train_isolation.py's report
REPORTED = "spring_mass_damper"
#: where the package looks for what it ships
PACKAGE_DATA = SHIPPED_THRESHOLDS.parent
#: the smoke run: one system, its network from a small database
SMOKE_SYSTEMS = ["rlc_circuit"]
SMOKE_DATABASE = DatabaseConfig(intervals=4, n_loads=2, fault_free_runs=3, noise_levels=(0.0, 0.05), frame_ends=(30.0, 40.0))
SMOKE_TRAINING = TrainingConfig(epochs=50)


def ship_network(name: str, out: Path, database: DatabaseConfig, training: TrainingConfig) -> Path:
    """Train the "strong" network of built-in ``name`` from seed 0 and save it in ``out`` under the package's file name."""
    rng = np.random.default_rng(ISOLATION_SEED)
    classifier = train_isolation(get_model(name), rng, database, training, variants=("strong",)).classifiers["strong"]
    return classifier.save(out / shipped_classifier_path(name).name)


def ship_thresholds(names: list[str], out: Path) -> Path:
    """Calibrate the built-ins ``names`` at the environments' defaults and write the table under the keys the package computes."""
    config = EnvConfig().phm_config
    entries = {}
    for name in names:
        model = get_model(name)
        rng = np.random.default_rng(SEED)
        key = calibration_key(model, config, rng)
        thresholds = calibrate_thresholds(model, config, rng)
        entries[key] = {"model": name, "settings": "EnvConfig().phm_config", "seed": SEED, "thresholds": thresholds.tolist(),
                        "rng_after": rng.bit_generator.state}
        print(f"{name}: thresholds {np.array2string(thresholds, precision=4)}")
    return write_json(out / SHIPPED_THRESHOLDS.name, {"format": CALIBRATION_FORMAT, "entries": entries})


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--retrain", action="store_true", help="retrain the networks already shipped (but the spring-mass-damper's)")
    parser.add_argument("--out", type=Path, default=PACKAGE_DATA, help="folder to write into (default the package's data, ea_gym/data)")
    args = parse_with_smoke(parser, argv, {})
    if args.smoke:
        systems, database, training = SMOKE_SYSTEMS, SMOKE_DATABASE, SMOKE_TRAINING
    else:
        systems, database, training = sorted(MODELS), DatabaseConfig(), TrainingConfig()
    for name in systems:
        if name != REPORTED and (args.retrain or not (args.out / shipped_classifier_path(name).name).is_file()):
            print(f"wrote {ship_network(name, args.out, database, training)}", flush=True)
    print(f"wrote {ship_thresholds(systems, args.out)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
