"""Every part's RUL in the v1 environment, where every part ages at once, past half-way to its limit (issue 30's acceptance).

The batched ``ea_gym/SpringMassDamper-v1`` (``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``) at
its default settings: every part starts within its tolerance, ages in the background and has its own fault
(linear wear, random direction, 0.5-1.5 % of the way to the limit per s, arrival 0-150 s), so two or three
faults overlap in most episodes; the chain runs the joint filter. No maintenance (always action 0,
``continue_after_failure`` at its default: an episode ends at the first part's failure); each system runs its
first episode to its end.

Counted: every step (but the one that ends the episode) at which a part is past half-way from the value it
started the episode with to the limit it moves toward, its position there in [0.5, 1). At those steps, from the
environment's public API (the observation's ``rul`` (n, 3): each part's point, low, high, clipped to
[0, rul_max]; the info's ``true_rul`` (n,), s: each part's mean trend to its limit), per component and pooled
(``estimates_in_env.rul_metrics``, the single-fault study's own measures):

* relative error |rul_hat - rul_true| / rul_true, its median (no prediction: rul_hat at rul_max, a large error);
* coverage: the share of steps whose interval [low, high] holds rul_true, an interval reaching rul_max
  (unbounded, or no prediction) a miss;
* Spearman's rank correlation of rul_hat with rul_true, per component and pooled over all three.

Targets (issue 30): median relative error <= 0.2 and coverage >= 0.9 per component, pooled Spearman >= 0.9.
Writes results.json, table.md and rul.png into experiments/results/v1_rul/.

    python experiments/studies/v1_rul.py                # 30 episodes
    python experiments/studies/v1_rul.py --smoke        # 2 episodes, every fault at once at the fastest rate
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # this checkout's ea_gym and experiments.common, installed or not

from ea_gym.degradation import WearConfig
from ea_gym.env import V1_ENV_IDS
from ea_gym.env.vector import BondGraphMaintenanceVectorEnv
from ea_gym.files import json_ready, save_figure, write_json, write_text
from experiments.common import machine_info, parse_with_smoke
from experiments.studies.estimates_in_env import TARGETS, PastHalfway, figure, rul_metrics

RESULTS = Path(__file__).resolve().parents[1] / "results" / "v1_rul"
# --smoke: two episodes, every part's fault at once at the fastest default rate (the first failure within 67 s)
SMOKE = {"episodes": 2}
SMOKE_WEAR = WearConfig(rate=(0.015, 0.015), arrival=(0.0, 0.0))


def past_halfway(value: np.ndarray, start: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """Each part's position from its ``start`` (0) to the safe limit it has moved toward (1), (N, n); ``value`` and
    ``start`` (N, n), ``limits`` (n, 2)."""
    toward_low, toward_high = (value - start) / (limits[:, 0] - start), (value - start) / (limits[:, 1] - start)
    return np.maximum(toward_low, toward_high)


def run(episodes: int, seed: int, horizon: int | None, wear: WearConfig | None) -> tuple[dict[str, PastHalfway], dict[str, Any]]:
    """``episodes`` first episodes of v1, every system's parts counted past half-way; the steps per component."""
    overrides: dict[str, Any] = {"horizon": horizon} if horizon is not None else {}
    if wear is not None:
        overrides["wear"] = {name: wear for name in ("k", "m", "b")}
    env = gymnasium.make_vec(V1_ENV_IDS[0], num_envs=episodes, vectorization_mode="vector_entry_point", **overrides)
    vector = env.unwrapped
    if not isinstance(vector, BondGraphMaintenanceVectorEnv):
        raise TypeError(f"expected the native batched environment, got {type(vector).__name__}")
    core = vector.core
    components = core.components
    limits = np.array([core.safe_limits[c] for c in components])
    observation, info = env.reset(seed=seed)
    start = np.column_stack([info["true_parameters"][c] for c in components])
    running = np.ones(episodes, dtype=bool)
    reached = np.zeros((episodes, len(components)), dtype=bool)
    rows: list[tuple[np.ndarray, ...]] = []
    steps = 0
    while running.any():
        observation, _, terminated, truncated, info = env.step(np.zeros(episodes, dtype=np.int64))
        steps += 1
        rul_true = np.asarray(info["true_rul"], dtype=float)  # (N, n)
        position = past_halfway(np.column_stack([info["true_parameters"][c] for c in components]), start, limits)
        done = terminated | truncated
        counted = (running & ~done)[:, None] & (position >= 0.5) & (position < 1.0) & (rul_true > 0)
        reached |= counted
        rul = np.asarray(observation["rul"], dtype=float)  # (N, n, 3)
        rows.append((counted, rul_true, rul))
        running &= ~done
    env.close()
    parts = {}
    for d, name in enumerate(components):
        masks = [r[0][:, d] for r in rows]
        truth = np.concatenate([r[1][m, d] for r, m in zip(rows, masks)])
        point, low, high = (np.concatenate([r[2][m, d, k] for r, m in zip(rows, masks)]) for k in range(3))
        parts[name] = PastHalfway(truth, point, low, high, episodes=int(reached[:, d].sum()))
    return parts, {"env_steps": steps * episodes, "rul_max": core.config.rul_max, "components": components}


