"""Training and evaluation of the fault-isolation classifiers (paper 4.2), and the shipped networks.

:func:`train_isolation` simulates the fault database once (:func:`ea_gym.diagnosis.database.build_database`),
trains one :class:`~ea_gym.diagnosis.classifier.FaultClassifier` per feature variant on the training
runs (split 0), keeping the epoch with the best accuracy on the validation runs (split 1), and scores
every variant on the same held-out test runs (split 2) with :func:`evaluate_isolation`.

The networks trained by ``experiments/build/train_isolation.py`` ship inside the package as
``ea_gym/data/{model}_{variant}.safetensors``; :func:`load_shipped_classifier` reads them.

Populations of the evaluation (test frames of one noise level):

* ``quarter``: fault frames whose parameter is at least a quarter of the way from its nominal value to
  the safe limit on the fault's side (magnitude >= 0.25). Smaller faults hardly change the EA and are
  not expected to be isolated; this is the acceptance population.
* ``quarter_with_none``: the same plus the fault-free frames (class "none").
* ``all``: every test frame, the small faults included.
"""

from __future__ import annotations

import importlib.resources
import pathlib
import sys
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ea_gym.cache import cache_dir, cache_key, entry_path, model_definition, warn_rebuilt
from ea_gym.diagnosis.classifier import FaultClassifier, TrainingConfig
from ea_gym.diagnosis.database import DatabaseConfig, FaultDatabase, build_database, classes_of
from ea_gym.diagnosis.features import VARIANTS
from ea_gym.diagnosis.monitor import MonitorConfig
from ea_gym.files import finite_or_none
from ea_gym.metrics import confusion_matrix, per_class_accuracy
from ea_gym.models import SystemModel

__all__ = [
    "ISOLATION_FORMAT",
    "ISOLATION_SEED",
    "MAGNITUDE_BINS",
    "QUARTER",
    "REGENERATE_COMMAND",
    "IsolationTraining",
    "cached_isolation_path",
    "evaluate_isolation",
    "isolation_key",
    "isolation_network",
    "load_shipped_classifier",
    "noise_key",
    "shipped_classifier_path",
    "train_isolation",
]

#: Smallest fault magnitude of the acceptance population (fraction of the way from nominal to a limit).
QUARTER = 0.25
#: Fault-magnitude bins of the accuracy-vs-magnitude curve; the last one includes 1.0.
MAGNITUDE_BINS: tuple[tuple[float, float], ...] = ((0.0, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0))
#: The script that (re)writes the shipped classifiers.
REGENERATE_COMMAND = "python experiments/build/train_isolation.py"
#: raise it when training computes a different network from the same inputs: every cached network is then retrained
ISOLATION_FORMAT = 1
#: the seed of every network trained for the cache, and of the shipped ones
ISOLATION_SEED = 0
#: the cache's entry kind
_KIND = "isolation"


@dataclass(frozen=True)
class IsolationTraining:
    """Result of :func:`train_isolation`.

    Attributes:
        database: the simulated fault database (all splits).
        classifiers: variant name -> trained classifier.
        evaluation: :func:`evaluate_isolation` on the test split (JSON-serialisable).
        training: JSON-serialisable bookkeeping: seconds spent building the database and training each
            variant, each variant's best validation accuracy and final training loss, the seeds used.
    """

    database: FaultDatabase
    classifiers: dict[str, FaultClassifier]
    evaluation: dict
    training: dict = field(default_factory=dict)


def noise_key(level: float) -> str:
    """The key of a noise level in the evaluation's dictionaries, e.g. 0.01 -> "0.01"."""
    return f"{float(level):g}"


def _accuracy(correct: np.ndarray) -> float | None:
    """Mean of a boolean array, or None (JSON null) when it is empty."""
    return float(correct.mean()) if correct.size else None


def _population_scores(
    database: FaultDatabase, variant_predictions: np.ndarray, mask: np.ndarray
) -> dict[str, Any]:
    """Accuracies, counts, confusion matrix and accuracy vs magnitude over the test frames in ``mask``."""
    classes = list(database.classes)
    labels = database.labels[mask]
    predicted = variant_predictions[mask]
    magnitude = database.magnitude[mask]
    correct = labels == predicted
    fault = labels > 0
    none = labels == 0
    quarter = fault & (magnitude >= QUARTER)
    quarter_with_none = quarter | none

    if quarter_with_none.any():
        matrix = confusion_matrix(
            [classes[i] for i in labels[quarter_with_none]],
            [classes[i] for i in predicted[quarter_with_none]],
            classes,
        )
    else:
        matrix = np.zeros((len(classes), len(classes)), dtype=np.int64)
    recall = per_class_accuracy(matrix, classes)

    by_magnitude = []
    for k, (low, high) in enumerate(MAGNITUDE_BINS):
        upper = magnitude <= high if k == len(MAGNITUDE_BINS) - 1 else magnitude < high
        in_bin = fault & (magnitude >= low) & upper
        by_magnitude.append(
            {"low": low, "high": high, "n": int(in_bin.sum()), "accuracy": _accuracy(correct[in_bin])}
        )

    return {
        "accuracy_quarter": _accuracy(correct[quarter]),
        "accuracy_quarter_with_none": _accuracy(correct[quarter_with_none]),
        "accuracy_all": _accuracy(correct),
        "n": {
            "all": int(mask.sum()),
            "none": int(none.sum()),
            "fault": int(fault.sum()),
            "quarter": int(quarter.sum()),
            "quarter_with_none": int(quarter_with_none.sum()),
            "below_quarter": int((fault & ~quarter).sum()),
            "per_class": {name: int((labels == i).sum()) for i, name in enumerate(classes)},
        },
        "confusion": matrix.tolist(),
        "per_class_accuracy": {name: finite_or_none(value) for name, value in recall.items()},
        "accuracy_vs_magnitude": by_magnitude,
    }


