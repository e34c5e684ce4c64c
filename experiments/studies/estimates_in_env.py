"""The environment's RUL estimates past half-way to the limit, per fault type (issue 17's acceptance).

The batched spring-mass-damper environment (``gymnasium.make_vec("ea_gym/SpringMassDamper-v0",
vectorization_mode="vector_entry_point")``) at its default settings, no maintenance (always action 0,
``continue_after_failure`` at its default: an episode ends at the failure), its PHM chain's estimator
chosen with ``--estimator`` (``PHMConfig.estimator_kind``). For each fault type (k, m, b) the wear
config names that component alone, with the default ``WearConfig`` (linear wear, random direction,
0.5-1.5 % of the way to the limit per s, arrival 0-150 s), so every episode's fault is the one asked
for; each system runs its first episode to its end (failure or the horizon).

Counted: every step at which the faulty part is past half-way to its limit, that is the true
parameter's position between nominal and the limit it moves toward is in [0.5, 1). At those steps,
from the environment's public API (the observation's ``rul``: point, low, high, clipped to
[0, rul_max]; the info's ``true_rul``, s):

* relative error |rul_hat - rul_true| / rul_true, median per fault type (no prediction: rul_hat at
  rul_max, a large error);
* coverage: share of steps whose interval [low, high] holds rul_true, an interval reaching rul_max
  (unbounded, or no prediction) counted as a miss; beside it the share of steps with a prediction and
  with a bounded interval;
* Spearman's rank correlation of rul_hat with rul_true, per fault type and pooled over all three.

Targets (issue 17): median relative error <= 0.2 and coverage >= 0.9 for each fault type, pooled
Spearman >= 0.9. Writes results.json, table.md and rul.png (estimated against true RUL) into
experiments/results/estimates_in_env/<estimator>/.

    python experiments/studies/estimates_in_env.py                  # 30 episodes per fault type
    python experiments/studies/estimates_in_env.py --estimator tracking --episodes 30
    python experiments/studies/estimates_in_env.py --smoke          # 1 episode per fault type, fast wear
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from scipy.stats import spearmanr

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.degradation import WearConfig
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv
from ea_gym.files import json_ready, save_figure, write_json, write_text
from ea_gym.phm import ESTIMATORS, PHMConfig
from ea_gym.pyplot import plt
from experiments.common import parse_with_smoke

FAULTS = ("k", "m", "b")
RESULTS = Path(__file__).resolve().parents[1] / "results" / "estimates_in_env"
TARGETS = {"median_relative_error": 0.2, "coverage": 0.9, "spearman": 0.9}
# --smoke: one episode per fault type, the fault at once and at the fastest default rate (failure after 1 / 0.015 = 67 s)
SMOKE = {"episodes": 1}
SMOKE_WEAR = WearConfig(rate=(0.015, 0.015), arrival=(0.0, 0.0))


@dataclass
class PastHalfway:
    """The steps past half-way to the limit of one fault type: the truth and the observed RUL (s)."""

    rul_true: np.ndarray
    rul: np.ndarray
    low: np.ndarray
    high: np.ndarray
    episodes: int  # episodes that reached half-way

    def rounded(self) -> dict[str, Any]:
        """The steps as a dict, times to the millisecond (the results file keeps them for the figure)."""
        return {"rul_true": self.rul_true.round(3), "rul": self.rul.round(3), "low": self.low.round(3), "high": self.high.round(3),
                "episodes": self.episodes}

    @classmethod
    def concatenate(cls, parts: Sequence[PastHalfway]) -> PastHalfway:
        def joined(key: str) -> np.ndarray:
            return np.concatenate([getattr(p, key) for p in parts])

        return cls(joined("rul_true"), joined("rul"), joined("low"), joined("high"), episodes=sum(p.episodes for p in parts))


def position_toward_limit(value: np.ndarray, nominal: float, limits: tuple[float, ...]) -> np.ndarray:
    """Position of a parameter between nominal (0) and the safe limit (lower, upper) it has moved toward (1)."""
    limit = np.where(value >= nominal, limits[1], limits[0])
    return (value - nominal) / (limit - nominal)


def rul_metrics(steps: PastHalfway, rul_max: float) -> dict[str, Any]:
    """Median relative error, interval coverage (intervals reaching ``rul_max`` count as misses) and
    Spearman's rank correlation over ``steps``; None where there are no steps."""
    n = len(steps.rul_true)
    if n == 0:
        return {
            "steps": 0, "episodes": steps.episodes, "median_relative_error": None, "coverage": None, "spearman": None, "predicted": None,
            "bounded": None,
        }
    relative = np.abs(steps.rul - steps.rul_true) / steps.rul_true
    bounded = steps.high < rul_max
    covered = bounded & (steps.low <= steps.rul_true) & (steps.rul_true <= steps.high)
    rho = spearmanr(steps.rul, steps.rul_true).statistic if n > 2 else float("nan")
    return {
        "steps": n, "episodes": steps.episodes, "median_relative_error": float(np.median(relative)),
        "coverage": float(covered.mean()), "spearman": float(rho), "predicted": float(np.mean(steps.rul < rul_max)),
        "bounded": float(bounded.mean()),
    }


