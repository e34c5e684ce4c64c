"""What the figures of a PHM run share: each component's colour and marker, points kept within an axis, End-of-Life
labels that never overprint, the events and the truth drawn on a time axis.

Units: times in s, parameters in their SI unit (``SystemModel.units``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.text import Annotation
from numpy.typing import ArrayLike

from ea_gym.phm import PHMChain
from ea_gym.scenario import Scenario

#: each component's colour and marker, in ``chain.degradable`` order (red is the safe limits', black the truth's, orange,
#: purple and brown the extrapolations')
COMPONENT_STYLES: tuple[tuple[str, str], ...] = (
    ("tab:blue", "o"), ("tab:green", "s"), ("tab:olive", "^"), ("tab:cyan", "D"), ("tab:pink", "v"), ("tab:gray", "P"),
    ("navy", "X"), ("darkgreen", "*"),
)
#: the backdrop of an End-of-Life label: the lines it crosses stay readable beneath it
LABEL_BOX = {"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.75}


def mark_events(ax: Any, results: dict, scenario: Scenario | None, label: bool = True) -> None:
    """Vertical lines at the fault onsets, every fault profile's breakpoints and the detection time."""
    breakpoints = sorted({t for fault in scenario.faults for t in fault.profile.times}) if scenario is not None else []
    for j, tb in enumerate(breakpoints):
        ax.axvline(tb, color="0.6", lw=0.8, ls=":", label="profile breakpoints" if label and j == 0 else None)
    if results.get("detection_time") is not None:
        ax.axvline(results["detection_time"], color="tab:red", lw=1.0, ls="--",
                   label=f"detection {results['detection_time']:g} s" if label else None)


def plot_within(ax: Any, x: ArrayLike, y: ArrayLike, bottom: float, top: float, color: str, label: str,
                marker: str = ".", size: float = 4.0) -> None:
    """Points (x, y) on an axis whose y range is [bottom, top] (set by the caller): those outside are
    drawn at the edge they passed as triangles pointing off the axis, so that none leaves it and the
    axis does not stretch to a runaway value. Nothing is drawn (and nothing enters the legend) for an
    empty set."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    inside = (y >= bottom) & (y <= top)
    if inside.any():
        ax.plot(x[inside], y[inside], marker, color=color, ms=size, ls="none", label=label)
    for edge, outside, pointer in ((top, y > top, "^"), (bottom, y < bottom, "v")):
        if outside.any():
            ax.plot(x[outside], np.full(int(outside.sum()), edge), pointer, color=color, ms=size + 2, ls="none",
                    clip_on=False, label=f"{label}: off the axis, {'above' if edge == top else 'below'} it")


def component_style(chain: PHMChain, name: str) -> tuple[str, str]:
    """The colour and marker of component ``name`` in every figure."""
    return COMPONENT_STYLES[chain.degradable.index(name) % len(COMPONENT_STYLES)]


def place_labels(ax: Any, labels: list[tuple[Annotation, int]]) -> None:
    """Move End-of-Life labels so that none overprints another: each label (with the direction, +1 up or -1 down, toward
    the inside of the axes from the limit it names), in order, is first moved sideways into the axes' width where it
    sticks out, then one label height plus 2 points that way while its box overlaps the box of a label placed before
    it. Call once the figure's layout is final (``tight_layout``)."""
    figure = ax.figure
    renderer = figure.canvas.get_renderer()
    to_points = 72.0 / figure.dpi
    frame = ax.get_window_extent(renderer)
    placed: list[Any] = []
    for label, direction in labels:
        box = label.get_window_extent(renderer)
        dx, dy = label.xyann
        label.xyann = (dx - max(box.x1 - frame.x1, 0.0) * to_points + max(frame.x0 - box.x0, 0.0) * to_points, dy)
        for _ in range(4 * len(labels) + 1):  # enough steps to clear every label placed before
            box = label.get_window_extent(renderer)
            if not any(box.overlaps(other) for other in placed):
                break
            dx, dy = label.xyann
            label.xyann = (dx, dy + direction * (box.height * to_points + 2.0))
        placed.append(label.get_window_extent(renderer))


def truth_curve(scenario: Scenario, parameter: str, end: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, end, 2001)
    index = scenario.model.parameter_names.index(parameter)
    return t, scenario.parameters_at(t)[:, index]


def joint_results(results: dict) -> bool:
    """Whether the run's components come from the chain's per-part health (its joint filter), not its estimator alone."""
    return any(series["degrading"] and series["degrading"][-1] is not None for series in results["components"].values())