def evaluate_isolation(database: FaultDatabase, classifiers: Mapping[str, FaultClassifier]) -> dict:
    """Score each classifier on the test split (2) of ``database``, per noise level.

    Every variant is scored on the same test frames. For each variant the result holds, per noise level
    (keyed by :func:`noise_key`) and pooled over all noise levels:

    * ``accuracy_quarter``: fault frames with magnitude >= 0.25 (the acceptance population);
    * ``accuracy_quarter_with_none``: those plus the fault-free frames;
    * ``accuracy_all``: every test frame;
    * ``n``: frame counts of each population (``all = none + quarter + below_quarter``) and per class;
    * ``confusion``: confusion matrix over ``classes`` (rows true, columns predicted) on the
      quarter+none population, as nested lists;
    * ``per_class_accuracy``: recall of each class on that population (None for an empty row);
    * ``accuracy_vs_magnitude``: over the fault frames only, per bin of :data:`MAGNITUDE_BINS`
      (``[low, high)``, the last bin closed), ``{"low", "high", "n", "accuracy"}``.

    Accuracies of empty populations are None. Everything is plain JSON (lists, dicts, floats, ints).

    Returns:
        ``{"classes", "noise_levels", "magnitude_bins", "quarter", "test_frames", "test_runs",
        "variants": {variant: {"by_noise": {key: scores}, "pooled": scores}}}``.
    """
    test = database.split == 2
    if not test.any():
        raise ValueError("the database has no test frames (split 2)")
    levels = sorted({float(v) for v in database.noise})
    result: dict[str, Any] = {
        "classes": list(database.classes),
        "noise_levels": levels,
        "magnitude_bins": [list(b) for b in MAGNITUDE_BINS],
        "quarter": QUARTER,
        "test_frames": int(test.sum()),
        "test_runs": int(np.unique(database.run[test]).size),
        "variants": {},
    }
    for variant, classifier in classifiers.items():
        if tuple(classifier.classes) != tuple(database.classes):
            raise ValueError(
                f"classifier {variant!r} has classes {classifier.classes}, the database {database.classes}"
            )
        predicted = np.full(len(database.labels), -1, dtype=np.int64)
        predicted[test] = classifier.predict_proba(database.features[variant][test]).argmax(axis=1)
        result["variants"][variant] = {
            "by_noise": {
                noise_key(level): {"noise": level, **_population_scores(database, predicted, test & (database.noise == level))}
                for level in levels
            },
            "pooled": _population_scores(database, predicted, test),
        }
    return result


def train_isolation(
    model: SystemModel,
    rng: np.random.Generator,
    config: DatabaseConfig = DatabaseConfig(),
    training: TrainingConfig = TrainingConfig(),
    progress: Callable[[str, int, int], None] | None = None,
    variants: tuple[str, ...] = VARIANTS,
) -> IsolationTraining:
    """Build the fault database once, train one classifier per variant, evaluate them on the test split.

    ``rng`` is split into independent child generators: one for the database and one per variant
    (in the order of :data:`~ea_gym.diagnosis.features.VARIANTS`), so a variant's network depends only
    on the seed and on its own child, not on which other variants are trained.

    Args:
        model: the system (its degradable parameters are the classes).
        rng: the source of randomness of the whole run.
        config: how the database is simulated.
        training: optimiser settings of every classifier.
        progress: called as ``progress(stage, done, total)`` before each stage ("database",
            "train <variant>", "evaluate") and once with ``("done", total, total)`` at the end.
        variants: the feature variants to train (default both).
    """
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        raise ValueError(f"unknown variants {unknown}; known: {VARIANTS}")
    children = rng.spawn(1 + len(VARIANTS))
    database_rng, variant_rng = children[0], dict(zip(VARIANTS, children[1:]))
    total = len(variants) + 2
    report = progress or (lambda stage, done, total: None)

    report("database", 0, total)
    start = time.perf_counter()
    database = build_database(model, database_rng, config)
    info: dict[str, Any] = {"database_seconds": time.perf_counter() - start, "variants": {}}

    classifiers: dict[str, FaultClassifier] = {}
    for k, variant in enumerate(variants):
        report(f"train {variant}", 1 + k, total)
        start = time.perf_counter()
        features, labels = database.subset(0, variant)
        classifier = FaultClassifier(database.classes, variant, features.shape[1], training.hidden)
        fit = classifier.fit(features, labels, validation=database.subset(1, variant), rng=variant_rng[variant], config=training)
        classifiers[variant] = classifier
        info["variants"][variant] = {
            "seconds": time.perf_counter() - start,
            "n_features": int(features.shape[1]),
            **{key: float(value) for key, value in fit.items()},
        }

    report("evaluate", total - 1, total)
    evaluation = evaluate_isolation(database, classifiers)
    report("done", total, total)
    return IsolationTraining(database=database, classifiers=classifiers, evaluation=evaluation, training=info)