def run_fault(
    fault: str, estimator: str, episodes: int, seed: int, horizon: int | None, wear: WearConfig
) -> tuple[PastHalfway, dict[str, Any]]:
    """``episodes`` first episodes of the environment with ``fault`` the only wearing component, worn as ``wear`` says."""
    overrides: dict[str, Any] = {"horizon": horizon} if horizon is not None else {}
    env = gymnasium.make_vec(
        "ea_gym/SpringMassDamper-v0", num_envs=episodes, vectorization_mode="vector_entry_point",
        wear={fault: wear}, phm=PHMConfig(estimator_kind=estimator), **overrides,
    )
    vector = env.unwrapped
    if not isinstance(vector, BondGraphMaintenanceVectorEnv):
        raise TypeError(f"expected the native batched environment, got {type(vector).__name__}")
    core = vector.core
    rul_max, nominal, limits = core.config.rul_max, core.nominal_parameters[fault], core.safe_limits[fault]
    observation, _ = env.reset(seed=seed)
    if any(core.faulty_component(i) != fault for i in range(episodes)):
        raise RuntimeError(f"the wear config did not force the {fault} fault")
    running = np.ones(episodes, dtype=bool)
    reached = np.zeros(episodes, dtype=bool)
    rows: list[tuple[np.ndarray, ...]] = []
    steps = 0
    while running.any():
        observation, _, terminated, truncated, info = env.step(np.zeros(episodes, dtype=np.int64))
        steps += 1
        rul_true = np.asarray(info["true_rul"], dtype=float)
        position = position_toward_limit(np.asarray(info["true_parameters"][fault], dtype=float), nominal, limits)
        done = terminated | truncated
        # the step that ends an episode is left out (past the limit, or the horizon's; the results were measured so)
        counted = running & ~done & (position >= 0.5) & (position < 1.0) & (rul_true > 0)
        reached |= counted
        rul = np.asarray(observation["rul"], dtype=float)
        rows.append((rul_true[counted], rul[counted, 0], rul[counted, 1], rul[counted, 2]))
        running &= ~done
    env.close()
    rul_true, rul, low, high = (np.concatenate([r[k] for r in rows]) for k in range(4))
    part = PastHalfway(rul_true, rul, low, high, episodes=int(reached.sum()))
    return part, {"env_steps": steps * episodes, "rul_max": rul_max}


def measure(estimator: str, episodes: int, seed: int, horizon: int | None, wear: WearConfig) -> dict[str, Any]:
    """Every fault type's metrics, the pooled ones, and the steps themselves (for the figure)."""
    parts, by_fault, started = {}, {}, time.perf_counter()
    for k, fault in enumerate(FAULTS):
        part, stats = run_fault(fault, estimator, episodes, seed + 1000 * k, horizon, wear)
        parts[fault] = part
        by_fault[fault] = {**rul_metrics(part, stats["rul_max"]), **stats}
        print(f"{fault}: {by_fault[fault]}", flush=True)
    rul_max = by_fault[FAULTS[0]]["rul_max"]
    pooled = rul_metrics(PastHalfway.concatenate(list(parts.values())), rul_max)
    met = all(
        m["median_relative_error"] is not None and m["median_relative_error"] <= TARGETS["median_relative_error"]
        and m["coverage"] >= TARGETS["coverage"] for m in by_fault.values()
    ) and pooled["spearman"] is not None and pooled["spearman"] >= TARGETS["spearman"]
    return {
        "estimator": estimator, "episodes_per_fault": episodes, "seed": seed, "horizon": horizon, "rul_max": rul_max,
        "wear": vars(wear), "seconds": time.perf_counter() - started, "targets": TARGETS, "targets_met": bool(met),
        "faults": by_fault, "pooled": pooled,
        "steps": {fault: part.rounded() for fault, part in parts.items()},
    }


