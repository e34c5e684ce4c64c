"""The monitor's sliding histories (``ea_gym._kernels.history``): each window kept in the first or the
second half of a backing array twice its length, moved back to the start when it would pass the end."""

from __future__ import annotations

import numpy as np


def slide(history: np.ndarray, start: int, length: int, k: int) -> int:
    """Where the window of ``length`` entries of ``history`` (N, A, 2 length) starts once ``k`` new entries
    follow it: k further on, or back at 0 with its last length - k entries moved there."""
    start += k
    if start + length > history.shape[2]:
        history[..., : length - k] = history[..., start : start + length - k].copy()
        start = 0
    return start


def record_step(
    ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, balance: np.ndarray, noise: np.ndarray,
    dissipators: np.ndarray, step_time: float, time: np.ndarray, steps: np.ndarray,
    histories: tuple[np.ndarray, ...], starts: np.ndarray, lengths: np.ndarray,
) -> None:
    """One step of N systems onto their histories, in place: the EA pushed as it is; the gram and cross
    summed over the balance windows in order; the balance's sum and sum of squares (numpy's); the
    dissipators' reference EA, numpy's sum of each added element after element; the noise sums."""
    subs = ea.shape[2]
    for i, history in enumerate(histories):
        starts[i] = slide(history, int(starts[i]), int(lengths[i]), subs if i < 2 else 1)
    ends = starts + lengths
    n = len(ea)
    time += step_time
    steps += 1
    gram_total, cross_total = np.zeros(gram[:, 0].shape), np.zeros(cross[:, 0].shape)
    for w in range(gram.shape[1]):
        gram_total += gram[:, w]
        cross_total += cross[:, w]
    dissipated = np.zeros(n)
    for d in dissipators:
        dissipated += ea_reference[:, d].sum(-1)
    pushed = (
        (ea, subs), (ea_reference, subs), (gram_total.reshape(n, -1, 1), 1), (cross_total[..., None], 1),
        (balance.sum(-1)[:, None, None], 1), ((balance * balance).sum(-1)[:, None, None], 1), (dissipated[:, None, None], 1),
        (noise.reshape(n, -1, 1), 1),
    )
    for history, end, (entries, count) in zip(histories, ends, pushed, strict=True):
        history[..., end - count : end] = entries
