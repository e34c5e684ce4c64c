"""The paper's section 4 end to end: Table 2 system, Fig 10 fault, isolation network, EoL (Table 3).

The stiffness falls from 100 N/m at 5 s at 0.3 N/m/s until a corrective action at 50 s, then recovers
linearly to 100 N/m at 100 s. The paper drives the system with a constant 10 N force; its response
dies out (the damping ratio is 0.8 %, so within a few minutes, and a static deflection carries no
power), which starves Energy Activity of information. The chain is run on the paper's setting and on
a persistently exciting load, noise-free and at 1 % sensor noise.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.files import write_json, write_text
from ea_gym.models import spring_mass_damper
from ea_gym.phm import ChainRun, ChainTiming, PHMChain, PHMConfig, build_chain, run_scenario
from ea_gym.reporting import write_phm_outputs
from ea_gym.scenario import Scenario, load_scenario

PAPER_TABLE_3 = {"eol_fault": 55.0, "eol_corrective": 113.0}
FAULT_PROFILE = [[0, 100], [5, 100], [50, 86.5], [100, 100]]
CORRECTIVE_START, CORRECTIVE_END = 50.0, 100.0
LOADS = {
    "constant": {"kind": "constant", "value": 10.0},
    "persistent": {
        "kind": "sines",
        "offset": 10.0,
        "sines": [{"amplitude": 5.0, "frequency": 0.3}, {"amplitude": 2.0, "frequency": 1.1, "phase": 0.5}],
    },
}
#: (name, load, noise) of the runs; the first two are the paper's own setting.
RUNS = (("constant_noise0", "constant", 0.0), ("constant_noise1", "constant", 0.01),
        ("persistent_noise0", "persistent", 0.0), ("persistent_noise1", "persistent", 0.01))


def paper_scenario(load: str, noise: float) -> Scenario:
    """Table 2 system, Fig 10 fault, 120 s at 100 Hz."""
    return load_scenario({
        "system": "spring_mass_damper",
        "limits": {"k": [85, 105]},
        "load": LOADS[load],
        "duration": 120.0,
        "fault": {"parameter": "k", "profile": FAULT_PROFILE},
        "sensors": {"noise": noise, "seed": 0},
    })


@dataclass(frozen=True)
class PhaseEoL:
    """The End of Life predicted at the last step of a phase of the profile, and the truth."""

    predicted: float | None
    true: float
    max_error_after: float | None  # largest |predicted - true| over the phase's predictions after ``after``


def phase_eol(run: ChainRun, chain: PHMChain, scenario: Scenario, start: float, end: float, after: float) -> PhaseEoL:
    """Last EoL predicted before ``end`` while k was isolated, and the worst error after ``after`` (s)."""
    if scenario.fault is None:
        raise ValueError("phase_eol needs a scenario with a fault")
    profile = scenario.fault.profile
    limits = scenario.model.safe_limits["k"]
    k_class = chain.classes.index("k")
    predicted = [
        (float(status.t[0]), float(status.eol[0])) for status in run.statuses
        if start < float(status.t[0]) < end and status.isolated[0] == k_class and np.isfinite(status.eol[0])
    ]
    true = float(profile.trend_end_of_life(np.array([0.5 * (start + end)]), limits)[0])
    if not predicted:
        return PhaseEoL(None, true, None)
    times, eols = np.array(predicted).T
    late = times > after
    worst = float(np.max(np.abs(eols[late] - true))) if np.any(late) else None
    return PhaseEoL(float(eols[-1]), true, worst)


def run_record(results: dict[str, Any], fault: PhaseEoL, corrective: PhaseEoL) -> dict[str, Any]:
    """A run's row of the summary from its ``chain_results`` and the phases' End of Life. The End of
    Life counts only from a run whose isolation named k in the end: after a wrong isolation, or none,
    it is None and ``isolation`` says why ("wrong", "undecided", "not detected")."""
    metrics = results["metrics"]
    right = metrics["isolation_outcome"] == "right"
    return {
        "detection_time": results["detection_time"],
        "isolated_parameter": results["isolated_parameter"],
        "isolation": metrics["isolation_outcome"],
        "favoured": results["isolation"]["favoured"],
        "estimation": metrics.get("estimation"),
        "eol_fault": fault.predicted if right else None,
        "eol_fault_true": fault.true,
        "eol_fault_max_error_after_30s": fault.max_error_after if right else None,
        "eol_corrective": corrective.predicted if right else None,
        "eol_corrective_true": corrective.true,
        "phases": metrics.get("eol_phases"),
    }


def reproduce(
    out: Path,
    classifier: FaultClassifier | None = None,
    seed: int = 0,
    progress: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Run everything and write ``out``: one directory per run, results.json and report.md."""
    from ea_gym.diagnosis.figures import plot_peaks
    from ea_gym.diagnosis.training import train_isolation

    started = time.perf_counter()
    model = spring_mass_damper()
    rng = np.random.default_rng(seed)
    training_summary = None
    if classifier is None:
        progress("training the isolation network (fault database of Table 2's ranges in 20 intervals)")
        training = train_isolation(model, rng, variants=("strong",))
        classifier = training.classifiers["strong"]
        training_summary = {"evaluation": training.evaluation, "training": training.training}
        plot_peaks(training.database, out / "fig8_peaks.png")
    runs = {}
    for name, load, noise in RUNS:
        progress(f"running the chain: {name}")
        scenario = paper_scenario(load, noise)
        chain = build_chain(model, PHMConfig(timing=ChainTiming(noise=noise)), classifier, np.random.default_rng(seed))
        run = run_scenario(scenario, chain, np.random.default_rng(seed + 1))
        results = write_phm_outputs(out / name, run, chain, scenario, f"Paper section 4, {load} load, noise {noise:.0%}")
        fault = phase_eol(run, chain, scenario, 5.0, CORRECTIVE_START, after=30.0)
        corrective = phase_eol(run, chain, scenario, CORRECTIVE_START, CORRECTIVE_END, after=CORRECTIVE_START + 30.0)
        runs[name] = {
            "load": load,
            "noise": noise,
            **run_record(results, fault, corrective),
            "ea_per_step": {
                element: [float(s.ea[0, j]) for s in run.statuses] for j, element in enumerate(chain.monitor.elements)
            },
        }
    headline = runs["persistent_noise1"]
    summary = {
        "eol_fault": headline["eol_fault"],
        "eol_corrective": headline["eol_corrective"],
        "eol_fault_true": headline["eol_fault_true"],
        "eol_corrective_true": headline["eol_corrective_true"],
        "paper_table_3": PAPER_TABLE_3,
        "headline_run": "persistent_noise1",
        "estimator": PHMConfig().estimator_kind,
        "runs": runs,
        "isolation_training": training_summary,
        "wall_time_s": None,
    }
    plot_information(runs, out / "information.png")
    summary["wall_time_s"] = round(time.perf_counter() - started, 2)
    write_text(out / "report.md", report_markdown(summary))
    write_json(out / "results.json", summary)
    return summary