def measure(episodes: int, seed: int, horizon: int | None, wear: WearConfig | None) -> dict[str, Any]:
    """Every component's metrics, the pooled ones, and the steps themselves (for the figure)."""
    started = time.perf_counter()
    parts, stats = run(episodes, seed, horizon, wear)
    rul_max = stats["rul_max"]
    by_part = {name: rul_metrics(part, rul_max) for name, part in parts.items()}
    pooled = rul_metrics(PastHalfway.concatenate(list(parts.values())), rul_max)
    met = all(
        m["median_relative_error"] is not None and m["median_relative_error"] <= TARGETS["median_relative_error"]
        and m["coverage"] >= TARGETS["coverage"] for m in by_part.values()
    ) and pooled["spearman"] is not None and pooled["spearman"] >= TARGETS["spearman"]
    return {
        "env": V1_ENV_IDS[0], "estimator": "joint (v1)", "episodes": episodes, "seed": seed, "horizon": horizon, "rul_max": rul_max,
        "wear": "the environment's default" if wear is None else vars(wear), "env_steps": stats["env_steps"],
        "seconds": time.perf_counter() - started, "machine": machine_info(), "targets": TARGETS, "targets_met": bool(met),
        "faults": by_part, "pooled": pooled, "steps": {name: part.rounded() for name, part in parts.items()},
    }


def table(result: dict[str, Any]) -> str:
    """The markdown table: one row per component and the pooled row."""
    def cell(value: float | None, spec: str) -> str:
        return "n/a" if value is None or not np.isfinite(value) else format(value, spec)

    lines = [
        f"`{result['env']}`, {result['episodes']} episodes without maintenance, every part ageing; steps at which a part is past "
        f"half-way from its starting value to its limit (targets: median relative error <= {TARGETS['median_relative_error']} and "
        f"coverage >= {TARGETS['coverage']} per component, pooled Spearman >= {TARGETS['spearman']}; met: "
        f"{'yes' if result['targets_met'] else 'no'}).",
        "",
        "| component | episodes past half-way | steps | RUL median relative error | interval covers truth | Spearman "
        "| steps with a prediction | steps with a bounded interval |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, m in [*result["faults"].items(), ("pooled", result["pooled"])]:
        lines.append(
            f"| {name} | {m['episodes']} | {m['steps']} | {cell(m['median_relative_error'], '.3f')} | {cell(m['coverage'], '.2f')} "
            f"| {cell(m['spearman'], '.2f')} | {cell(m['predicted'], '.2f')} | {cell(m['bounded'], '.2f')} |"
        )
    return "\n".join(lines) + "\n"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=30, help="episodes (default 30)")
    parser.add_argument("--seed", type=int, default=0, help="reset seed of the first episode (episode i: seed + i)")
    parser.add_argument("--horizon", type=int, default=None, help="steps per episode (default: the environment's)")
    parser.add_argument("--out", type=Path, default=RESULTS, help="output folder (default experiments/results/v1_rul)")
    args = parse_with_smoke(parser, argv, SMOKE)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    result = measure(args.episodes, args.seed, args.horizon, SMOKE_WEAR if args.smoke else None)
    write_json(args.out / "results.json", json_ready(result))
    write_text(args.out / "table.md", table(result))
    save_figure(figure(result), args.out / "rul.png")
    print(table(result))
    print(f"{result['seconds']:.0f} s; written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
