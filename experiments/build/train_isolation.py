"""Train the spring-mass-damper's fault-isolation networks (paper 4.2) and report how well they isolate.

What it does
    1. Simulates the fault database of ``ea_gym.models.spring_mass_damper()`` once
       (``ea_gym.diagnosis.database.build_database``): each degradable parameter (k, m, b) swept over
       its safe range in 20 intervals (Table 2), under random loads and three sensor-noise levels,
       beside fault-free runs; runs split 70/15/15 into training, validation and test sets.
    2. Trains one classifier per feature variant (``paper``: the STFT peaks of the mass's EA residual;
       ``strong``: those plus relative EA residuals, EAI residuals, energy-balance deviations and the
       noise level) with ``ea_gym.diagnosis.training.train_isolation``.
    3. Scores both on the same held-out test runs, per noise level, and writes under ``--out``:
       ``isolation.json`` (all numbers), ``isolation.md`` (the readable report), ``fig8_peaks.png``
       (the paper's Fig 8: largest residual peak, frequency vs amplitude, per class),
       ``confusion.png`` (confusion matrices, variants x noise levels) and
       ``accuracy_vs_magnitude.png``.
    4. Unless ``--no-ship``, saves the networks as ``ea_gym/data/spring_mass_damper_{paper,strong}.safetensors``,
       the classifiers the package loads with ``ea_gym.diagnosis.training.load_shipped_classifier``.

How to run (from the repository root; about a minute on a laptop)
    python experiments/build/train_isolation.py [--seed 0] [--out experiments/results/isolation] [--no-ship] [--smoke]

``--smoke`` trains on a small database for a few epochs and ships nothing.

The database options (``--intervals``, ``--loads``, ``--fault-free-runs``, ``--noise-levels``,
``--frame-ends``) and ``--epochs`` default to the package's ``DatabaseConfig`` and ``TrainingConfig``;
change them only for experiments, not for the shipped networks.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.diagnosis.classifier import TrainingConfig
from ea_gym.diagnosis.database import DatabaseConfig, FaultDatabase
from ea_gym.diagnosis.features import N_PEAKS, VARIANTS
from ea_gym.diagnosis.figures import percent, plot_accuracy_vs_magnitude, plot_confusion, plot_peaks
from ea_gym.diagnosis.training import (
    MAGNITUDE_BINS,
    IsolationTraining,
    noise_key,
    shipped_classifier_path,
    train_isolation,
)
from ea_gym.files import write_json, write_text
from ea_gym.models import spring_mass_damper
from experiments.common import parse_with_smoke

MODEL_NAME = "spring_mass_damper"
SPLITS = ("train", "validation", "test")
#: the smoke run: a small database (2 loads, 4 intervals, 2 noise levels, 2 frames per run), 50 epochs, nothing shipped
SMOKE = {"no_ship": True, "intervals": 4, "loads": 2, "fault_free_runs": 3, "noise_levels": [0.0, 0.05], "frame_ends": [30.0, 40.0], "epochs": 50}
POPULATIONS = (
    ("accuracy_quarter", "quarter", "faults >= 1/4 of the way to a limit"),
    ("accuracy_quarter_with_none", "quarter_with_none", "the same + fault-free"),
    ("accuracy_all", "all", "every test frame"),
)


def _parser() -> argparse.ArgumentParser:
    db, tr = DatabaseConfig(), TrainingConfig()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=0, help="seed of the whole run (default 0)")
    parser.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "isolation", help="results folder")
    parser.add_argument("--no-ship", action="store_true", help="do not overwrite ea_gym/data/spring_mass_damper_*.safetensors")
    parser.add_argument("--intervals", type=int, default=db.intervals, help=f"intervals per safe range (default {db.intervals})")
    parser.add_argument("--loads", type=int, default=db.n_loads, help=f"random loads (default {db.n_loads})")
    parser.add_argument("--fault-free-runs", type=int, default=db.fault_free_runs,
                        help=f"extra fault-free runs per load and noise level (default {db.fault_free_runs})")
    parser.add_argument("--noise-levels", type=float, nargs="+", default=list(db.noise_levels),
                        help=f"sensor noise fractions of RMS (default {' '.join(map(str, db.noise_levels))})")
    parser.add_argument("--frame-ends", type=float, nargs="+", default=list(db.frame_ends),
                        help=f"end times (s) of the frames taken from each run (default {' '.join(map(str, db.frame_ends))})")
    parser.add_argument("--epochs", type=int, default=tr.epochs, help=f"training epochs (default {tr.epochs})")
    return parser


# --------------------------------------------------------------------------------------------------
# numbers
# --------------------------------------------------------------------------------------------------


def database_summary(database: FaultDatabase) -> dict[str, Any]:
    """Sizes of the database: frames and runs per split, frames per class (per split), feature counts."""
    classes = database.classes
    return {
        "frames": len(database.labels),
        "runs": int(np.unique(database.run).size),
        "features": {variant: int(f.shape[1]) for variant, f in database.features.items()},
        "class_counts": {name: int((database.labels == i).sum()) for i, name in enumerate(classes)},
        "split_frames": {name: int((database.split == s).sum()) for s, name in enumerate(SPLITS)},
        "split_runs": {name: int(np.unique(database.run[database.split == s]).size) for s, name in enumerate(SPLITS)},
        "class_counts_by_split": {
            name: {c: int(((database.split == s) & (database.labels == i)).sum()) for i, c in enumerate(classes)}
            for s, name in enumerate(SPLITS)
        },
        "noise_levels": sorted({float(v) for v in database.noise}),
    }


def summary_rows(evaluation: dict) -> list[list[str]]:
    """One row per variant and noise level: accuracies of the three populations and their sizes."""
    rows = []
    for variant, result in evaluation["variants"].items():
        entries = [(noise_key(level), result["by_noise"][noise_key(level)]) for level in evaluation["noise_levels"]]
        for key, scores in [*entries, ("pooled", result["pooled"])]:
            row = [variant, key]
            for accuracy, population, _ in POPULATIONS:
                row.append(f"{percent(scores[accuracy])} (n={scores['n'][population]})")
            rows.append(row)
    return rows


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def _plain_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(str(x)) for x in column) for column in zip(header, *rows)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join([fmt.format(*header), fmt.format(*("-" * w for w in widths)), *(fmt.format(*r) for r in rows)])


SUMMARY_HEADER = ("variant", "noise", "acc. faults >= 1/4", "acc. + fault-free", "acc. all test frames")


# --------------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------------


def _reading(evaluation: dict) -> list[str]:
    """A few generated sentences: each variant's pooled acceptance accuracy and its largest confusion."""
    classes = evaluation["classes"]
    lines = []
    for variant, res in evaluation["variants"].items():
        pooled = res["pooled"]
        counts = np.asarray(pooled["confusion"])
        off = counts - np.diag(np.diag(counts))
        sentence = f"* **{variant}**: {percent(pooled['accuracy_quarter'])} of the faults >= 1/4 isolated over all noise levels"
        if off.sum() > 0:
            i, j = np.unravel_index(int(off.argmax()), off.shape)
            sentence += (f"; its largest confusion is true {classes[i]} predicted {classes[j]} "
                         f"({int(off[i, j])} of the {int(counts[i].sum())} {classes[i]} frames of that population)")
            if {classes[i], classes[j]} == {"k", "m"}:
                sentence += (", as expected: k and m both move the natural frequency sqrt(k/m)/(2 pi), so "
                             "the spectral peaks of the mass's EA residual alone hardly tell them apart")
        lines.append(sentence + ".")
    return ["Reading:", "", *lines, ""]


