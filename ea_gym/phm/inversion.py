"""The EA inversion of one window: the parameter value that best explains the measured Energy Activity (paper 3.3).

For a window [t0, t1], candidate values phi of a parameter are simulated from the measured state at
t0 - c under the measured load (c is the smoothing context), their signals go through the same
denoising and nominal laws as the measurements, and the candidate whose components' EA and energy
balance over [t0, t1] match the measured ones best (in relative least squares) is refined on finer
grids, then to the vertex of the parabola through it and its neighbours (past the grid's end by up
to ``InversionConfig.reach`` steps). This uses eq 10's ingredients without linearising them: dS/dphi
is the model's own response to phi, dEA/dS the component's constitutive law. It is preferred to
integrating the rate of eq 15 (eq 16) because each window's estimate is absolute: errors do not
accumulate, and it works for storage elements (C, I) as well as for dissipators (R), which the paper
names as its limitation.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.activity import trapezoid_activity
from ea_gym.bondgraph.simulation import simulate_measured
from ea_gym.diagnosis.monitor import Monitor
from ea_gym.models import SystemModel
from ea_gym.numerics import TINY
from ea_gym.phm.config import InversionConfig
from ea_gym.sensors import Sensors


@numba.njit(cache=True)
def _signatures(power: np.ndarray, components: np.ndarray, sources: np.ndarray, h: float) -> tuple[bool, np.ndarray]:
    """``EAInversion.signature`` of every row of power (M, E, T) in W, sampled every h seconds:
    whether the components' powers are all finite, and (M, C + 1) in J."""
    M, _, T = power.shape
    C = len(components)
    finite = True
    out = np.empty((M, C + 1))
    delivered = np.empty(T)
    absorbed = np.empty(T)
    for m in range(M):
        for c in range(C):
            p = power[m, components[c]]
            for t in range(T):
                finite &= np.isfinite(p[t])
            out[m, c] = trapezoid_activity(p, 0, T - 1, h)
        # trapezoids of the net power, the sources' minus the components'; time innermost to vectorize
        delivered[:] = 0.0
        absorbed[:] = 0.0
        for k in sources:
            for t in range(T):
                delivered[t] += power[m, k, t]
        for k in components:
            for t in range(T):
                absorbed[t] += power[m, k, t]
        total = 0.0
        for t in range(1, T):
            total += (delivered[t - 1] - absorbed[t - 1]) + (delivered[t] - absorbed[t])
        out[m, C] = 0.5 * total * h
    return finite, out


