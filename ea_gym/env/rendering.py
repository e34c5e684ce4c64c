"""Rendering of the maintenance environment: a picture of the recent steps, or a text line."""

from __future__ import annotations

from typing import Any

import numpy as np


def render_ansi(env: Any, history: list[dict[str, Any]]) -> str:
    """One line per element of the latest step: EA, residual, diagnosis, estimate, RUL, truth."""
    if not history:
        return "no step yet\n"
    last = history[-1]
    obs, info = last["observation"], last["info"]
    core = env.core
    lines = [f"step {len(history)}  action: {env.action_meanings[last['action']]}  cost: {info['cost']['total']:.1f}"]
    lines.append("EA (J): " + "  ".join(f"{n}={v:.4g}" for n, v in zip(core.elements, obs["ea"])))
    lines.append("residual: " + "  ".join(f"{n}={v:+.3f}" for n, v in zip(core.elements, obs["residual"])))
    if "diagnosis" in obs:
        lines.append("diagnosis: " + "  ".join(f"{c}={p:.2f}" for c, p in zip(env.diagnosis_classes, obs["diagnosis"])))
        lines.append("RUL (s): {:.1f} [{:.1f}, {:.1f}]".format(*obs["rul"]))
    if "degrading" in obs:  # every part ages: each one's line
        for c, p, (point, low, high) in zip(core.components, obs["degrading"], obs["rul"]):
            lines.append(f"{c}: degrading {p:.2f}  RUL (s): {point:.1f} [{low:.1f}, {high:.1f}]")
    truth = "  ".join(f"{n}={v:.4g}" for n, v in info["true_parameters"].items())
    true_rul = np.atleast_1d(info["true_rul"])
    rul_text = "  ".join(f"{v:.1f}" for v in true_rul) if len(true_rul) > 1 else f"{true_rul[0]:.1f}"
    lines.append(f"true: {truth}  true RUL={rul_text} s  failed={info['failed']}")
    lines += [f"event: {e}" for e in info["events"]]
    return "\n".join(lines) + "\n"


def render_rgb(env: Any, history: list[dict[str, Any]]) -> np.ndarray:
    """Recent EA per element, parameter position in the safe range (true and estimated), RUL."""
    from ea_gym.pyplot import plt

    core = env.core
    steps = np.arange(len(history))
    fig, axes = plt.subplots(3, 1, figsize=(6.4, 6.4), sharex=True)
    if history:
        ea = np.array([h["observation"]["ea"] for h in history])
        for j, name in enumerate(core.elements):
            axes[0].semilogy(steps, np.maximum(ea[:, j], 1e-12), label=name)
        truth = np.array([[h["info"]["true_parameters"][c] for c in core.components] for h in history])
        low, high = core.limits[:, 0], core.limits[:, 1]
        for d, name in enumerate(core.components):
            line = axes[1].plot(steps, (truth[:, d] - low[d]) / (high[d] - low[d]), label=f"{name} true")[0]
            if "parameter_estimate" in history[-1]["observation"]:
                estimate = np.array([h["observation"]["parameter_estimate"][d] for h in history])
                axes[1].plot(steps, estimate, "--", color=line.get_color(), label=f"{name} estimate")
        # one RUL (v0) or one per part (v1): rows (steps, parts, 3) either way
        true_rul = np.minimum(np.array([np.atleast_1d(h["info"]["true_rul"]) for h in history]), env.config.rul_max)
        names = list(core.components) if true_rul.shape[1] > 1 else [""]
        rul = np.array([np.reshape(h["observation"]["rul"], (-1, 3)) for h in history]) if "rul" in history[-1]["observation"] else None
        for d, name in enumerate(names):
            suffix = f" of {name}" if name else ""
            color = axes[2].plot(steps, true_rul[:, d], ":", label=f"true RUL{suffix}")[0].get_color()
            if rul is not None:
                axes[2].plot(steps, rul[:, d, 0], color=color, label=f"estimated RUL{suffix}")
                axes[2].fill_between(steps, rul[:, d, 1], rul[:, d, 2], color=color, alpha=0.3)
    axes[0].set_ylabel("EA (J)")
    axes[1].set_ylabel("position in safe range")
    axes[1].axhline(0.0, color="r", lw=0.8)
    axes[1].axhline(1.0, color="r", lw=0.8)
    axes[2].set_ylabel("RUL (s)")
    axes[2].set_xlabel("recent steps")
    for ax in axes:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper left", ncol=3)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()  # type: ignore[attr-defined]  # the Agg canvas
    plt.close(fig)
    return image
