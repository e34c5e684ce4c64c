"""The monitor's outputs over the recent steps, which detection and isolation read; per-system arrays.

Every stage of the chain keeps its state as arrays whose first axis is the system. ``reset`` rewrites
the rows of the systems that start over in place, with no fresh array of their size (under random
actions a good share of the systems is reset at every step). Histories along the last axis are kept
by :func:`push_window`, which slides a window over a backing array instead of copying the history
at every step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ea_gym._kernels.history import record_step
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
    k, T = new.shape[-1], buffer.shape[-1]
    backing = buffer.base
    if backing is None or not _is_window(buffer, backing):
        backing = np.empty(buffer.shape[:-1] + (2 * T,), dtype=buffer.dtype)
        backing[..., :T] = buffer
        buffer = backing[..., :T]
    start = (buffer.ctypes.data - backing.ctypes.data) // buffer.itemsize + k  # the window's start, moved on
    if start + T > backing.shape[-1]:
        # the entries kept lie past T - k, clear of where they go: no overlap
        backing[..., : T - k] = buffer[..., k:]
        start = 0
    moved = backing[..., start : start + T]
    moved[..., T - k :] = new
    return moved


def _is_window(buffer: np.ndarray, backing: np.ndarray) -> bool:
    """Whether ``buffer`` is a window on the last axis of a backing array ``push_window`` made: C-contiguous, twice its length."""
    return (
        backing.flags.c_contiguous
        and backing.dtype == buffer.dtype
        and backing.shape[:-1] == buffer.shape[:-1]
        and backing.strides == buffer.strides
        and backing.shape[-1] == 2 * buffer.shape[-1]
    )


#: The histories ``MonitorHistory.record`` pushes, in the order ``record_step`` takes them.
SLIDING = ("ea", "ea_reference", "gram", "cross", "balance", "balance_square", "dissipated", "noise")


@dataclass
class MonitorHistory:
    """The chain's clock and the monitor's outputs over the last steps, N systems.

    Each history is a window on the last axis of a backing array twice its length, slid on at each step as
    ``push_window`` slides one: its fields are written in place (as ``reset`` writes them), not replaced.

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
    #: per history in ``SLIDING``: its window at each start on its backing array (0 to its length)
    _windows: list[list[np.ndarray]] = field(default_factory=list, init=False, repr=False, compare=False)
    #: the backing arrays as (N, entries per step, 2 length), the windows' starts and lengths: ``record_step``'s
    _histories: tuple[np.ndarray, ...] = field(default=(), init=False, repr=False, compare=False)
    _starts: np.ndarray = field(default_factory=lambda: np.zeros(len(SLIDING), dtype=np.int64), init=False, repr=False, compare=False)
    _lengths: np.ndarray = field(default_factory=lambda: np.zeros(len(SLIDING), dtype=np.int64), init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        histories = []
        for i, name in enumerate(SLIDING):
            values = getattr(self, name)
            length = values.shape[-1]
            backing = np.empty(values.shape[:-1] + (2 * length,))
            backing[..., :length] = values
            self._windows.append([backing[..., start : start + length] for start in range(length + 1)])
            histories.append(backing.reshape(len(backing), -1, 2 * length))
            self._lengths[i] = length
            setattr(self, name, self._windows[i][0])
        self._histories = tuple(histories)

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
        """Append one step's monitor outputs; ``dissipators``: the element indices of the dissipators.

        The isolation frame and the balance evidence need only the step's sums of the balance regression:
        one entry per step (compiled, numpy's sums to the bit: ``record_step``).
        """
        record_step(
            window.ea, window.ea_reference, window.gram, window.cross, window.balance, window.noise, dissipators, step_time,
            self.time, self.steps, self._histories, self._starts, self._lengths,
        )
        for name, windows, start in zip(SLIDING, self._windows, self._starts.tolist()):
            setattr(self, name, windows[start])
