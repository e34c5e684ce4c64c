"""The fault-isolation network: a small torch MLP over frame features, with its own standardisation.

Saved as safetensors (the weights and the standardisation as float64 arrays, classes, variant and layer
widths in its metadata) and read with ``safetensors.numpy``, so that a file cannot run code. Loading and
inference need no torch (the forward pass is compiled, ``ea_gym._kernels.network``): torch is imported to
train a network, or to read an older file.
Files written by ``torch.save`` (a zip of tensors) are read with ``torch.load(..., weights_only=True)``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from pickle import UnpicklingError  # what torch.load(weights_only=True) raises on a payload it refuses to run
from typing import TYPE_CHECKING

import numpy as np

from ea_gym._kernels.network import mlp_probabilities
from ea_gym.diagnosis.features import VARIANTS
from ea_gym.files import write_atomic
from ea_gym.threads import over_rows, single_threaded_torch

if TYPE_CHECKING:
    import torch
    from torch import nn

#: the first bytes of a zip archive, the container of ``torch.save``
_ZIP_MAGIC = b"PK\x03\x04"
_NOT_FINITE = "features contain NaN or inf"


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
    import torch

    with torch.random.fork_rng(devices=[]):
        if seed is not None:
            torch.manual_seed(seed)
        return _layers(n_features, hidden, n_classes)


def _layers(n_features: int, hidden: Sequence[int], n_classes: int) -> nn.Sequential:
    from torch import nn

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
        weights: the network's state (torch's names, float64 arrays), as read from a file; None: untrained.
    """

    def __init__(
        self, classes: Sequence[str], variant: str, n_features: int, hidden: Sequence[int] = (64, 64), weights: dict[str, np.ndarray] | None = None
    ):
        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {', '.join(VARIANTS)} (the feature sets), got {variant!r}")
        self.classes = tuple(classes)
        self.variant = variant
        self.hidden = tuple(hidden)
        self.mean = np.zeros(n_features)
        self.scale = np.ones(n_features)
        # the weights as read from a file, until the network is built from them
        self._weights = weights
        self._network: nn.Sequential | None = None
        # the linear layers' weights (transposed) and biases as numpy arrays, for inference; rebuilt when
        # the network is trained anew
        self._inference: tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]] | None = None

    @property
    def n_features(self) -> int:
        return len(self.mean)

    @property
    def network(self) -> nn.Sequential:
        """The torch network, built on first use (with the weights read from a file, if any)."""
        if self._network is None:
            import torch

            self._network = _network(self.n_features, self.hidden, len(self.classes))
            if self._weights is not None:
                self._network.load_state_dict({name: torch.from_numpy(value) for name, value in self._weights.items()})
                self._weights = None
        return self._network

    def _checked(self, features: np.ndarray) -> np.ndarray:
        """``features`` as float64, of shape (n, n_features)."""
        features = np.asarray(features, dtype=float)
        if features.ndim != 2 or features.shape[1] != self.n_features:
            raise ValueError(f"features must have shape (n, {self.n_features}), got {features.shape}")
        return features

    def _standardized(self, features: np.ndarray) -> np.ndarray:
        features = self._checked(features)
        if not np.isfinite(features).all():
            raise ValueError(_NOT_FINITE)
        return (features - self.mean) / self.scale

    def _inputs(self, features: np.ndarray) -> torch.Tensor:
        import torch

        return torch.from_numpy(self._standardized(features))

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
        import torch
        from torch import nn

        self._network = _network(features.shape[1], config.hidden, len(self.classes), seed=int(rng.integers(2**31)))
        self._weights = None
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
        self._inference = None  # inference reads the new weights
        return {"validation_accuracy": best, "final_loss": float(loss.detach())}

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        """Class probabilities, (n, n_classes): the network's forward and softmax, compiled
        (``ea_gym._kernels.network``), within ~1e-15 of torch's. Each row's probabilities are the same
        to the bit whatever rows come with it (a single environment's row and the same row in a batch),
        which torch's batched matrix product does not promise. Needs no torch for a network read from a
        file."""
        weights, biases = self._inference_layers()
        features = self._checked(features)
        probabilities = np.empty((len(features), len(biases[-1])))
        finite: list[bool] = []

        def rows_of_probabilities(start: int, stop: int) -> None:
            finite.append(mlp_probabilities(features[start:stop], self.mean, self.scale, weights, biases, probabilities[start:stop]))

        over_rows(rows_of_probabilities, len(features))
        if not all(finite):
            raise ValueError(_NOT_FINITE)
        return probabilities

    def _inference_layers(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """The linear layers' weights, transposed to (in, out) and contiguous, and their biases, in order."""
        if self._inference is None:
            if self._network is None and self._weights is not None:
                state = self._weights
            else:
                state = {name: value.detach().numpy() for name, value in self.network.state_dict().items()}
            # an nn.Sequential's keys: "<index>.weight" and "<index>.bias" of its linear layers
            indices = sorted({int(name.split(".")[0]) for name in state})
            weights = tuple(np.ascontiguousarray(np.asarray(state[f"{i}.weight"], dtype=float).T) for i in indices)
            biases = tuple(np.ascontiguousarray(state[f"{i}.bias"], dtype=float) for i in indices)
            self._inference = (weights, biases)
        return self._inference

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write weights, standardisation and metadata as safetensors (atomically)."""
        from safetensors.numpy import save

        tensors = {f"network.{name}": value.detach().numpy() for name, value in self.network.state_dict().items()}
        tensors |= {"mean": self.mean, "scale": self.scale}
        metadata = {"classes": json.dumps(list(self.classes)), "variant": self.variant, "hidden": json.dumps(list(self.hidden))}
        data = save(tensors, metadata=metadata)
        return write_atomic(path, lambda tmp: Path(tmp).write_bytes(data))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> FaultClassifier:
        """Read a file written by ``save`` (or by ``torch.save`` before) without unpickling anything.

        Raises:
            ValueError: not such a file (the message names it and what is wrong).
        """
        from safetensors import SafetensorError

        try:
            with open(path, "rb") as file:
                zipped = file.read(len(_ZIP_MAGIC)) == _ZIP_MAGIC
            return cls._load_torch(path) if zipped else cls._load_safetensors(path)
        except (KeyError, TypeError, ValueError, RuntimeError, OSError, UnpicklingError, SafetensorError) as error:
            raise ValueError(f"{os.fspath(path)}: not an isolation network ({type(error).__name__}: {error})") from None

    @classmethod
    def _load_safetensors(cls, path: str | os.PathLike[str]) -> FaultClassifier:
        from safetensors import safe_open

        with safe_open(os.fspath(path), framework="numpy") as file:
            metadata = file.metadata() or {}
            tensors = {name: file.get_tensor(name) for name in file.keys()}
        mean, scale = tensors.pop("mean"), tensors.pop("scale")
        weights = {name.removeprefix("network."): value for name, value in tensors.items()}
        classifier = cls(json.loads(metadata["classes"]), metadata["variant"], len(mean), json.loads(metadata["hidden"]), weights)
        classifier.mean, classifier.scale = mean, scale
        return classifier

    @classmethod
    def _load_torch(cls, path: str | os.PathLike[str]) -> FaultClassifier:
        import torch

        payload = torch.load(path, weights_only=True)
        classifier = cls(payload["classes"], payload["variant"], len(payload["mean"]), payload["hidden"])
        classifier.network.load_state_dict(payload["state"])
        classifier.mean = payload["mean"].numpy()
        classifier.scale = payload["scale"].numpy()
        return classifier
