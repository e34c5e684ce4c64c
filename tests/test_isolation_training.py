"""Tests of ea_gym.diagnosis.training on a small database (experiments/build/train_isolation.py's smoke run is in test_experiments.py).

The database here is far smaller than the shipped one (intervals=10, 8 loads, noise 0 only, frames
ending at 30 and 40 s: 296 runs, 592 frames, 90 of them test frames; about 2 s to simulate and train)
so that the whole file runs in well under 30 s.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ea_gym.diagnosis.classifier import FaultClassifier, TrainingConfig
from ea_gym.diagnosis.database import DatabaseConfig
from ea_gym.diagnosis.features import VARIANTS
from ea_gym.diagnosis.training import (
    MAGNITUDE_BINS,
    IsolationTraining,
    evaluate_isolation,
    load_shipped_classifier,
    noise_key,
    shipped_classifier_path,
    train_isolation,
)
from ea_gym.models import spring_mass_damper
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads

SMALL = DatabaseConfig(intervals=10, n_loads=8, fault_free_runs=4, noise_levels=(0.0,), frame=20.0, frame_ends=(30.0, 40.0))
SEED = 0


@pytest.fixture(scope="module")
def trained() -> IsolationTraining:
    return train_isolation(spring_mass_damper(), np.random.default_rng(SEED), SMALL)


def test_database_and_classifiers(trained: IsolationTraining) -> None:
    db = trained.database
    assert db.classes == ("none", "k", "m", "b")
    assert set(trained.classifiers) == set(VARIANTS)
    for variant, classifier in trained.classifiers.items():
        assert classifier.variant == variant
        assert classifier.n_features == db.features[variant].shape[1]
    assert set(np.unique(db.split)) == {0, 1, 2}
    assert set(trained.training["variants"]) == set(VARIANTS)
    json.dumps(trained.training, allow_nan=False)


def test_counts_add_up_to_the_test_split(trained: IsolationTraining) -> None:
    db, evaluation = trained.database, trained.evaluation
    test = db.split == 2
    assert evaluation["test_frames"] == int(test.sum())
    assert evaluation["noise_levels"] == [0.0]
    for variant in VARIANTS:
        result = evaluation["variants"][variant]
        total = 0
        for level in evaluation["noise_levels"]:
            n = result["by_noise"][noise_key(level)]["n"]
            assert n["all"] == n["none"] + n["quarter"] + n["below_quarter"]
            assert n["quarter_with_none"] == n["quarter"] + n["none"]
            assert n["fault"] == n["quarter"] + n["below_quarter"]
            assert sum(n["per_class"].values()) == n["all"]
            total += n["all"]
        assert total == int(test.sum()) == result["pooled"]["n"]["all"]
        # the magnitude bins cover every fault frame exactly once
        bins = result["pooled"]["accuracy_vs_magnitude"]
        assert [(b["low"], b["high"]) for b in bins] == list(MAGNITUDE_BINS)
        assert sum(b["n"] for b in bins) == result["pooled"]["n"]["fault"]
    # both variants are scored on the very same frames
    paper, strong = (evaluation["variants"][v]["pooled"]["n"] for v in ("paper", "strong"))
    assert paper == strong


def test_confusion_rows_sum_to_class_counts(trained: IsolationTraining) -> None:
    db, evaluation = trained.database, trained.evaluation
    test = db.split == 2
    population = test & ((db.labels == 0) | (db.magnitude >= 0.25))
    expected = [int((population & (db.labels == i)).sum()) for i in range(len(db.classes))]
    for variant in VARIANTS:
        scores = evaluation["variants"][variant]["by_noise"]["0"]
        confusion = np.asarray(scores["confusion"])
        assert confusion.shape == (len(db.classes), len(db.classes))
        assert confusion.sum(axis=1).tolist() == expected
        assert confusion.sum() == scores["n"]["quarter_with_none"]
        # the diagonal is the accuracy of the quarter+none population
        assert np.trace(confusion) / confusion.sum() == pytest.approx(scores["accuracy_quarter_with_none"])


def test_evaluation_is_json_and_recomputable(trained: IsolationTraining) -> None:
    json.dumps(trained.evaluation, allow_nan=False)
    assert evaluate_isolation(trained.database, trained.classifiers) == trained.evaluation


def test_quarter_accuracy_well_above_chance(trained: IsolationTraining) -> None:
    # Among the 3 fault classes (k, m, b) chance is 1/3. The strong features isolate every fault at
    # least a quarter of the way to a limit at noise 0 (100 % on the shipped database); on this small
    # database (about 60 such test frames) seeds 0-9 gave 0.968-1.0 (seed 0: 61/62 = 0.984), so 0.9
    # is far above chance and still leaves room for numerical drift across library versions.
    # The paper's peaks alone confuse k and m (both move sqrt(k/m)): seeds 0-9 gave 0.50-0.74 here and
    # 0.65 on the shipped database, so for them we only ask for better than chance.
    scores = trained.evaluation["variants"]
    assert scores["strong"]["by_noise"]["0"]["n"]["quarter"] >= 40
    assert scores["strong"]["by_noise"]["0"]["accuracy_quarter"] >= 0.9
    assert scores["paper"]["by_noise"]["0"]["accuracy_quarter"] > 1.0 / 3.0


def test_save_and_load_give_identical_probabilities(trained: IsolationTraining, tmp_path: Path) -> None:
    db = trained.database
    for variant, classifier in trained.classifiers.items():
        path = classifier.save(tmp_path / f"{variant}.safetensors")
        loaded = FaultClassifier.load(path)
        assert loaded.classes == classifier.classes and loaded.variant == variant
        features = db.features[variant]
        assert np.array_equal(loaded.predict_proba(features), classifier.predict_proba(features))


def test_a_variant_is_reproducible_alone(trained: IsolationTraining) -> None:
    # each variant trains from its own child generator: training only "strong" with the same seed
    # gives the same network as training both
    alone = train_isolation(spring_mass_damper(), np.random.default_rng(SEED), SMALL, variants=("strong",))
    features = trained.database.features["strong"]
    assert np.array_equal(alone.database.features["strong"], features)
    assert np.array_equal(alone.classifiers["strong"].predict_proba(features),
                          trained.classifiers["strong"].predict_proba(features))


def test_shipped_classifier_path() -> None:
    path = shipped_classifier_path("spring_mass_damper")
    assert path.name == "spring_mass_damper_strong.safetensors"
    assert path.parent.name == "data" and path.parent.parent.name == "ea_gym"
    assert shipped_classifier_path("rlc_circuit", "paper").name == "rlc_circuit_paper.safetensors"


def test_unknown_model_names_the_script() -> None:
    with pytest.raises(FileNotFoundError, match=r"python experiments/build/train_isolation\.py"):
        load_shipped_classifier("no_such_model")
    with pytest.raises(ValueError, match="variant"):
        load_shipped_classifier("spring_mass_damper", "weak")


@pytest.mark.parametrize("variant", VARIANTS)
def test_shipped_classifier_matches_the_features(trained: IsolationTraining, variant: str) -> None:
    if not shipped_classifier_path("spring_mass_damper", variant).is_file():
        pytest.skip("run python experiments/build/train_isolation.py to write the shipped classifiers")
    classifier = load_shipped_classifier("spring_mass_damper", variant)
    assert classifier.variant == variant
    assert classifier.classes == trained.database.classes
    # stale if the feature definitions changed since it was trained
    assert classifier.n_features == trained.database.features[variant].shape[1]
    probabilities = classifier.predict_proba(trained.database.features[variant][:5])
    assert probabilities.shape == (5, 4) and np.allclose(probabilities.sum(axis=1), 1.0)


def test_single_threaded_torch_restores_the_thread_count() -> None:
    import torch

    from ea_gym.threads import single_threaded_torch

    before = torch.get_num_threads()
    with single_threaded_torch():
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before


def test_predict_proba_is_the_network_modules_forward_and_each_row_its_own(trained: IsolationTraining) -> None:
    import torch

    features = trained.database.features["strong"]
    shipped = load_shipped_classifier("spring_mass_damper", "strong")
    for classifier in (trained.classifiers["strong"], shipped):
        inputs = torch.from_numpy((features - classifier.mean) / classifier.scale)
        with torch.no_grad():
            by_modules = torch.softmax(classifier.network(inputs), dim=1).numpy()
        batch = classifier.predict_proba(features)
        np.testing.assert_allclose(batch, by_modules, rtol=1e-12, atol=1e-15)
        # a row alone (a single environment's) and among the others (a batch of alarmed systems, its rows split
        # over two kernel threads): the same bits
        alone = np.concatenate([classifier.predict_proba(features[i : i + 1]) for i in range(len(features))])
        previous = kernel_threads()
        try:
            set_kernel_threads(2)
            assert len(features) >= 2 * MIN_ROWS_PER_THREAD  # enough rows to split
            assert alone.tobytes() == batch.tobytes() == classifier.predict_proba(features).tobytes()
        finally:
            set_kernel_threads(previous)
    # training anew replaces the network: inference follows it
    retrained = FaultClassifier(shipped.classes, "strong", shipped.n_features)
    retrained.predict_proba(features[:1])
    retrained.fit(features, trained.database.labels, (features, trained.database.labels), np.random.default_rng(1), TrainingConfig(epochs=3))
    inputs = torch.from_numpy((features - retrained.mean) / retrained.scale)
    with torch.no_grad():
        np.testing.assert_allclose(retrained.predict_proba(features), torch.softmax(retrained.network(inputs), dim=1).numpy(), rtol=1e-12, atol=1e-15)


def test_mlp_probabilities_by_hand() -> None:
    from ea_gym._kernels.network import mlp_probabilities

    # one hidden unit: h = tanh(1 * x0 - 1 * x1 + 0.5); logits (2h, -h + 1)
    weights = (np.array([[1.0], [-1.0]]), np.array([[2.0, -1.0]]))
    biases = (np.array([0.5]), np.array([0.0, 1.0]))
    x = np.array([[0.25, 1.0], [0.0, 0.0]])
    h = np.tanh(x[:, 0] - x[:, 1] + 0.5)
    logits = np.stack([2 * h, -h + 1], axis=1)
    expected = np.exp(logits) / np.exp(logits).sum(axis=1, keepdims=True)
    probabilities = np.empty((2, 2))
    assert mlp_probabilities(x, np.zeros(2), np.ones(2), weights, biases, probabilities)
    np.testing.assert_allclose(probabilities, expected, rtol=1e-15)
    # standardised inside: the inputs shifted and scaled back give the same bits; a NaN input is reported
    mean, scale = np.array([0.5, -2.0]), np.array([4.0, 0.5])
    standardised = np.empty((2, 2))
    assert mlp_probabilities(x * scale + mean, mean, scale, weights, biases, standardised)
    assert standardised.tobytes() == probabilities.tobytes()
    assert not mlp_probabilities(np.array([[np.nan, 0.0]]), mean, scale, weights, biases, np.empty((1, 2)))
