"""The benchmark's report (benchmark.md): ranking, cost breakdown, value of information, tuning, command."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from agents.evaluation import COST_BREAKDOWN

__all__ = ["fmt_ci", "fmt_diff", "markdown"]


def fmt_ci(row: Mapping[str, Any]) -> str:
    """``mean [low, high]`` of a row with ``mean_cost`` and ``ci95`` (just the mean when the interval is None/NaN)."""
    low, high = row["ci95"]
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return f"{row['mean_cost']:.1f}"
    return f"{row['mean_cost']:.1f} [{low:.1f}, {high:.1f}]"


def fmt_diff(d: Mapping[str, Any]) -> str:
    """``+mean [+low, +high]`` of a paired difference (just the mean when the interval is None/NaN)."""
    low, high = d["ci95"]
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)):
        return f"{d['mean']:+.1f}"
    return f"{d['mean']:+.1f} [{low:+.1f}, {high:+.1f}]"


def _value(value: Any) -> str:
    """A tuned value for the tables: a number, or one per component (CorrectiveBand's bands)."""
    if isinstance(value, Mapping):
        return ", ".join(f"{k} {v:g}" for k, v in value.items())
    return f"{value:g}"


def _ratio(row: Mapping[str, Any]) -> str:
    r = row.get("cost_ratio_to_oracle")
    return "n/a" if r is None else f"{r:.2f}"


def _param(row: Mapping[str, Any]) -> str:
    if row.get("parameter") is None:
        return "-"
    unit = " s" if str(row.get("parameter_name", "")).endswith("_s") else ""
    action = f"{row['action']}, " if row.get("action") else ""
    return f"{action}{row['parameter_name'].removesuffix('_s')} = {_value(row['parameter'])}{unit}"


def markdown(result: Mapping[str, Any]) -> str:
    """The benchmark's report: ranking table, skipped policies, value of information, tuning, command."""
    lines = _ranking(result) + _cost_breakdown(result) + _value_of_information(result) + _tuning(result) + _figures_and_command(result)
    return "\n".join(lines)


def _ranking(result: Mapping[str, Any]) -> list[str]:
    rows = result["policies"]
    seeds = result["seeds"]
    env = result["environment"]
    ranking = result["ranking"]
    lines = [
        "# Maintenance policy benchmark",
        "",
        f"`{env['id']}` with continue_after_failure=True"
        + (f", env_kwargs {env['env_kwargs']}" if env["env_kwargs"] else "")
        + f": horizon {env['horizon']} steps of {env['step_seconds']:g} s. "
        f"{seeds['episodes']} evaluation episodes per policy on the same seeds "
        f"{seeds['evaluation'][0]}..{seeds['evaluation'][1]} (paired: every policy meets the same machines, loads and "
        f"faults); rules tuned on seeds {seeds['tuning'][0]}..{seeds['tuning'][1]}; PPO trained on seeds from "
        f"{seeds['training_from']} and validated on seeds from {seeds['validation_from']}: no evaluation episode was "
        "seen in tuning, training or validation.",
        "",
        "Cost: mean per episode [95 % CI, normal approximation mean ± 1.96 sd/√n]. ×oracle: mean cost / the "
        "oracle's. Δ oracle: paired per-seed cost difference to the oracle [95 % CI]. Failures, maintenance "
        "actions: mean per episode; availability: mean fraction of steps the machine was up.",
        "",
        "| rank | policy | obs_mode | tuned parameter | cost [95 % CI] | ×oracle | Δ oracle [95 % CI] | failures | availability | "
        "maintenance actions |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rank, name in enumerate(ranking, 1):
        row = rows[name]
        lines.append(
            f"| {rank} | **{name}** ({row['label']}) | {row['obs_mode']} | {_param(row)} | {fmt_ci(row)} | {_ratio(row)} | "
            f"{fmt_diff(row['vs_oracle'])} | {row['failures']:.2f} | {row['availability']:.3f} | {row['maintenance_actions']:.1f} |"
        )
    lines += ["", f"Policies evaluated ({seeds['episodes']} episodes each): "
              + "; ".join(f"**{name}**: {rows[name]['label']}, obs_mode {rows[name]['obs_mode']}" for name in rows) + ".",
              "", f"Ranking (lowest mean cost first): {' < '.join(ranking)}.", ""]
    if result["skipped"]:
        lines += ["Skipped:", ""]
        lines += [f"- **{name}**: {note}" for name, note in result["skipped"].items()]
        lines.append("")
    return lines


def _cost_breakdown(result: Mapping[str, Any]) -> list[str]:
    lines = ["## Cost breakdown (mean per episode)", "", "| policy | " + " | ".join(i.replace("_", " ") for i in COST_BREAKDOWN) + " |",
             "|---|" + "---|" * len(COST_BREAKDOWN)]
    for name in result["ranking"]:
        b = result["policies"][name]["cost_breakdown"]
        lines.append(f"| {name} | " + " | ".join(f"{b[i]:.1f}" for i in COST_BREAKDOWN) + " |")
    return lines


def _value_of_information(result: Mapping[str, Any]) -> list[str]:
    rows = result["policies"]
    voi = result["value_of_information"]
    lines = [
        "", "## Value of information", "",
        "The same decision rule (or the same learner) given more information: sensors only → the PHM chain's "
        "diagnosis and RUL → the true state. Per information regime, the best policy of each kind:",
        "",
        "| information (obs_mode) | rule | rule cost [95 % CI] | learned (PPO) | PPO cost [95 % CI] |",
        "|---|---|---|---|---|",
    ]
    for mode, entry in voi["by_obs_mode"].items():
        rule = entry["rule"]
        learned = entry["ppo"]
        rule_text = f"{rule} | {fmt_ci(rows[rule])}" if rule else "- | -"
        ppo_text = " / ".join(learned) + " | " + " / ".join(fmt_ci(rows[n]) for n in learned) if learned else "- | -"
        lines.append(f"| {mode} | {rule_text} | {ppo_text} |")
    lines.append("")
    if voi["gains"]:
        lines += ["Cost saved by the extra information (paired per-seed difference, less information minus more, [95 % CI]):", ""]
        for gain in voi["gains"]:
            lines.append(f"- {gain['kind']}, {gain['from']} → {gain['to']}: {fmt_diff(gain['difference'])} per episode "
                         f"({gain['less']} minus {gain['more']})")
        lines.append("")
    if not any(entry["ppo"] for entry in voi["by_obs_mode"].values()):
        lines += ["No trained PPO agent was evaluated, so the learned column is empty.", ""]
    return lines


def _tuned_source(result: Mapping[str, Any]) -> str:
    """Where the rules' tuned settings came from: tuned in this run, or read from a file (and whether it was stale)."""
    source, seeds = result["tuned_settings"], result["seeds"]["tuning"]
    on = f"on seeds {seeds[0]}..{seeds[1]} by `{source['command']}`"
    if source["tuned"] == "in this run":
        written = f", written to `{source['file']}`" if source["file"] else ""
        return f"The rules were tuned in this run {on}{written}."
    match = ("the same as this environment's" if not source["stale"] else
             f"**STALE: this environment's is {source['current_fingerprint'][:12]}** (used anyway, --allow-stale)")
    return (f"The rules' tuned settings were read from `{source['file']}`, tuned {on} on environment fingerprint "
            f"{source['fingerprint'][:12]}, {match}.")


def _tuning(result: Mapping[str, Any]) -> list[str]:
    lines = ["## Tuning (tuning seeds)", "", _tuned_source(result), ""]
    for name, tuning in result["tuning"].items():
        action = f" ({tuning['action']})" if tuning.get("action") else ""
        lines.append(f"{name} (obs_mode {tuning['obs_mode']}), {tuning['parameter_name']}: best {_value(tuning['best'])}{action}")
        lines += ["", "| value | cost [95 % CI] | failures | availability | maintenance actions |", "|---|---|---|---|---|"]
        for r in tuning["table"]:
            value = f"{r['action']}, {_value(r['parameter'])}" if r.get("action") else _value(r["parameter"])
            lines.append(f"| {value} | {fmt_ci(r)} | {r['failures']:.2f} | {r['availability']:.3f} | {r['maintenance_actions']:.1f} |")
        lines.append("")
    return lines


def _figures_and_command(result: Mapping[str, Any]) -> list[str]:
    seeds = result["seeds"]
    lines = [
        "## Figures",
        "",
        "![episode cost per policy](cost_distribution.png)",
        "",
        f"![one episode per policy, seed {seeds['timeline']}](timelines.png)",
        "",
        f"The timelines show evaluation seed {seeds['timeline']} for every policy (numbers in timelines.json); the PHM "
        "estimates beside the sensors- and oracle-mode policies come from the PHM chain run on the same episode.",
        "",
        "## Reproduce",
        "",
        "```bash",
        result["commands"]["reproduce"],
        "```",
        "",
    ]
    if result["commands"].get("note"):
        lines += [result["commands"]["note"], ""]
    t = result["timings_s"]
    lines += [f"Took {t['total']:.0f} s ({t['total'] / 60:.1f} min) on {result['machine']['platform']}, Python {result['machine']['python']}.", ""]
    return lines