def table(result: dict[str, Any]) -> str:
    """The markdown table: one row per fault type and the pooled row."""
    def cell(value: float | None, spec: str) -> str:
        return "n/a" if value is None or not np.isfinite(value) else format(value, spec)

    lines = [
        f"Estimator `{result['estimator']}`, {result['episodes_per_fault']} episodes per fault type, steps past half-way to the limit "
        f"(targets: median relative error <= {TARGETS['median_relative_error']}, coverage >= {TARGETS['coverage']}, "
        f"pooled Spearman >= {TARGETS['spearman']}; met: {'yes' if result['targets_met'] else 'no'}).",
        "",
        "| fault | episodes past half-way | steps | RUL median relative error | interval covers truth | Spearman "
        "| steps with a prediction | steps with a bounded interval |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, m in [*result["faults"].items(), ("pooled", result["pooled"])]:
        lines.append(
            f"| {name} | {m['episodes']} | {m['steps']} | {cell(m['median_relative_error'], '.3f')} | {cell(m['coverage'], '.2f')} "
            f"| {cell(m['spearman'], '.2f')} | {cell(m['predicted'], '.2f')} | {cell(m['bounded'], '.2f')} |"
        )
    return "\n".join(lines) + "\n"


def figure(result: dict[str, Any]) -> Any:
    """Estimated against true RUL per fault type, the interval as a vertical bar, y = x and +-20 %."""
    fig, axes = plt.subplots(1, len(FAULTS), figsize=(4.2 * len(FAULTS), 4.0), sharey=True)
    for ax, fault in zip(axes, FAULTS):
        steps = result["steps"][fault]
        truth, rul = np.asarray(steps["rul_true"]), np.asarray(steps["rul"])
        top = max(float(truth.max()) if len(truth) else 1.0, 1.0) * 1.3
        bounded = np.asarray(steps["high"]) < result["rul_max"]
        ax.vlines(truth[bounded], np.asarray(steps["low"])[bounded], np.asarray(steps["high"])[bounded], color="0.8", lw=0.5,
                  label="95 % interval")
        ax.plot(truth, np.minimum(rul, top), ".", ms=2, label="estimate (clipped to the axes)")
        ax.plot([0, top], [0, top], "k-", lw=0.8, label="truth")
        ax.fill_between([0, top], [0, 0.8 * top], [0, 1.2 * top], color="k", alpha=0.07, label="+-20 %")
        error = result["faults"][fault]["median_relative_error"]
        title = f"{fault}: median relative error {'n/a' if error is None else f'{error:.3f}'}"
        ax.set(xlim=(0, top), ylim=(0, top), xlabel="true RUL (s)", title=title)
    axes[0].set_ylabel("estimated RUL (s)")
    axes[0].legend(loc="upper left", fontsize=7)
    fig.suptitle(f"RUL past half-way to the limit, estimator {result['estimator']}")
    fig.tight_layout()
    return fig


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--estimator", default=PHMConfig().estimator_kind, choices=sorted(ESTIMATORS), help="the chain's parameter estimator")
    parser.add_argument("--episodes", type=int, default=30, help="episodes per fault type (default 30)")
    parser.add_argument("--seed", type=int, default=0, help="reset seed of the first fault type's first episode")
    parser.add_argument("--horizon", type=int, default=None, help="steps per episode (default: the environment's)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default experiments/results/estimates_in_env/<estimator>)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    result = measure(args.estimator, args.episodes, args.seed, args.horizon, SMOKE_WEAR if args.smoke else WearConfig())
    out = args.out if args.out is not None else RESULTS / args.estimator
    write_json(out / "results.json", json_ready(result))
    write_text(out / "table.md", table(result))
    save_figure(figure(result), out / "rul.png")
    print(table(result))
    print(f"{result['seconds']:.0f} s; written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
