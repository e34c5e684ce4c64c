"""Figures of the isolation database and of the networks' test scores (paper Fig 8 and beyond)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ea_gym.diagnosis.database import FaultDatabase
from ea_gym.diagnosis.training import MAGNITUDE_BINS, noise_key
from ea_gym.files import save_figure
from ea_gym.pyplot import plt


def percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def _class_colours(classes: Sequence[str]) -> dict[str, str]:
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    return {name: ("0.45" if i == 0 else palette[(i - 1) % len(palette)]) for i, name in enumerate(classes)}


def plot_peaks(database: FaultDatabase, path: Path) -> Path:
    """Fig 8: largest residual peak of each frame, frequency vs relative amplitude, per class and noise level."""
    levels = sorted({float(v) for v in database.noise})
    features = database.features["paper"]
    colours = _class_colours(database.classes)
    fig, axes = plt.subplots(1, len(levels), figsize=(4.6 * len(levels), 4.4), sharex=True, sharey=True, squeeze=False)
    for ax, level in zip(axes[0], levels):
        for i, name in enumerate(database.classes):
            rows = (database.labels == i) & (database.noise == level)
            frequency, amplitude = features[rows, 0], features[rows, 1]
            has_peak = amplitude > 0
            missing = int((~has_peak).sum())
            label = f"{name}: {int(rows.sum())} frames" + (f", {missing} without a peak (not shown)" if missing else "")
            ax.scatter(frequency[has_peak], amplitude[has_peak], marker="x", s=14, linewidths=0.8,
                       color=colours[name], alpha=0.6, label=label)
        ax.set_yscale("log")
        ax.set_title(f"sensor noise {level:g} of RMS")
        ax.set_xlabel("frequency of the largest peak (Hz)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper center", markerscale=1.5, framealpha=0.9)
    axes[0, 0].set_ylabel("relative amplitude of the largest peak")
    fig.suptitle("Isolation database: STFT peaks of the mass's EA residual (cf. the paper's Fig 8)")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_confusion(evaluation: dict, path: Path) -> Path:
    """Grid of confusion matrices: rows the variants, columns the noise levels; colour = row fraction."""
    classes = evaluation["classes"]
    variants = list(evaluation["variants"])
    levels = evaluation["noise_levels"]
    fig, axes = plt.subplots(len(variants), len(levels), figsize=(3.3 * len(levels) + 0.6, 3.2 * len(variants)), squeeze=False)
    image = None
    for r, variant in enumerate(variants):
        for c, level in enumerate(levels):
            scores = evaluation["variants"][variant]["by_noise"][noise_key(level)]
            counts = np.asarray(scores["confusion"], dtype=float)
            totals = counts.sum(axis=1, keepdims=True)
            fraction = np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)
            ax = axes[r, c]
            image = ax.imshow(fraction, cmap="Blues", vmin=0, vmax=1)
            for i in range(len(classes)):
                for j in range(len(classes)):
                    ax.text(j, i, f"{int(counts[i, j])}", ha="center", va="center", fontsize=9,
                            color="white" if fraction[i, j] > 0.6 else "black")
            ax.set_xticks(range(len(classes)), classes)
            ax.set_yticks(range(len(classes)), classes)
            ax.set_title(f"{variant}, noise {level:g}: {percent(scores['accuracy_quarter_with_none'])}", fontsize=9)
            if r == len(variants) - 1:
                ax.set_xlabel("predicted")
            if c == 0:
                ax.set_ylabel("true")
    fig.suptitle("Test confusion (faults >= 1/4 of the way to a limit + fault-free); colour: fraction of the row")
    fig.tight_layout(rect=(0, 0, 0.93, 1))
    if image is not None:
        fig.colorbar(image, cax=fig.add_axes((0.94, 0.15, 0.015, 0.7)))
    return save_figure(fig, path)


def plot_accuracy_vs_magnitude(evaluation: dict, path: Path) -> Path:
    """Accuracy per fault-magnitude bin, one panel per variant, one line per noise level."""
    variants = list(evaluation["variants"])
    fig, axes = plt.subplots(1, len(variants), figsize=(5.2 * len(variants), 4.0), sharey=True, squeeze=False)
    centres = [0.5 * (low + high) for low, high in MAGNITUDE_BINS]
    labels = [f"[{low:g}, {high:g}{']' if k == len(MAGNITUDE_BINS) - 1 else ')'}" for k, (low, high) in enumerate(MAGNITUDE_BINS)]
    n_classes = len(evaluation["classes"]) - 1
    for ax, variant in zip(axes[0], variants):
        for level in evaluation["noise_levels"]:
            entries = evaluation["variants"][variant]["by_noise"][noise_key(level)]["accuracy_vs_magnitude"]
            accuracy = [np.nan if e["accuracy"] is None else e["accuracy"] for e in entries]
            ax.plot(centres, accuracy, marker="o", label=f"noise {level:g}")
        ax.axhline(1.0 / n_classes, color="0.5", ls=":", lw=1, label=f"chance among {n_classes} faults")
        ax.axvline(0.25, color="0.7", ls="--", lw=1)
        ax.set_xticks(centres, labels)
        ax.set_ylim(0, 1.03)
        ax.set_xlabel("fault magnitude (fraction of the way from nominal to the limit)")
        ax.set_title(f"{variant} features")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    axes[0, 0].set_ylabel("test isolation accuracy (fault frames)")
    fig.tight_layout()
    return save_figure(fig, path)
