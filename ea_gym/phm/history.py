"""The monitor's outputs over the recent steps, which detection and isolation read; per-system arrays.

Every stage of the chain keeps its state as arrays whose first axis is the system. ``reset`` rewrites
the rows of the systems that start over in place, with no fresh array of their size (under random
actions a good share of the systems is reset at every step). Histories along the last axis are kept
by :func:`push_window`, which slides a window over a backing array instead of copying the history
at every step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np

from ea_gym._kernels.history import step_sums
from ea_gym.diagnosis.monitor import MonitorWindow


def rows_of(systems: np.ndarray | None) -> slice | np.ndarray:
    """The rows a reset rewrites: all (``systems`` None) or those where the boolean mask (N,) is true."""
    return slice(None) if systems is None else np.flatnonzero(systems)


def push_window(buffer: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Append ``new`` (..., k) along the last axis and drop as many of the oldest entries; returns the buffer.

    The buffer is a window on the last axis of a backing array twice its length (its ``base``, made
    at the first push): each push slides the window on, and only when it reaches the backing
    array's end are its entries moved back to the start. The history is then copied once per
    buffer length's worth of pushes instead of at every push, and no array is allocated.
    """
    T = buffer.shape[-1]
    backing = buffer.base
    if backing is None or not _is_window(buffer, backing):
        backing = np.empty(buffer.shape[:-1] + (2 * T,), dtype=buffer.dtype)
        backing[..., :T] = buffer
        buffer = backing[..., :T]
    return slide_window(backing, window_start(buffer, backing), buffer, new)[0]


def window_start(window: np.ndarray, backing: np.ndarray) -> int:
    """Where a window ``push_window`` keeps starts on its ``backing`` array's last axis."""
    return (window.ctypes.data - backing.ctypes.data) // window.itemsize


def slide_window(backing: np.ndarray, start: int, window: np.ndarray, new: np.ndarray) -> tuple[np.ndarray, int]:
    """``push_window`` on the window at ``start`` on ``backing``'s last axis: the new window and its start."""
    k, T = new.shape[-1], window.shape[-1]
    start += k
    if start + T > backing.shape[-1]:
        # the entries kept lie past T - k, clear of where they go: no overlap
        backing[..., : T - k] = window[..., k:]
        start = 0
    moved = backing[..., start : start + T]
    moved[..., T - k :] = new
    return moved, start


def _is_window(buffer: np.ndarray, backing: np.ndarray) -> bool:
    """Whether ``buffer`` is a window on the last axis of a backing array ``push_window`` made: C-contiguous, twice its length."""
    return (
        backing.flags.c_contiguous
        and backing.dtype == buffer.dtype
        and backing.shape[:-1] == buffer.shape[:-1]
        and backing.strides == buffer.strides
        and backing.shape[-1] == 2 * buffer.shape[-1]
    )


@dataclass
class MonitorHistory:
    """The chain's clock and the monitor's outputs over the last steps, N systems.

    Attributes:
        time: time since the last reset at the end of the step (s), (N,).
        steps: updates since the last reset, (N,).
        ea, ea_reference: EA of every element per sub-window over the isolation frame (J), (N, E, S).
        gram, cross: per step, the energy-balance regression's sums (J^2), (N, C, C, R) and (N, C, R).
        balance: per step, the energy-balance residual, real minus reference (J), (N, B).
        balance_square: per step, the sum of its windows' squares (J^2), (N, V).
        dissipated: per step, the dissipators' reference EA (J), (N, B).
        noise: per step, the monitor's noise estimate's sums, (N, 2, nx, F).
    """

    time: np.ndarray
    steps: np.ndarray
    ea: np.ndarray
    ea_reference: np.ndarray
    gram: np.ndarray
    cross: np.ndarray
    balance: np.ndarray
    balance_square: np.ndarray
    dissipated: np.ndarray
    noise: np.ndarray
    _starts: dict[str, tuple[np.ndarray, np.ndarray, int]] = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def new(cls, n: int, elements: int, components: int, states: int, subs: int, frame_steps: int, regression_steps: int,
            balance_steps: int, evidence_steps: int) -> MonitorHistory:
        """A history of N systems; its lengths as in the attributes (S = ``subs``, F = ``frame_steps``, ...)."""
        history = cls(
            time=np.empty(n), steps=np.empty(n, dtype=int),
            ea=np.empty((n, elements, subs)), ea_reference=np.empty((n, elements, subs)),
            gram=np.empty((n, components, components, regression_steps)), cross=np.empty((n, components, regression_steps)),
            balance=np.empty((n, balance_steps)), balance_square=np.empty((n, evidence_steps)),
            dissipated=np.empty((n, balance_steps)), noise=np.empty((n, 2, states, frame_steps)),
        )
        history.reset()
        return history

    def reset(self, systems: np.ndarray | None = None) -> None:
        """Start over for all systems, or for those where the boolean mask (N,) is true."""
        rows = rows_of(systems)
        self.time[rows] = 0.0
        self.steps[rows] = 0
        for history in (self.ea, self.ea_reference, self.gram, self.cross, self.balance, self.balance_square, self.dissipated, self.noise):
            history[rows] = 0.0

    def record(self, window: MonitorWindow, step_time: float, dissipators: np.ndarray) -> None:
        """Append one step's monitor outputs; ``dissipators``: the element indices of the dissipators."""
        self.time = self.time + step_time
        self.steps = self.steps + 1
        n, components = window.cross.shape[0], window.cross.shape[2]
        # the isolation frame and the balance evidence need only their sums: one entry per step
        gram, cross = np.empty((n, components, components, 1)), np.empty((n, components, 1))
        balance, balance_square, dissipated = np.empty((n, 1)), np.empty((n, 1)), np.empty((n, 1))
        step_sums(window.gram, window.cross, window.balance, window.ea_reference, dissipators, gram, cross, balance, balance_square, dissipated)
        for name, new in (
            ("ea", window.ea), ("ea_reference", window.ea_reference), ("gram", gram), ("cross", cross), ("balance", balance),
            ("balance_square", balance_square), ("dissipated", dissipated), ("noise", window.noise[..., None]),
        ):
            self._push(name, new)

    def _push(self, name: str, new: np.ndarray) -> None:
        """``push_window`` on the history ``name``, its window's start kept from the last push (while it is that window)."""
        current = getattr(self, name)
        known = self._starts.get(name)
        if known is not None and known[0] is current:
            backing = known[1]
            moved, start = slide_window(backing, known[2], current, new)
        else:
            moved = push_window(current, new)
            backing = cast(np.ndarray, moved.base)  # push_window's result is a window on its backing array
            start = window_start(moved, backing)
        self._starts[name] = (moved, backing, start)
        setattr(self, name, moved)