def markdown_report(result: dict[str, Any]) -> str:
    """The readable report of ``isolation.json``'s content."""
    evaluation = result["evaluation"]
    classes = evaluation["classes"]
    db = result["database"]
    config = result["database_config"]
    lines = [
        "# Fault isolation on the spring-mass-damper (paper 4.2)",
        "",
        f"Command: `{result['command']}` (seed {result['seed']}; wall time {result['wall_seconds']:.1f} s; "
        f"torch {result['versions']['torch']}, numpy {result['versions']['numpy']}).",
        "",
        "## Feature variants",
        "",
        "* **paper**: the paper's features alone: the frequencies and relative amplitudes of the "
        f"{N_PEAKS} largest peaks of the STFT (window = the {config['frame']:g} s frame) of the EA residual of the "
        "I element (the mass), noisy peaks (above the excitation bandwidth or below 5 % of the largest) "
        "removed.",
        "* **strong**: the paper's peaks plus, for every element, the relative EA residual over the frame "
        "and over each of its halves, the residuals of every component's EAI (its share of the components' "
        "EA), the least-squares relative deviations of the components' coefficients from the junction's "
        "energy balance, and the measured signals' noise level.",
        "",
        "Both networks are the same MLP "
        f"(hidden {tuple(result['training_config']['hidden'])}, tanh, full-batch Adam, "
        f"{result['training_config']['epochs']} epochs, the epoch with the best validation accuracy kept), "
        "trained on the same training runs and scored on the same held-out test runs.",
        "",
        "## Database",
        "",
        f"{db['runs']} runs, {db['frames']} frames ({len(config['frame_ends'])} frames per run, ending at "
        f"{', '.join(f'{t:g}' for t in config['frame_ends'])} s): each parameter's safe range in "
        f"{config['intervals']} intervals x {config['n_loads']} random loads x noise levels "
        f"{', '.join(f'{v:g}' for v in config['noise_levels'])} (fraction of RMS), plus "
        f"{config['fault_free_runs']} fault-free runs per load and noise level. Runs (not frames) are split "
        f"{'/'.join(f'{100 * f:g}' for f in config['split'])} into training/validation/test.",
        "",
        _table(
            ("split", "runs", "frames", *classes),
            [
                [name, str(db["split_runs"][name]), str(db["split_frames"][name]),
                 *(str(db["class_counts_by_split"][name][c]) for c in classes)]
                for name in SPLITS
            ]
            + [["all", str(db["runs"]), str(db["frames"]), *(str(db["class_counts"][c]) for c in classes)]],
        ),
        "",
        f"Time: database {result['training']['database_seconds']:.1f} s; "
        + "; ".join(
            f"{v} network {info['seconds']:.1f} s ({info['n_features']} features, best validation accuracy "
            f"{percent(info['validation_accuracy'])})"
            for v, info in result["training"]["variants"].items()
        )
        + ".",
        "",
        "## Test accuracy",
        "",
        "Populations (test frames of one noise level): *faults >= 1/4*: fault frames whose parameter is at "
        "least a quarter of the way from nominal to the safe limit (the acceptance population); "
        "*+ fault-free*: the same plus the fault-free frames; *all*: every test frame, the smallest faults "
        "(less than a quarter of the way, which barely change the EA) included.",
        "",
        _table(SUMMARY_HEADER, summary_rows(evaluation)),
        "",
        *_reading(evaluation),
        "## Confusion matrices",
        "",
        "Rows: true class; columns: predicted class; test frames with a fault >= 1/4 of the way to a limit, "
        "plus the fault-free frames.",
        "",
    ]
    for variant, res in evaluation["variants"].items():
        for level in evaluation["noise_levels"]:
            scores = res["by_noise"][noise_key(level)]
            lines += [f"**{variant}, noise {level:g}** (per-class recall: "
                      + ", ".join(f"{c} {percent(a)}" for c, a in scores["per_class_accuracy"].items()) + ")", ""]
            lines.append(_table(["true \\ predicted", *classes],
                                [[c, *map(str, row)] for c, row in zip(classes, scores["confusion"])]))
            lines.append("")
    lines += ["![confusion matrices](confusion.png)", "", "## Accuracy against fault magnitude", "",
              "Fault test frames only; magnitude = fraction of the way from nominal to the safe limit on the "
              "fault's side.", ""]
    bins = [f"[{low:g}, {high:g}{']' if k == len(MAGNITUDE_BINS) - 1 else ')'}" for k, (low, high) in enumerate(MAGNITUDE_BINS)]
    rows = []
    for variant, res in evaluation["variants"].items():
        for level in evaluation["noise_levels"]:
            entries = res["by_noise"][noise_key(level)]["accuracy_vs_magnitude"]
            rows.append([variant, f"{level:g}", *(f"{percent(e['accuracy'])} (n={e['n']})" for e in entries)])
    lines += [_table(("variant", "noise", *bins), rows), "", "![accuracy vs magnitude](accuracy_vs_magnitude.png)", "",
              "## The paper's Fig 8", "",
              "The paper-variant features of the whole database: frequency and relative amplitude (amplitude of "
              "the STFT of the mass's EA residual over the frame's mean reference EA) of each frame's largest "
              "residual peak, one colour per class. Fault-free frames have no residual peak at noise 0.", "",
              "![Fig 8](fig8_peaks.png)", ""]
    if result["shipped"]:
        lines += ["## Shipped networks", "", *(f"* `{p}`" for p in result["shipped"]), ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------------
# main
# --------------------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_with_smoke(_parser(), argv, SMOKE)
    command = shlex.join(["python", "experiments/build/train_isolation.py", *(sys.argv[1:] if argv is None else argv)])
    config = dataclasses.replace(
        DatabaseConfig(),
        intervals=args.intervals,
        n_loads=args.loads,
        fault_free_runs=args.fault_free_runs,
        noise_levels=tuple(args.noise_levels),
        frame_ends=tuple(args.frame_ends),
    )
    training_config = dataclasses.replace(TrainingConfig(), epochs=args.epochs)
    model = spring_mass_damper()

    start = time.perf_counter()
    with tqdm(total=len(VARIANTS) + 2, desc="isolation", unit="stage", file=sys.stderr) as bar:
        def progress(stage: str, done: int, total: int) -> None:
            bar.n = done
            bar.set_description(stage)
            bar.refresh()

        result: IsolationTraining = train_isolation(model, np.random.default_rng(args.seed), config, training_config, progress)

    shipped = []
    if not args.no_ship:
        for variant, classifier in result.classifiers.items():
            path = classifier.save(shipped_classifier_path(MODEL_NAME, variant))
            try:
                shipped.append(str(path.resolve().relative_to(ROOT)))
            except ValueError:
                shipped.append(str(path))

    out = args.out
    plot_peaks(result.database, out / "fig8_peaks.png")
    plot_confusion(result.evaluation, out / "confusion.png")
    plot_accuracy_vs_magnitude(result.evaluation, out / "accuracy_vs_magnitude.png")
    report = {
        "command": command,
        "seed": args.seed,
        "model": MODEL_NAME,
        "database_config": dataclasses.asdict(config),
        "training_config": dataclasses.asdict(training_config),
        "database": database_summary(result.database),
        "training": result.training,
        "wall_seconds": time.perf_counter() - start,
        "shipped": shipped,
        "versions": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "torch": torch.__version__,
            "machine": platform.platform(),
        },
        "evaluation": result.evaluation,
    }
    write_json(out / "isolation.json", report)
    write_text(out / "isolation.md", markdown_report(report))

    print(_plain_table(SUMMARY_HEADER, summary_rows(result.evaluation)))
    print(f"\n{report['database']['frames']} frames ({report['database']['split_frames']['test']} test), "
          f"wall time {report['wall_seconds']:.1f} s; results in {out}"
          + (f"; shipped {', '.join(shipped)}" if shipped else "; nothing shipped (--no-ship)"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