def plot_information(runs: dict[str, dict], path: Path) -> Path:
    """EA of every element per step under the constant and the persistent load (noise-free runs)."""
    from ea_gym.files import save_figure
    from ea_gym.pyplot import plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, name in zip(axes, ("constant_noise0", "persistent_noise0")):
        for element, values in runs[name]["ea_per_step"].items():
            ax.semilogy(np.arange(1, len(values) + 1), np.maximum(values, 1e-12), label=element)
        ax.set_title(f"{runs[name]['load']} load: EA per 1 s step")
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("EA (J)")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)


def _number(value: float | None, unit: str = "s") -> str:
    return "-" if value is None else f"{value:.1f} {unit}"


def headline(summary: dict[str, Any]) -> str:
    """One line of the headline run's End of Life beside the truth and the paper, or why it has none."""
    run = summary["runs"][summary["headline_run"]]
    cells = []
    for cause, key, paper in (("fault", "eol_fault", 55), ("corrective action", "eol_corrective", 113)):
        cells.append(f"{cause}: {_eol_cell(run, summary[key])} (truth {summary[key + '_true']:.1f} s, paper {paper} s)")
    return f"End of Life, {'; '.join(cells)}"


def _isolation_mark(run: dict[str, Any]) -> str:
    """Why a run has no End of Life in the tables: "isolated b, wrong", "undecided, m favoured", "not detected"."""
    if run["isolation"] == "wrong":
        return f"isolated {run['isolated_parameter']}, wrong"
    if run["isolation"] == "undecided":
        return f"undecided, {run['favoured']} favoured"
    return str(run["isolation"])


def _eol_cell(run: dict[str, Any], eol: float | None) -> str:
    """A run's End of Life in Table 3: only from a run that isolated k, else why not."""
    return _number(eol) if run["isolation"] == "right" else f"- ({_isolation_mark(run)})"


# how each estimator kind estimates and extrapolates, for the report's first paragraph
ESTIMATOR_ROUTES = {
    "tracking": "a Kalman filter per hypothesis tracking the parameter and its drift, the drift carried to the safe limits",
    "ea_inversion": "the paper's EA inversion, its recent estimates' degree-1 trend extrapolated to the safe limits",
    "joint": "one Kalman filter over the states, every degradable parameter and its drift, each drift carried to the safe limits",
}