def shipped_classifier_path(model_name: str, variant: str = "strong") -> pathlib.Path:
    """Where the package keeps the trained classifier of a model and variant: ``ea_gym/data/{model}_{variant}.safetensors``."""
    return pathlib.Path(str(importlib.resources.files("ea_gym") / "data" / f"{model_name}_{variant}.safetensors"))


def isolation_key(model: SystemModel) -> str:
    """The cache key of ``model``'s network: its definition, the default database, monitor and training settings, the seed."""
    return cache_key(
        _KIND, ISOLATION_FORMAT, model=model_definition(model), variant="strong", database=DatabaseConfig(), monitor=MonitorConfig(),
        training=TrainingConfig(), seed=ISOLATION_SEED,
    )


def cached_isolation_path(model: SystemModel) -> pathlib.Path:
    """Where the cache keeps ``model``'s network (see :mod:`ea_gym.cache`)."""
    return entry_path(_KIND, isolation_key(model), ".safetensors")


def _cached_network(path: pathlib.Path, classes: tuple[str, ...]) -> FaultClassifier | None:
    """The network cached at ``path`` if it is one for ``classes`` (else None, warned)."""
    try:
        classifier = FaultClassifier.load(path)
    except ValueError as error:
        warn_rebuilt(path, str(error))
        return None
    if classifier.classes != classes or classifier.variant != "strong":
        warn_rebuilt(path, f"a {classifier.variant!r} network for classes {classifier.classes}, not a 'strong' one for {classes}")
        return None
    return classifier


def isolation_network(model: SystemModel) -> FaultClassifier:
    """The "strong" isolation network of ``model``: shipped for a built-in system, else cached, else trained now and cached.

    A network depends only on the model and the default settings: it is trained from
    ``ISOLATION_SEED``, as the shipped ones were. Training (about a minute) says so on stderr, with a
    progress bar over its stages.
    """
    classes = classes_of(model)
    shipped = shipped_classifier_path(model.name)
    if shipped.is_file():
        classifier = FaultClassifier.load(shipped)
        if classifier.classes == classes:
            return classifier
    path = cached_isolation_path(model)
    if path.is_file():
        cached = _cached_network(path, classes)
        if cached is not None:
            return cached
    from tqdm import tqdm

    print(f"no isolation network for model {model.name!r} with these settings in {cache_dir()}; training one (about a minute)...",
          file=sys.stderr, flush=True)
    with tqdm(total=3, desc="isolation network", unit="stage", file=sys.stderr) as bar:
        def progress(stage: str, done: int, total: int) -> None:
            bar.set_postfix_str(stage)
            bar.n = done
            bar.refresh()

        trained = train_isolation(model, np.random.default_rng(ISOLATION_SEED), progress=progress, variants=("strong",))
    classifier = trained.classifiers["strong"]
    try:
        classifier.save(path)
    except OSError as error:  # a read-only home: the network is right, only not kept
        warnings.warn(f"could not cache the isolation network: {error}", RuntimeWarning, stacklevel=2)
    return classifier


def load_shipped_classifier(model_name: str, variant: str = "strong") -> FaultClassifier:
    """The classifier shipped with the package for ``model_name`` and ``variant``.

    Raises:
        ValueError: unknown variant.
        FileNotFoundError: no such file; the message names the script that writes it.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    path = shipped_classifier_path(model_name, variant)
    if not path.is_file():
        raise FileNotFoundError(
            f"no shipped isolation classifier for model {model_name!r}, variant {variant!r} (expected {path}); "
            f"regenerate it with `{REGENERATE_COMMAND}` from the repository root"
        )
    classifier = FaultClassifier.load(path)
    if classifier.variant != variant:
        raise ValueError(f"{path} holds a {classifier.variant!r} classifier, not {variant!r}")
    return classifier