class EAInversion:
    """Estimates one parameter per system from the EA of the components over one window.

    Args:
        monitor: the monitor whose denoising and nominal laws produced the measured EA.
        config: inversion settings.
    """

    def __init__(self, monitor: Monitor, config: InversionConfig = InversionConfig()):
        self.monitor = monitor
        self.model: SystemModel = monitor.model
        self.config = config
        self.sensors = Sensors(self.model)
        self.context = monitor.config.smoothing
        self._components = np.array([monitor.elements.index(c) for c in monitor.components])
        self._sources = np.array([monitor.elements.index(u) for u in self.model.state_space.input_names])
        # per parameter (NaN for one without safe limits): the first grid and the safe span
        limits = [self.model.safe_limits.get(name) for name in self.model.parameter_names]
        self._grids = np.array([
            np.full(config.grid, np.nan) if pair is None else self.candidate_grid(name)
            for name, pair in zip(self.model.parameter_names, limits)
        ])
        self._spans = np.array([np.nan if pair is None else pair[1] - pair[0] for pair in limits])

    def signature(self, power: np.ndarray) -> np.ndarray:
        """What the inversion matches over a window, from every element's power (..., E, L + 1): (..., C + 1).

        The EA of each component (J) and, last, the window's energy-balance residual (J): the energy
        the sources deliver minus what the components absorb, both under the nominal laws. A
        dissipator's nominal law hides its own fault from its EA, but not from this balance (a damper
        whose coefficient grew by 10 % leaves 10 % of its dissipation unaccounted for), which is what
        makes a light damper identifiable.
        """
        rows = np.ascontiguousarray(power, dtype=float).reshape((-1,) + power.shape[-2:])
        finite, signature = _signatures(rows, self._components, self._sources, self.monitor.h)
        if not finite:
            raise ValueError("power contains NaN or inf; Energy Activity needs finite signals")
        return signature.reshape(power.shape[:-2] + signature.shape[-1:])

    def mismatch_scale(self, signature: np.ndarray) -> np.ndarray:
        """Per-entry scale of the mismatch: each component's EA, and for the balance see ``balance_share``."""
        ea = signature[..., :-1]
        balance = ea[..., self.monitor.dissipators].sum(-1, keepdims=True) + self.config.balance_share * ea.sum(-1, keepdims=True)
        return np.maximum(np.concatenate([ea, balance], axis=-1), TINY)

    def candidate_grid(self, parameter: str) -> np.ndarray:
        """The first grid of ``parameter``'s candidates: its safe range widened by ``margin`` on both sides."""
        lower, upper = self.model.safe_limits[parameter]
        span = upper - lower
        low = max(lower - self.config.margin * span, 1e-6 * upper)
        return np.linspace(low, upper + self.config.margin * span, self.config.grid)

    def candidate_signature(
        self, parameter_index: np.ndarray, values: np.ndarray, start: np.ndarray, u: np.ndarray, du: np.ndarray
    ) -> np.ndarray:
        """``signature`` over the window for each (system, candidate): (N, G, C + 1)."""
        n, g = values.shape
        space = self.model.state_space
        theta = np.repeat(self.model.parameter_vector()[None, None], n, 0).repeat(g, 1)
        theta[np.arange(n), :, parameter_index] = values
        theta = theta.reshape(n * g, -1)
        to_signal = self.sensors.gain(theta)
        x0 = np.repeat(start, g, 0) / to_signal
        uu, duu = self.model.source_inputs(np.repeat(u, g, 0), np.repeat(du, g, 0))
        # the measured signals, then the load: (n g, nx + 1, T)
        signals = self.monitor.buffer("candidates", (n * g, space.n_states + 1, u.shape[1]))
        simulate_measured(space, self.monitor.h, uu, duu, theta, x0, to_signal, out=signals[:, :-1])
        signals[:, -1] = uu[..., self.model.load_index]
        power, _ = self.monitor.powers(signals, self.context, scratch=True)
        return self.signature(power).reshape(n, g, -1)

    def fit_cost(
        self, parameter_index: np.ndarray, values: np.ndarray, start: np.ndarray, u: np.ndarray, du: np.ndarray, measured: np.ndarray
    ) -> np.ndarray:
        """Fit cost (N,) of the model with ``values`` (N,) of the parameters ``parameter_index`` (the
        others nominal); arguments as in ``estimate``. With nominal values: the cost of "no fault"."""
        return self.cost(self.candidate_signature(parameter_index, values[:, None], start, u, du), measured)[:, 0]

    def cost(self, signature: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """Fit cost of candidate signatures (N, G, C + 1) against the measured ones (N, C + 1), (N, G): the
        sum of the squared relative mismatches (``mismatch_scale``)."""
        return (((signature - measured[:, None, :]) / self.mismatch_scale(measured)[:, None, :]) ** 2).sum(-1)

    def estimate(
        self,
        parameter_index: np.ndarray,
        start: np.ndarray,
        u: np.ndarray,
        du: np.ndarray,
        measured: np.ndarray,
        previous: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Parameter value per system that best explains the measured EA and energy balance, and how well it does.

        Args:
            parameter_index: index into ``model.parameter_names`` of each system's isolated parameter, (N,).
            start: denoised measured signals (flows of I, displacements of C) at t0 - c, (N, nx).
            u, du: load and its derivative from t0 - c to t1, (N, c + L + 1).
            measured: ``signature`` of the measurements over [t0, t1], (N, C + 1).
            previous: the last estimate of each system, NaN where there is none; finite: a warm start.

        Returns:
            the estimates (N,) and their fit costs (N,): the sum of the squared relative mismatches
            between the best candidate's signature and the measured one. Comparing the costs of the
            hypotheses "parameter j alone has changed" tells which one the EA supports.
        """
        grids = self._grids[parameter_index]
        previous = np.full(len(parameter_index), np.nan) if previous is None else previous
        warm = np.isfinite(previous)
        spans = self._spans[parameter_index[warm]]
        offsets = np.linspace(-1.0, 1.0, self.config.warm_grid) * self.config.warm_span
        warm_grids = np.maximum(previous[warm, None] + offsets * spans[:, None], 1e-6 * grids[warm, -1:])
        # warm and cold systems are searched apart, so that a system's estimate never depends on the batch
        estimate, fit = np.empty(len(parameter_index)), np.empty(len(parameter_index))
        for rows, start_grids, passes in ((warm, warm_grids, self.config.warm_passes), (~warm, grids[~warm], self.config.passes)):
            if np.any(rows):
                estimate[rows], fit[rows] = self._search(
                    parameter_index[rows], start_grids, start[rows], u[rows], du[rows], measured[rows], passes
                )
        return estimate, fit

    def _search(
        self, parameter_index: np.ndarray, grids: np.ndarray, start: np.ndarray, u: np.ndarray, du: np.ndarray, measured: np.ndarray,
        passes: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Grid search refined ``passes`` times; each pass narrows to one step either side of the best.

        Returns the vertex of the parabola through the last pass's best candidate and its neighbours
        (the cost is smooth in the parameter near its minimum), or, when the best is an outer candidate,
        through the three outer ones, at most ``config.reach`` steps beyond it; the best candidate
        itself where the cost is not convex. Also returns the best candidate's cost."""
        rows = np.arange(len(grids))
        size = grids.shape[1]
        for _ in range(passes):
            searched = grids
            cost = self.cost(self.candidate_signature(parameter_index, grids, start, u, du), measured)
            step = grids[:, 1] - grids[:, 0]
            best = np.argmin(cost, axis=1)
            grids = np.maximum(grids[rows, best][:, None] + np.linspace(-1.0, 1.0, size) * step[:, None], 1e-6 * grids[:, -1:])
        middle = np.clip(best, 1, size - 2)
        left, right = cost[rows, middle - 1], cost[rows, middle + 1]
        curvature = left - 2.0 * cost[rows, middle] + right
        convex = curvature > 0
        # in steps from the middle candidate: within half a step of an inner best, up to ``reach`` steps past an outer one
        farthest = 1.0 + self.config.reach
        shift = np.clip(0.5 * (left - right) / np.where(convex, curvature, 1.0), -farthest, farthest)
        estimate = np.where(convex, searched[rows, middle] + shift * step, searched[rows, best])
        return np.maximum(estimate, 1e-6 * grids[:, -1]), cost[rows, best]