def report_markdown(summary: dict[str, Any]) -> str:
    """The reproduction report: Table 3 beside ours, every run, the information the loads carry."""
    runs = summary["runs"]
    lines = [
        "# Paper section 4, reproduced",
        "",
        "System of Table 2 (m = 10 kg, k = 100 N/m in [85, 105], b = 0.5 N s/m), fault of Fig 10: k falls from "
        "100 N/m at 5 s at 0.3 N/m/s, a corrective action at 50 s brings it back linearly to 100 N/m at 100 s. "
        "Detection, isolation (the neural network on EA-residual features, fused with the estimator's and the "
        f"energy balance's evidence), the estimate of k by the `{summary['estimator']}` estimator "
        f"(`PHMConfig.estimator_kind`: {ESTIMATOR_ROUTES[summary['estimator']]}).",
        "",
        "## End of Life (Table 3)",
        "",
        "The predicted EoL is the last prediction of each phase made while k was isolated; the ground truth is where "
        "the profile's current segment, extended, reaches the limit (the corrective phase's rate, 0.27 N/m/s from "
        "86.5 N/m at 50 s, reaches 105 N/m at 118.5 s; the paper reports 113 s). Only runs whose isolation named k "
        "in the end give an End of Life: a run that isolated another parameter (wrong) or none (undecided: no "
        "parameter reached the share of the belief the chain needs) is marked instead.",
        "",
        "| cause | paper | ground truth | " + " | ".join(runs) + " |",
        "|---|---|---|" + "---|" * len(runs),
        "| fault | 55 s | " + _number(summary["eol_fault_true"]) + " | "
        + " | ".join(_eol_cell(r, r["eol_fault"]) for r in runs.values()) + " |",
        "| corrective action | 113 s | " + _number(summary["eol_corrective_true"]) + " | "
        + " | ".join(_eol_cell(r, r["eol_corrective"]) for r in runs.values()) + " |",
        "",
        "## Every run",
        "",
        "| run | detection | isolated (the fault is in k) | k estimate error 10 s on (max / median, N/m) "
        "| fault-phase EoL error after 30 s (max, s) |",
        "|---|---|---|---|---|",
    ]
    for name, r in runs.items():
        estimation = r["estimation"] or {}
        error = f"{estimation['max']:.2f} / {estimation['median']:.2f}" if "max" in estimation else "-"
        isolated = "k" if r["isolation"] == "right" else _isolation_mark(r)
        lines.append(
            f"| [{name}]({name}/report.md) | {_number(r['detection_time'])} | {isolated} | "
            f"{error} | {_eol_cell(r, r['eol_fault_max_error_after_30s'])} |"
        )
    lines += [
        "",
        "## What the paper's constant load leaves to observe",
        "",
        "Under a constant force the spring-mass-damper rings down to a static deflection: its power, and so "
        "its Energy Activity, decays with the damping time 2m/b = 40 s, and what is left (the static "
        "deflection F/k) exchanges no power. Faults after the ring-down change EA only through the slow drift "
        "itself, so detection and estimation starve. A persistently exciting load (10 + 5 sin(2 pi 0.3 t) + "
        "2 sin(2 pi 1.1 t + 0.5) N) keeps every element active:",
        "",
        "![EA per element under both loads](information.png)",
        "",
    ]
    training = summary.get("isolation_training")
    if training:
        lines += [
            "## Isolation network",
            "",
            "The fault database (each parameter's safe range in 20 intervals, random loads, noise 0, 1 % and 5 %): "
            "the largest peak of the mass's EA-residual spectrum per frame, in the spirit of the paper's Fig 8.",
            "",
            "![Fig 8: residual peaks of the database](fig8_peaks.png)",
            "",
            "Test-set accuracy on faults at least a quarter of the way to a limit:",
            "",
        ]
        variants = training["evaluation"]["variants"]
        levels = list(variants["strong"]["by_noise"])
        lines.append("| variant | " + " | ".join(f"noise {level}" for level in levels) + " |")
        lines.append("|---|" + "---|" * len(levels))
        for variant, scores in variants.items():
            cells = [scores["by_noise"][level].get("accuracy_quarter") for level in levels]
            lines.append(f"| {variant} | " + " | ".join("-" if c is None else f"{c:.3f}" for c in cells) + " |")
        lines.append("")
    lines += [f"Wall time: {summary['wall_time_s']} s. Reproduce with `ea-gym reproduce --out DIR`.", ""]
    return "\n".join(lines)
