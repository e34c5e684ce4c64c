"""The fault-isolation network: a small torch MLP over frame features, with its own standardisation.

Saved as a plain dict of tensors and strings and loaded with ``torch.load(..., weights_only=True)``,
so a shipped file cannot run code.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ea_gym.files import write_atomic
from ea_gym.threads import single_threaded_torch


@dataclass(frozen=True)
class TrainingConfig:
    """Optimiser settings: full-batch Adam with weight decay, best validation epoch kept."""

    hidden: tuple[int, ...] = (64, 64)
    epochs: int = 400
    learning_rate: float = 3e-3
    weight_decay: float = 1e-4


def _network(n_features: int, hidden: Sequence[int], n_classes: int, seed: int | None = None) -> nn.Sequential:
    """The MLP, its initial weights drawn from ``seed`` (None: any, for weights loaded next) without
    touching torch's global random state."""
    with torch.random.fork_rng(devices=[]):
        if seed is not None:
            torch.manual_seed(seed)
        return _layers(n_features, hidden, n_classes)


def _layers(n_features: int, hidden: Sequence[int], n_classes: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    width = n_features
    for size in hidden:
        layers += [nn.Linear(width, size), nn.Tanh()]
        width = size
    layers.append(nn.Linear(width, n_classes))
    return nn.Sequential(*layers).double()


class FaultClassifier:
    """Class probabilities over ``classes`` (e.g. ["none", "k", "m", "b"]) from feature vectors.

    Args:
        classes: class names; index 0 is the fault-free class.
        variant: the feature set it reads (see ``ea_gym.diagnosis.features``).
        n_features: feature vector length.
        hidden: hidden layer widths.
    """

    def __init__(self, classes: Sequence[str], variant: str, n_features: int, hidden: Sequence[int] = (64, 64)):
        self.classes = tuple(classes)
        self.variant = variant
        self.hidden = tuple(hidden)
        self.network = _network(n_features, self.hidden, len(self.classes))
        self.mean = np.zeros(n_features)
        self.scale = np.ones(n_features)

    @property
    def n_features(self) -> int:
        return len(self.mean)

    def _inputs(self, features: np.ndarray) -> torch.Tensor:
        features = np.asarray(features, dtype=float)
        if features.ndim != 2 or features.shape[1] != self.n_features:
            raise ValueError(f"features must have shape (n, {self.n_features}), got {features.shape}")
        if not np.all(np.isfinite(features)):
            raise ValueError("features contain NaN or inf")
        return torch.from_numpy((features - self.mean) / self.scale)

    def fit(
        self,
        features: np.ndarray,
        labels: np.ndarray,
        validation: tuple[np.ndarray, np.ndarray],
        rng: np.random.Generator,
        config: TrainingConfig = TrainingConfig(),
    ) -> dict[str, float]:
        """Train on integer ``labels``; keep the weights of the epoch with the best validation accuracy."""
        with single_threaded_torch():
            return self._fit(features, labels, validation, rng, config)

    def _fit(
        self,
        features: np.ndarray,
        labels: np.ndarray,
        validation: tuple[np.ndarray, np.ndarray],
        rng: np.random.Generator,
        config: TrainingConfig,
    ) -> dict[str, float]:
        self.network = _network(features.shape[1], config.hidden, len(self.classes), seed=int(rng.integers(2**31)))
        self.hidden = config.hidden
        self.mean = features.mean(axis=0)
        self.scale = np.where(features.std(axis=0) > 0, features.std(axis=0), 1.0)
        x, y = self._inputs(features), torch.from_numpy(np.asarray(labels, dtype=np.int64))
        xv, yv = self._inputs(validation[0]), torch.from_numpy(np.asarray(validation[1], dtype=np.int64))
        optimiser = torch.optim.Adam(self.network.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay)
        loss_fn = nn.CrossEntropyLoss()
        best, best_state = -1.0, None
        for _ in range(config.epochs):
            optimiser.zero_grad()
            loss = loss_fn(self.network(x), y)
            loss.backward()
            optimiser.step()
            with torch.no_grad():
                accuracy = float((self.network(xv).argmax(1) == yv).double().mean())
            if accuracy > best:
                best, best_state = accuracy, {k: v.clone() for k, v in self.network.state_dict().items()}
        if best_state is not None:  # None only after no epoch
            self.network.load_state_dict(best_state)
        return {"validation_accuracy": best, "final_loss": float(loss.detach())}

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        """Class probabilities, (n, n_classes)."""
        with torch.no_grad():
            return torch.softmax(self.network(self._inputs(features)), dim=1).numpy()

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write weights, standardisation and metadata (atomically)."""
        payload = {
            "state": self.network.state_dict(),
            "mean": torch.from_numpy(self.mean),
            "scale": torch.from_numpy(self.scale),
            "classes": list(self.classes),
            "variant": self.variant,
            "hidden": list(self.hidden),
        }
        return write_atomic(path, lambda tmp: torch.save(payload, tmp))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> FaultClassifier:
        """Read a file written by ``save`` without unpickling arbitrary objects."""
        payload = torch.load(path, weights_only=True)
        model = cls(payload["classes"], payload["variant"], len(payload["mean"]), payload["hidden"])
        model.network.load_state_dict(payload["state"])
        model.mean = payload["mean"].numpy()
        model.scale = payload["scale"].numpy()
        return model
