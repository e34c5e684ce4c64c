"""Figures a person would rather look at than read (matplotlib, Agg backend)."""

from __future__ import annotations

import os
from pathlib import Path

from ea_gym.energy import WindowedEnergy
from ea_gym.files import save_figure
from ea_gym.plant import Trajectory
from ea_gym.pyplot import plt


def plot_energy(trajectory: Trajectory, energy: WindowedEnergy, path: str | os.PathLike[str], title: str = "") -> Path:
    """Signals, parameters, EA and EAI per window over time, in one PNG.

    Panels: the load and the flow of every component; the component values relative to nominal
    (a fault shows as a departure from 1); EA per window (log scale); EAI per window (stacked).
    """
    model = trajectory.model
    t = trajectory.t
    palette = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    color = {name: palette[i % len(palette)] for i, name in enumerate(energy.ea)}
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    ax = axes[0]
    ax.plot(t, trajectory.effort[model.load_source], color="k", lw=0.8,
            label=f"load {model.load_source} ({model.units.get(model.load_source, '')})")
    ax.set_ylabel("load")
    twin = ax.twinx()
    for j, name in enumerate(model.state_names):
        variable = "p" if model.graph.elements[name].kind.value == "I" else "q"
        twin.plot(t, trajectory.states[:, j], lw=0.7, color=color[name], label=f"{variable} of {name}")
    twin.set_ylabel("energy variables (SI)")
    lines = ax.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", fontsize=8, ncol=2)
    ax.set_title(title or f"{model.description or model.name}: signals, Energy Activity and EAI")

    ax = axes[1]
    nominal = model.parameter_vector()
    for j, name in enumerate(model.parameter_names):
        ax.plot(t, trajectory.parameters[:, j] / nominal[j], lw=1.0, color=color[name], label=f"{name} ({model.units.get(name, '')})")
    ax.set_ylabel("value / nominal")
    ax.legend(loc="best", fontsize=8, ncol=3)

    ax = axes[2]
    centres = energy.t + 0.5 * energy.window + t[0]
    for name, ea in energy.ea.items():
        ax.semilogy(centres, ea, marker=".", ms=3, lw=0.8, color=color[name], label=name)
    ax.set_ylabel(f"EA per {energy.window:g} s window (J)")
    ax.legend(loc="best", fontsize=8, ncol=3)

    ax = axes[3]
    names = list(energy.eai)
    ax.stackplot(centres, [energy.eai[n] for n in names], labels=names, colors=[color[n] for n in names], alpha=0.85)
    ax.set_ylim(0, 1)
    ax.set_ylabel("EAI")
    ax.set_xlabel("time (s)")
    ax.legend(loc="upper right", fontsize=8, ncol=len(names))
    for a in axes:
        a.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
